"""How one setting moves a method: on the suite's conditions and on BROAD, in sample and left out (issue 23).

``python -m attica_dev.sensitivity mekf6 tau_acc_lp 1.25,1.45,1.6`` runs the method (a kind or a variant
of ``attica eval``) once per value of the setting, every other setting on its default, and prints

- per value its score on each suite condition chosen (``--conditions``; every condition by default):
  the mean over ``--seeds`` seeds of the RMSE after the condition's ``score_from``, inclination for a
  6-axis method and total for a 9-axis one, exactly as ``attica eval --suite`` scores it, with VQF's
  figure of the same axes beside it (``--no-peer`` leaves VQF out);
- with ``--data`` (a directory of BROAD trials) its mean score on them (in sample), and the
  leave-one-trial-out figure of choosing the value on the data: for each trial the value with the lowest
  mean on the other trials, scored on that trial, with how often each value was chosen (the value's
  one-setting grid through :func:`attica.tuning.grid_scores` and :func:`attica.tuning.leave_one_out`).

``--with gyro_noise=7e-5,bias_noise=5e-5`` sets other settings for every value (a sensor's own figures,
say): the table is then of the varied setting over those, not over the defaults.

docs/accuracy.md ("What the defaults trade") quotes its output: the settings that would close the suite's
last gaps to VQF cost elsewhere, in the suite or on BROAD; and what a gyro's datasheet figures, entered
as settings, give. A table takes a few seconds per value.
"""

from __future__ import annotations

import argparse
import dataclasses
import enum
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from attica.data import Recording
from attica.evaluate import load_trials
from attica.evaluate.core import VARIANTS, Method, attica_method
from attica.evaluate.parallel import TrialPool
from attica.evaluate.suite import CONDITIONS, Condition, condition, score_method, suite_methods
from attica.kinds import info
from attica.settings import SETTINGS_CLASS, FilterKind
from attica.sim import simulate_with_truth
from attica.tuning import GridResult, grid_scores, leave_one_out

PEER = {False: "vqf6", True: "vqf9"}
"""The peer printed beside a method, by its axes (False: 6-axis)."""


@dataclass(frozen=True)
class Sensitivity:
    """The scores of one method over the values of one setting.

    Attributes
    ----------
    method : str
        The kind or variant.
    setting : str
        The setting varied.
    values : tuple
        Its values, in the order given.
    suite : dict of str to list of float
        Per condition the score of each value (deg), and under ``"<peer>"`` keys the peer's score.
    broad : GridResult or None
        The BROAD errors per value (the grid's points, in the values' order) and trial, when trials
        were given; :func:`attica.tuning.leave_one_out` of it is the figure of choosing the value.
    fixed : dict
        The other settings given for every value (``--with``; empty: the defaults).

    """

    method: str
    setting: str
    values: tuple[Any, ...]
    suite: dict[str, list[float]]
    broad: GridResult | None = None
    fixed: dict[str, Any] = dataclasses.field(default_factory=dict)


def _kind_of(method: str) -> FilterKind:
    """The kind of a kind or variant name; ValueError listing the variants otherwise."""
    if method in VARIANTS:
        return VARIANTS[method][0]
    try:
        return FilterKind.parse(method)
    except ValueError as exc:
        raise ValueError(f"{exc} (or a variant: {', '.join(VARIANTS)})") from None


def parse_values(method: str, setting: str, text: str) -> tuple[Any, ...]:
    """The values of one setting of a method, typed as the setting's default.

    Parameters
    ----------
    method : str
        A kind or variant (``ars``, ``mekf6`` ...).
    setting : str
        A field of the kind's settings that is a number or a flag, and neither the magnetometer switch
        (it changes the method's axes, so its score) nor ``gyro_range`` (the clipping conditions set it).
    text : str
        Distinct comma-separated values (``true``/``false``/``1``/``0`` for a flag).

    Returns
    -------
    tuple
        The values, as float, int or bool like the default.

    Raises
    ------
    ValueError
        For an unknown method or setting, one that cannot be varied here, or an unreadable or repeated
        value.

    """
    kind = _kind_of(method)
    cls = SETTINGS_CLASS[kind]
    fields = {f.name: f for f in dataclasses.fields(cls)}
    if setting not in fields:
        raise ValueError(f"{method} has no setting {setting!r}; its settings: {', '.join(fields)}")
    if setting == info(kind).mag_switch:
        raise ValueError(f"{setting} switches the magnetometer: compare the 6- and 9-axis methods instead")
    if setting == "gyro_range":
        raise ValueError("gyro_range is the sensor's, set by the clipping conditions: it is not varied here")
    default = getattr(cls(), setting)
    if isinstance(default, enum.Enum) or not isinstance(default, (bool, int, float)):
        raise ValueError(f"{setting} is not a number or a flag (its default: {default!r})")
    out: list[Any] = []
    for word in (w.strip() for w in text.split(",")):
        try:
            if isinstance(default, bool):
                if word.lower() not in ("true", "false", "1", "0"):
                    raise ValueError("not true, false, 1 or 0")
                out.append(word.lower() in ("true", "1"))
            elif isinstance(default, int):
                out.append(int(word))
            else:
                out.append(float(word))
        except ValueError as exc:
            raise ValueError(
                f"{setting}: cannot read {word!r} as a {type(default).__name__} ({exc})"
            ) from None
    if len(set(out)) != len(out):
        raise ValueError(f"{setting}: give distinct values, got {text!r}")
    return tuple(out)


def parse_fixed(method: str, setting: str, text: str) -> dict[str, Any]:
    """The settings of ``--with``: ``name=value`` pairs, comma-separated, held for every value.

    Parameters
    ----------
    method : str
        A kind or variant.
    setting : str
        The setting varied: it cannot be held too.
    text : str
        ``name=value[,name=value ...]``; each name a setting :func:`parse_values` accepts, each value
        read as it reads one.

    Returns
    -------
    dict
        The settings, in the order given.

    Raises
    ------
    ValueError
        For a pair without ``=``, a name given twice or the varied one, and whatever
        :func:`parse_values` refuses.

    """
    out: dict[str, Any] = {}
    for pair in (p.strip() for p in text.split(",")):
        name, eq, value = pair.partition("=")
        name = name.strip()
        if not eq or not name or not value.strip():
            raise ValueError(f"--with: {pair!r} is not name=value")
        if name == setting:
            raise ValueError(f"--with: {name} is the setting varied")
        if name in out:
            raise ValueError(f"--with: {name} given twice")
        out[name] = parse_values(method, name, value)[0]
    return out


def _method(method: str, setting: str, value: Any, extra: dict[str, Any] | None = None) -> Method:
    over = {setting: value, **(extra or {})}
    if method in VARIANTS:
        return attica_method(VARIANTS[method][0], overrides=over, variant=method)
    return attica_method(FilterKind.parse(method), overrides=over)


def suite_scores(
    method: str,
    setting: str,
    values: Sequence[Any],
    conditions: Sequence[Condition],
    seeds: Sequence[int],
    peer: bool,
    fixed: dict[str, Any] | None = None,
) -> dict[str, list[float]]:
    """Per condition the suite's score of each value (and the peer's under ``"<peer>" + condition``).

    The settings of ``fixed`` are held for every value (the peer's runs have none).
    """
    nine = _method(method, setting, values[0]).nine_axis
    metric = "total" if nine else "inclination"
    out: dict[str, list[float]] = {}
    for cond in conditions:
        over = {**(fixed or {}), **({"gyro_range": cond.gyro_range} if cond.gyro_range > 0 else {})}
        methods = [_method(method, setting, v, over) for v in values]
        if peer:
            methods += suite_methods([], [PEER[nine]], cond.gyro_range)
        acc = np.zeros((len(methods), len(seeds)))
        for j, seed in enumerate(seeds):
            rec, _ = simulate_with_truth(cond.config(seed, None))
            for i, m in enumerate(methods):
                acc[i, j] = getattr(score_method(m, rec, cond.score_from)[0], metric)
        means = acc.mean(axis=1).tolist()
        out[cond.name] = means[: len(values)]
        if peer:
            out["<peer>" + cond.name] = means[len(values) :]
    return out


def broad_scores(
    method: str,
    setting: str,
    values: Sequence[Any],
    recs: Sequence[Recording],
    jobs: int,
    fixed: dict[str, Any] | None = None,
) -> GridResult:
    """The method on ``recs`` for each value: the one-setting grid of :func:`attica.tuning.grid_scores`.

    The settings of ``fixed`` are axes of one value each, so the points stay in the values' order.
    """
    variant = method if method in VARIANTS else ""
    grid: dict[str, list[Any]] = {setting: list(values), **{k: [v] for k, v in (fixed or {}).items()}}
    with TrialPool(jobs) as pool:
        return grid_scores(_kind_of(method), recs, grid, variant, progress=False, pool=pool)


def measure(
    method: str,
    setting: str,
    values: Sequence[Any],
    conditions: Sequence[Condition] = CONDITIONS,
    seeds: Sequence[int] = range(1, 11),
    recs: Sequence[Recording] | None = None,
    jobs: int = 1,
    peer: bool = True,
    fixed: dict[str, Any] | None = None,
) -> Sensitivity:
    """The scores of ``method`` for each value of ``setting``.

    Parameters
    ----------
    method, setting : str
        The kind or variant and the setting varied (:func:`parse_values`).
    values : sequence
        The setting's values.
    conditions : sequence of Condition
        The suite's conditions to score on.
    seeds : sequence of int
        The seeds of each condition.
    recs : sequence of Recording, optional
        BROAD trials (with ground truth) to score on as well.
    jobs : int
        Worker processes for the trials.
    peer : bool
        Score VQF of the method's axes beside it.
    fixed : dict, optional
        Other settings held for every value (:func:`parse_fixed`); the defaults otherwise.

    Returns
    -------
    Sensitivity
        The scores.

    """
    held = dict(fixed or {})
    suite = suite_scores(method, setting, values, conditions, seeds, peer, held)
    broad = broad_scores(method, setting, values, recs, jobs, held) if recs else None
    return Sensitivity(method, setting, tuple(values), suite, broad, held)


def format_table(s: Sensitivity) -> str:
    """The printed table: a row per value, a column per condition (and BROAD), the peer's row last."""
    conds = [c for c in s.suite if not c.startswith("<peer>")]
    head = f"{s.setting:>16s}" + "".join(f"{c[:13]:>14s}" for c in conds)
    if s.broad is not None:
        head += f"{'BROAD':>10s}"
    lines = [head]
    means = s.broad.scores().mean(axis=1) if s.broad is not None else None
    for i, v in enumerate(s.values):
        row = f"{v!s:>16s}" + "".join(f"{s.suite[c][i]:14.3f}" for c in conds)
        if means is not None:
            row += f"{means[i]:10.4f}"
        lines.append(row)
    if any(c.startswith("<peer>") for c in s.suite):
        lines.append(f"{'VQF':>16s}" + "".join(f"{s.suite['<peer>' + c][0]:14.3f}" for c in conds))
    if s.broad is not None:
        loo = leave_one_out(s.broad)
        counts = ", ".join(f"{s.values[i]} x{loo.chosen.count(i)}" for i in sorted(set(loo.chosen)))
        lines.append(f"BROAD leave-one-trial-out of choosing {s.setting}: {loo.mean:.4f} (chosen: {counts})")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Command line."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("method", help="a kind or variant (ars, mekf6, mars ...)")
    ap.add_argument("setting", help="the setting to vary (a field of the kind's settings)")
    ap.add_argument("values", help="comma-separated values")
    ap.add_argument("--conditions", default="", help="comma-separated suite conditions (default: all)")
    ap.add_argument("--seeds", type=int, default=10, help="seeds 1 .. N (default 10, as the suite)")
    ap.add_argument("--data", type=Path, default=None, help="a directory of BROAD trials")
    ap.add_argument("-j", "--jobs", type=int, default=1, help="worker processes for the BROAD trials")
    ap.add_argument("--no-peer", action="store_true", help="leave VQF out")
    ap.add_argument(
        "--with",
        dest="fixed",
        default="",
        metavar="NAME=VALUE,...",
        help="other settings held for every value (default: the defaults)",
    )
    args = ap.parse_args(argv)
    try:
        values = parse_values(args.method, args.setting, args.values)
        fixed = parse_fixed(args.method, args.setting, args.fixed) if args.fixed else {}
        conds = (
            [condition(c.strip()) for c in args.conditions.split(",")]
            if args.conditions
            else list(CONDITIONS)
        )
    except KeyError as exc:
        ap.error(str(exc.args[0]))
    except ValueError as exc:
        ap.error(str(exc))
    if args.seeds < 1:
        ap.error(f"--seeds must be at least 1, got {args.seeds}")
    if args.jobs < 1:
        ap.error(f"--jobs must be at least 1, got {args.jobs}")
    recs: list[Recording] = []
    if args.data is not None:
        if not args.data.exists():
            ap.error(f"--data {args.data}: no such file or directory")
        try:
            recs = load_trials(args.data)
        except (ValueError, OSError) as exc:
            ap.error(f"--data {args.data}: {exc}")
        if len(recs) < 2:
            ap.error(f"--data {args.data}: {len(recs)} trial(s); leave-one-trial-out needs at least 2")
    t0 = time.perf_counter()
    s = measure(
        args.method,
        args.setting,
        values,
        conds,
        range(1, args.seeds + 1),
        recs,
        args.jobs,
        not args.no_peer,
        fixed,
    )
    held = ", with " + ", ".join(f"{k}={v}" for k, v in fixed.items()) if fixed else ""
    print(
        f"{s.method}{held}: mean of {args.seeds} seeds per condition "
        "(6-axis: inclination, 9-axis: total RMSE, deg)"
    )
    print(format_table(s))
    print(f"({time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""``attica eval``: accuracy on recorded trials with the BROAD metrics, peers side by side.

Runs attica's C filters (and with ``--peers`` other people's filters) over every recording of a
directory, prints the RMSE per trial, per group and on average (6-axis methods by inclination, 9-axis
methods by total error, in tables that fit 110 columns; ``--wide`` for one table each), and with
``--out`` writes results.json and PNG plots. ``--grid`` runs the grid search that chose the defaults.
``--suite`` runs the generalisation suite instead (:mod:`attica.evaluate.suite`: simulated conditions,
no ``--data``; ``--quick`` for its reduced set; with ``--out`` it writes suite.json).

Trials run in parallel (``--jobs N`` processes, every core by default) or on a Dask cluster
(``--scheduler tcp://host:port``); the figures are the serial run's bit for bit
(:mod:`attica.evaluate.parallel`).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import json
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from attica.commands._common import (
    CliError,
    add_calibration_argument,
    add_unit_check_argument,
    check_units,
    describe_calibration,
    filter_settings,
    load_calibration,
    parse_kinds,
    plan_overrides,
    prepare_output_dir,
    warn,
    warn_calibrated_truth,
)
from attica.settings import Preset, implemented_kinds

NAME = "eval"
HELP = "accuracy on recorded trials (BROAD metrics): tables, plots, JSON, peers side by side"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``attica eval``."""
    from attica.evaluate import VARIANTS
    from attica.evaluate.parallel import DASK_HINT, default_jobs
    from attica.evaluate.suite import KINDS as SUITE_KINDS
    from attica.evaluate.suite import PEERS as SUITE_PEERS

    choices = ", ".join([k.label for k in implemented_kinds()] + list(VARIANTS))
    p.add_argument(
        "--filter",
        help=f"'all' or comma-separated kinds and variants ({choices}); default all, with --suite "
        f"{','.join(SUITE_KINDS)}",
    )
    p.add_argument(
        "--data", help="directory of trials (.npz/.csv/.hdf5/.mat) or one file (required unless --suite)"
    )
    p.add_argument(
        "--suite",
        action="store_true",
        help="run the generalisation suite on the simulator instead of --data: fixed conditions (rates, "
        "sensor grades, magnetic disturbances, rest, fast turns, a clipping gyro, vibration) x seeds, "
        f"attica against {','.join(SUITE_PEERS)} by default (--peers: others, 'none': without); "
        "with --out: suite.json",
    )
    p.add_argument("--quick", action="store_true", help="with --suite: its reduced set (1 seed, 20 s each)")
    p.add_argument(
        "--preset",
        default="default",
        choices=["default", "seed", "both"],
        help="settings preset of attica's filters (default: default)",
    )
    p.add_argument("--out", help="directory for results.json and the PNG plots (created if missing)")
    p.add_argument(
        "--peers",
        nargs="?",
        const="all",
        help="also run other people's filters: all installed ones, or comma-separated names (vqf9,fusion9). "
        "Rows without a mag sample: VQF and Fusion get a zero field (their 'no sample'); the 9-axis ahrs "
        "filters start at the first mag sample (earlier rows not scored), the ahrs EKF holds the last "
        "sample; the notes under the tables say what was done per trial. With --suite: vqf6,vqf9,fusion6,"
        "fusion9 when left out, 'none' for none",
    )
    add_calibration_argument(p, "attica's filters (not with --peers or --grid)")
    p.add_argument(
        "--set",
        action="append",
        metavar="NAME=VALUE",
        help="change a setting of attica's filters (repeatable; applies to the kinds that have it; the "
        "method's name shows it, e.g. mekf[recovery_time=4.0]); not with --grid or --suite",
    )
    p.add_argument("--grid", action="store_true", help="run the grid search of the defaults instead")
    p.add_argument("--limit", type=int, help="only the first N trials")
    p.add_argument("--wide", action="store_true", help="one table per kind of method, however wide")
    p.add_argument(
        "-j",
        "--jobs",
        type=int,
        help="worker processes for the trials (default: every core, here "
        f"{default_jobs()}; 1: in this process); the figures are the same whatever the number",
    )
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run the trials on a Dask cluster, e.g. tcp://host:8786 (the dask.distributed client: "
        f"{DASK_HINT}); its workers must have the same attica installed",
    )
    p.add_argument("--no-plots", action="store_true", help="write no PNGs")
    add_unit_check_argument(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


def _peers(spec: str | None) -> list[Any]:
    """The peer methods asked for; unknown or missing names are CliErrors (before any work)."""
    from attica.evaluate import peer_methods
    from attica.peers import PEERS

    if spec is None:
        return []
    if spec in ("", "all"):
        methods = peer_methods(None)
        if not methods:
            raise CliError("--peers: no peer library is installed (pip install '.[peers]')")
        return methods
    names = [n.strip() for n in spec.split(",") if n.strip()]
    if not names:
        raise CliError("--peers: empty selection; give all or names such as vqf9,fusion9")
    known = {p.name: p for p in PEERS}
    bases = {p.name.split("@")[0] for p in PEERS}
    unknown = [n for n in names if n not in known and n not in bases]
    if unknown:
        raise CliError(f"--peers: unknown peer(s) {', '.join(unknown)}; peers: {', '.join(sorted(known))}")
    missing = sorted(
        {p.library for p in PEERS if (p.name in names or p.name.split("@")[0] in names) and not p.installed}
    )
    if missing:
        raise CliError(f"--peers: {', '.join(missing)} not installed (pip install '.[peers]')")
    return peer_methods(names)


def run(args: argparse.Namespace) -> int:
    """``attica eval``."""
    from attica.evaluate import format_stated, format_summary, format_tables, load_trials, run_methods
    from attica.evaluate.parallel import DASK_HINT

    if args.suite:
        return _suite(args)
    if args.data is None:
        raise CliError("--data is required (a directory of trials or one file), or --suite for the simulator")
    if args.quick:
        raise CliError("--quick belongs to --suite (its reduced set)")
    if args.peers == "none":
        raise CliError("--peers none: leave --peers out to run attica's filters only")
    if args.limit is not None and args.limit < 1:
        raise CliError("--limit must be >= 1")
    if args.jobs is not None and args.jobs < 1:
        raise CliError("--jobs must be >= 1")
    if args.scheduler is not None and args.jobs is not None:
        raise CliError("--jobs and --scheduler exclude each other (the cluster decides how many workers run)")
    if args.scheduler is not None and importlib.util.find_spec("distributed") is None:
        raise CliError(f"--scheduler needs the Dask client (dask.distributed): {DASK_HINT}")
    if args.calibration and (args.peers is not None or args.grid):
        what = "--peers (the peers would not get the calibration)" if args.peers is not None else "--grid"
        raise CliError(f"--calibration applies to attica's filters only; drop it or {what}")
    if args.set and args.grid:
        raise CliError("--set changes the defaults; --grid searches its own points around them: drop one")
    cal = load_calibration(args)
    overrides: dict[str, dict[str, Any]] = {}
    if args.grid:
        names = _grid_names(args.filter or "all")
        methods: list[Any] = []
    else:
        names = _method_names(args.filter or "all")
        overrides = _overrides(names, args.set or [])
        _check_settings(overrides, 100.0)  # before loading; again at the trials' rates below
        presets = [Preset.DEFAULT, Preset.SEED] if args.preset == "both" else [Preset.parse(args.preset)]
        methods = [_attica(n, p, cal, overrides.get(n)) for p in presets for n in names] + _peers(args.peers)
    out = prepare_output_dir(Path(args.out)) if args.out else None
    plots = out is not None and not args.no_plots and not args.grid
    if plots:
        from attica.evaluate.plots import _pyplot

        try:
            _pyplot()
        except RuntimeError as exc:
            raise CliError(str(exc)) from None
    try:
        recs = load_trials(args.data, args.limit)
    except (FileNotFoundError, ValueError, RuntimeError) as exc:
        raise CliError(str(exc)) from None
    missing_truth = [r.name for r in recs if r.quat_true is None]
    if missing_truth:
        raise CliError(f"no ground truth (opt_quat / quat_* columns) in: {', '.join(missing_truth)}")
    print(f"{args.data}: {len(recs)} trials, {sum(len(r) for r in recs)} samples")
    if cal is not None:
        print(describe_calibration(cal, args.calibration))
        warn_calibrated_truth(cal)
    for rec in recs:
        check_units(rec, args)
    for rate in sorted({r.rate for r in recs}):  # every setting checked before anything runs
        _check_settings(overrides, rate)
    with _pool(args) as pool:
        if args.grid:
            return _grid(args, names, recs, out, pool)
        t0 = time.perf_counter()
        report = run_methods(methods, recs, progress=not args.quiet, curves=plots, pool=pool)
        where = pool.describe()
    print(f"{len(methods)} methods x {len(recs)} trials in {time.perf_counter() - t0:.1f} s ({where})\n")
    print(format_tables(report, wide=args.wide))
    print(format_summary(report))
    stated = format_stated(report)
    if stated:
        print(f"\n{stated}")
    if out is not None:
        data = {
            "command": " ".join(["attica", *sys.argv[1:]]) if sys.argv[1:2] == ["eval"] else "attica eval"
        }
        data.update(report.as_dict())
        (out / "results.json").write_text(json.dumps(data, indent=1))
        print(f"\nwrote {out / 'results.json'}")
        if plots:
            from attica.evaluate.plots import write_plots

            written = write_plots(report, recs, out)
            print(f"wrote {len(written)} plots to {out} (error_*.png, groups*.png)")
    return 0


@contextlib.contextmanager
def _pool(args: argparse.Namespace) -> Iterator[Any]:
    """The :class:`~attica.evaluate.parallel.TrialPool` of ``--jobs`` / ``--scheduler`` (errors: CliError)."""
    from attica.evaluate.parallel import TrialPool

    try:  # DaskMissingError is a RuntimeError
        pool = TrialPool(args.jobs, args.scheduler)
        pool.__enter__()
    except (ConnectionError, RuntimeError) as exc:
        raise CliError(f"--scheduler: {exc}") from None
    try:
        yield pool
    finally:
        pool.close()


def _method_names(spec: str) -> list[str]:
    """Kinds and variants (``mekf6``) to run: ``all`` is every kind, each followed by its variants."""
    from attica.evaluate import VARIANTS

    names: list[str] = []
    if spec.strip() == "all":
        for k in implemented_kinds():
            names.append(k.label)
            names += [v for v, (kind, _, _) in VARIANTS.items() if kind == k]
        return names
    parts = [t.strip() for t in spec.split(",") if t.strip()]
    for part in parts:
        if part in VARIANTS:
            names.append(part)
        else:
            names += [k.label for k in parse_kinds(part)]
    if not names:
        raise CliError(f"empty filter selection {spec!r}")
    return list(dict.fromkeys(names))


def _grid_names(spec: str) -> list[str]:
    """Kinds and variants that have a tuning grid (``--grid``); others are a CliError."""
    from attica.evaluate import GRIDS, VARIANT_GRIDS

    tunable = [k.label for k in implemented_kinds() if GRIDS[k]] + list(VARIANT_GRIDS)  # baselines: empty
    if spec.strip() == "all":
        return tunable
    names = _method_names(spec)
    bad = [n for n in names if n not in tunable]
    if bad:
        raise CliError(f"--grid: {', '.join(bad)} has no tuning grid; tunable: {', '.join(tunable)}")
    return names


def _attica(
    name: str, preset: Preset, calibration: Any = None, overrides: dict[str, Any] | None = None
) -> Any:
    """Attica's method for a kind or variant name (with the calibration and setting overrides when given)."""
    from attica.evaluate import VARIANTS, attica_method, method_kind

    variant = name if name in VARIANTS else ""
    return attica_method(
        method_kind(name), preset, overrides, variant=variant, calibration=calibration, covariance=True
    )


def _check_settings(overrides: dict[str, dict[str, Any]], rate: float) -> None:
    """Each method's settings with its --set changes at ``rate``, checked as attica run checks them."""
    from attica.evaluate import VARIANTS, method_kind

    for name, over in overrides.items():
        base = VARIANTS[name][1] if name in VARIANTS else {}
        filter_settings(method_kind(name), rate, {**base, **over})


def _overrides(names: list[str], items: list[str]) -> dict[str, dict[str, Any]]:
    """``--set`` for the methods named: each setting to the kinds that have it (``plan_overrides``)."""
    if not items:
        return {}
    if any(item.partition("=")[0].strip() == "use_mag" for item in items):
        # it decides the axes a method is judged by, which its name says: mekf (9-axis) or mekf6
        raise CliError("--set use_mag: choose the axes with --filter mekf (9-axis) or mekf6 (6-axis) instead")
    from attica.evaluate import method_kind

    kinds = list(dict.fromkeys(method_kind(n) for n in names))
    plan = plan_overrides(kinds, items)
    return {n: plan[method_kind(n)] for n in names if plan[method_kind(n)]}


def _grid(args: argparse.Namespace, names: list[str], recs: list[Any], out: Path | None, pool: Any) -> int:
    """``attica eval --grid``: every grid (kinds and variants), best five, in-sample and leave-one-out."""
    from attica.evaluate import GRIDS, METRICS, VARIANT_GRIDS, method_kind
    from attica.tuning import grid_scores, leave_one_out

    if args.peers is not None:
        warn("--peers is ignored by --grid (it searches attica's settings only)")
    grids: dict[str, Any] = {}
    for name in names:
        variant = name if name in VARIANT_GRIDS else ""
        kind = method_kind(name)
        grid = VARIANT_GRIDS[name] if variant else GRIDS[kind]
        res = grid_scores(kind, recs, grid, variant=variant, progress=not args.quiet, pool=pool)
        rows = res.ranked()
        print(f"\ngrid {name} ({len(rows)} points, ranked by mean {res.metric} RMSE); best 5:")
        for over, e in rows[:5]:
            print(f"  {e.total:7.2f} {e.heading:7.2f} {e.inclination:7.2f}  {over}")
        entry: dict[str, Any] = {
            "grid": grid,
            "ranked": [{"settings": o, **{k: getattr(e, k) for k in METRICS}} for o, e in rows],
        }
        if len(recs) >= 2:
            loo = leave_one_out(res)
            print(
                f"  {res.metric}: in-sample {loo.in_sample:.3f}, leave-one-trial-out {loo.mean:.3f} "
                f"(the best point on the other {len(recs) - 1} trials, scored on the held-out one)"
            )
            entry["in_sample"] = loo.in_sample
            entry["leave_one_out"] = loo.mean
            entry["held_out"] = {t: float(v) for t, v in zip(res.trials, loo.held_out, strict=True)}
            entry["chosen"] = {t: res.points[i] for t, i in zip(res.trials, loo.chosen, strict=True)}
        grids[name] = entry
    if out is not None:
        (out / "grid.json").write_text(json.dumps(grids, indent=1, default=str))
        print(f"wrote {out / 'grid.json'}")
    return 0


def _suite(args: argparse.Namespace) -> int:
    """``attica eval --suite``: the generalisation suite on the simulator (tables, summary, suite.json)."""
    from attica.commands._common import progress
    from attica.evaluate.parallel import default_jobs
    from attica.evaluate.suite import (
        CONDITIONS,
        KINDS,
        PEERS,
        QUICK,
        QUICK_DURATION,
        QUICK_SEEDS,
        SEEDS,
        run_suite,
    )
    from attica.evaluate.suite_tables import format_suite
    from attica.peers import peer_by_name

    given = [
        opt
        for opt, bad in (
            ("--data", args.data is not None),
            ("--grid", args.grid),
            ("--limit", args.limit is not None),
            ("--calibration", bool(args.calibration)),
            ("--scheduler", args.scheduler is not None),
            ("--preset", args.preset != "default"),
            ("--set", bool(args.set)),
        )
        if bad
    ]
    if given:
        raise CliError(
            f"--suite simulates its own data with every method on its defaults; drop {', '.join(given)}"
        )
    if args.jobs is not None and args.jobs < 1:
        raise CliError("--jobs must be >= 1")
    kinds = list(KINDS) if args.filter is None else _method_names(args.filter)
    if args.peers is None:
        peers = [n for n in PEERS if peer_by_name(n).installed]
        missing = [n for n in PEERS if n not in peers]
        if missing:
            warn(f"--suite: {', '.join(missing)} not installed (pip install '.[peers]'): run without them")
    elif args.peers == "none":
        peers = []
    else:
        peers = [m.name for m in _peers(args.peers)]
    out = prepare_output_dir(Path(args.out)) if args.out else None
    conditions = [c for c in CONDITIONS if c.name in QUICK] if args.quick else list(CONDITIONS)
    seeds = QUICK_SEEDS if args.quick else SEEDS
    duration = QUICK_DURATION if args.quick else None
    jobs = args.jobs if args.jobs is not None else default_jobs()
    jobs = min(jobs, len(conditions) * len(seeds))
    t0 = time.perf_counter()
    with progress(len(conditions) * len(seeds), "suite", not args.quiet, unit="case") as bar:
        res = run_suite(kinds, peers, conditions, seeds, duration, jobs, done=lambda k: bar.update(1))
    where = "in one process" if jobs == 1 else f"on {jobs} processes"
    print(
        f"{len(kinds) + len(peers)} methods x {len(conditions)} conditions x {len(seeds)} seeds in "
        f"{time.perf_counter() - t0:.1f} s ({where})\n"
    )
    print(format_suite(res, width=10**6 if args.wide else 110))
    if out is not None:
        data = {
            "command": " ".join(["attica", *sys.argv[1:]]) if sys.argv[1:2] == ["eval"] else "attica eval"
        }
        data.update(res.as_dict())
        (out / "suite.json").write_text(json.dumps(data, indent=1))
        print(f"\nwrote {out / 'suite.json'}")
    return 0

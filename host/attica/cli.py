"""The ``attica`` command: one entry point, one subcommand per job.

- ``attica sim``: write a simulated IMU recording with ground truth (.npz, BROAD layout).
- ``attica run``: run a C filter over a simulated or recorded stream, print its error against truth.
- ``attica demo``: what ``make run`` shows: simulate, run the ARS in C and in the numpy reference,
  prove bit-exact agreement and print the attitude error.
"""

from __future__ import annotations

import argparse
import dataclasses
import enum
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.can.cli_can import add_subcommands as add_can_subcommands
from attica.data import Recording, load_recording
from attica.evaluate import add_eval_subcommand
from attica.metrics import evaluate
from attica.settings import FilterKind, Flag, describe_flags, implemented_kinds, make_settings
from attica.sim import SimConfig, simulate, simulate_with_truth

CHUNK = 20_000


class CliError(Exception):
    """A user error: printed without a traceback, exit status 2."""


def _progress(total: int, desc: str, enabled: bool) -> Any:
    from tqdm import tqdm

    show = enabled and sys.stderr.isatty()
    return tqdm(
        total=total,
        desc=desc,
        unit="step",
        unit_scale=True,
        disable=not show,
        leave=False,
        file=sys.stderr,
        mininterval=0.2,
    )


def _parse_value(text: str, current: Any) -> Any:
    if isinstance(current, bool):
        if text.lower() in ("1", "true", "yes", "on"):
            return True
        if text.lower() in ("0", "false", "no", "off"):
            return False
        raise ValueError(f"expected true/false, got {text!r}")
    if isinstance(current, enum.Enum):
        cls = type(current)
        try:
            return cls[text.upper()]
        except KeyError:
            return cls(int(text))
    if isinstance(current, int):
        return int(text)
    if isinstance(current, tuple):
        parts = [float(p) for p in text.split(",")]
        if len(parts) != len(current):
            raise ValueError(f"expected {len(current)} comma-separated numbers, got {text!r}")
        return tuple(parts)
    return float(text)


def parse_overrides(kind: FilterKind, items: Sequence[str]) -> dict[str, Any]:
    """``name=value`` strings to typed settings overrides for ``kind``."""
    defaults = make_settings(kind)
    names = {f.name for f in dataclasses.fields(defaults)}
    out: dict[str, Any] = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep:
            raise CliError(f"--set expects name=value, got {item!r}")
        if name not in names:
            raise CliError(f"{kind.label} has no setting {name!r}; settings: {', '.join(sorted(names))}")
        try:
            out[name] = _parse_value(value, getattr(defaults, name))
        except ValueError as exc:
            raise CliError(f"--set {name}: {exc}") from None
    return out


def _sim_config(args: argparse.Namespace) -> SimConfig:
    return SimConfig(
        duration=args.duration, rate=args.rate, seed=args.seed, taps=args.taps, rest_breaks=args.breaks
    )


def _simulate(cfg: SimConfig) -> Recording:
    try:
        return simulate(cfg)
    except ValueError as exc:
        raise CliError(f"simulation: {exc} (use a longer --duration or fewer --breaks)") from None


def _recording(args: argparse.Namespace) -> Recording:
    if getattr(args, "data", None):
        path = Path(args.data)
        if not path.exists():
            raise CliError(f"no such recording: {path}")
        try:
            return load_recording(path)
        except ValueError as exc:
            raise CliError(f"{path}: {exc}") from None
    return _simulate(_sim_config(args))


def run_native(kind: FilterKind, rec: Recording, settings: Any, show_progress: bool) -> NDArray[np.void]:
    """Run the C filter over a recording in chunks (for the progress bar); (N,) output records."""
    from attica import native

    try:
        f = native.Filter(kind, settings)
    except native.NativeError as exc:
        raise CliError(str(exc)) from None
    parts = []
    with _progress(len(rec.gyr), f"{kind.label} (C)", show_progress) as bar:
        for start in range(0, len(rec.gyr), CHUNK):
            sl = slice(start, start + CHUNK)
            parts.append(f.run(rec.gyr[sl], rec.acc[sl], rec.mag[sl]))
            bar.update(len(parts[-1]))
    return np.concatenate(parts) if parts else np.zeros(0, dtype=parts[0].dtype if parts else None)


def _flag_summary(flags: NDArray[np.uint32]) -> str:
    values, counts = np.unique(flags, return_counts=True)
    rows = sorted(zip(counts, values), reverse=True)[:6]
    return ", ".join(f"{describe_flags(int(v))}: {int(c)}" for c, v in rows)


USES_MAG = {FilterKind.MARS}
"""Kinds whose heading is meaningful (9-axis); 6-axis filters are judged by inclination only."""


def _print_errors(kind: FilterKind, rec: Recording, out: NDArray[np.void]) -> None:
    if rec.quat_true is None:
        print(f"{kind.label:>6}: no ground truth in this recording; last attitude {out['q'][-1]}")
        return
    e = evaluate(out["q"].astype(np.float64), rec.quat_true, rec.movement)
    if kind in USES_MAG:
        print(
            f"{kind.label:>6}: RMSE total {e.total:6.2f} deg   heading {e.heading:6.2f} deg   "
            f"inclination {e.inclination:6.2f} deg"
        )
    else:
        print(f"{kind.label:>6}: RMSE inclination {e.inclination:6.2f} deg (6-axis: heading not observable)")


def cmd_sim(args: argparse.Namespace) -> int:
    """``attica sim``."""
    rec = _simulate(_sim_config(args))
    out = Path(args.output)
    rec.save(out)
    print(f"wrote {out}: {len(rec.gyr)} samples at {rec.rate:g} Hz ({len(rec.gyr) / rec.rate:.1f} s)")
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    """``attica run``."""
    kinds = implemented_kinds() if args.filter == "all" else [FilterKind.parse(args.filter)]
    rec = _recording(args)
    source = args.data or f"simulation (seed {args.seed}, {args.duration:g} s)"
    print(f"{source}: {len(rec.gyr)} samples at {rec.rate:g} Hz")
    for kind in kinds:
        overrides = parse_overrides(kind, args.set or [])
        if "dt" in overrides:
            raise CliError("dt is the recording's sample period (1 / rate); use --rate for simulations")
        try:
            settings = make_settings(kind, dt=1.0 / rec.rate, **overrides)
        except (TypeError, ValueError) as exc:
            raise CliError(str(exc)) from None
        t0 = time.perf_counter()
        out = run_native(kind, rec, settings, not args.quiet)
        elapsed = time.perf_counter() - t0
        _print_errors(kind, rec, out)
        print(f"        {len(out)} steps in {elapsed * 1e3:.0f} ms; flags: {_flag_summary(out['flags'])}")
        if args.check:
            if not _check(kind, rec, settings, not args.quiet):
                return 1
        if args.output:
            path = Path(args.output)
            if len(kinds) > 1:
                path = path.with_name(f"{path.stem}_{kind.label}{path.suffix or '.npz'}")
            np.savez_compressed(
                path,
                q=out["q"],
                euler=out["euler"],
                gyro_bias=out["gyro_bias"],
                cov=out["cov"],
                flags=out["flags"],
            )
            print(f"        wrote {path}")
    return 0


def _check(kind: FilterKind, rec: Recording, settings: Any, show_progress: bool) -> bool:
    from attica.crosscheck import Stream, crosscheck

    with _progress(0, f"{kind.label} reference", show_progress) as bar:

        def progress(done: int, total: int) -> None:
            bar.total = total
            bar.update(done - bar.n)

        r = crosscheck(kind, [Stream(rec.gyr, rec.acc, rec.mag, rec.name)], settings, progress=progress)
    verdict = "bit-exact" if r.ok else "MISMATCH"
    print(f"        C vs numpy reference: {r.steps} steps compared, {r.mismatched_steps} differ: {verdict}")
    if not r.ok:
        print(f"        first difference: {r.first_mismatch}")
    return r.ok


def cmd_demo(args: argparse.Namespace) -> int:
    """``attica demo``."""
    cfg = SimConfig(duration=args.duration, rate=args.rate, seed=args.seed, taps=3)
    rec, truth = simulate_with_truth(cfg)
    print(
        f"simulated {cfg.duration:g} s of IMU data at {cfg.rate:g} Hz (seed {cfg.seed}): "
        f"{len(rec.gyr)} samples, gyro bias up to {cfg.gyro_bias} rad/s, 3 taps"
    )
    kind = FilterKind.ARS
    settings = make_settings(kind, dt=1.0 / rec.rate)
    out = run_native(kind, rec, settings, not args.quiet)
    ok = _check(kind, rec, settings, not args.quiet)
    _print_errors(kind, rec, out)
    learnt = np.nonzero(out["flags"] & Flag.BIAS_UPDATED)[0]
    if learnt.size:
        i = int(learnt[-1])  # the estimate changes only at rest: compare where it was last updated
        print(
            f"        gyro bias estimate {np.round(out['gyro_bias'][i], 4)} rad/s "
            f"at t = {i / rec.rate:.1f} s (true {np.round(truth.gyr_bias[i], 4)}; "
            f"it drifts {cfg.gyro_bias_drift} rad/s/sqrt(s))"
        )
    return 0 if ok else 1


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``attica``."""
    p = argparse.ArgumentParser(prog="attica", description="Deterministic attitude estimation: tools.")
    sub = p.add_subparsers(dest="command", required=True)

    def sim_args(sp: argparse.ArgumentParser) -> None:
        sp.add_argument("--duration", type=float, default=60.0, help="seconds to simulate (default 60)")
        sp.add_argument("--rate", type=float, default=285.714, help="sample rate in Hz (default 285.714)")
        sp.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
        sp.add_argument("--taps", type=int, default=0, help="number of taps (acceleration impulses)")
        sp.add_argument("--breaks", type=int, default=2, help="still pauses inside the motion (default 2)")

    sp = sub.add_parser("sim", help="write a simulated recording (.npz) with ground truth")
    sim_args(sp)
    sp.add_argument("-o", "--output", required=True, help="output .npz path")
    sp.set_defaults(func=cmd_sim)

    choices = [k.label for k in FilterKind] + ["all"]
    sp = sub.add_parser("run", help="run a filter (in C) over simulated or recorded data")
    sp.add_argument("--filter", default="ars", choices=choices, help="filter kind (default ars)")
    sp.add_argument("--data", help="recording (.npz in BROAD layout, or .csv); default: simulate")
    sim_args(sp)
    sp.add_argument("--set", action="append", metavar="NAME=VALUE", help="change a setting (repeatable)")
    sp.add_argument("--check", action="store_true", help="also run the numpy reference and compare bits")
    sp.add_argument("-o", "--output", help="write the outputs to this .npz")
    sp.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    sp.set_defaults(func=cmd_run)

    sp = sub.add_parser("demo", help="simulate, run the ARS in C and in the reference, compare")
    sp.add_argument("--duration", type=float, default=60.0)
    sp.add_argument("--rate", type=float, default=285.714)
    sp.add_argument("--seed", type=int, default=0)
    sp.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    sp.set_defaults(func=cmd_demo)
    add_eval_subcommand(sub)
    add_can_subcommands(sub)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``attica`` command."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except CliError as exc:
        print(f"attica: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

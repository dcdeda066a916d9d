"""``attica run``: run C filters over simulated or recorded data and print their error against truth."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.commands._common import (
    CliError,
    add_calibration_argument,
    add_resample_argument,
    add_sim_arguments,
    add_unit_check_argument,
    check_data_or_sim,
    check_output_file,
    check_units,
    describe_calibration,
    describe_source,
    filter_settings,
    fit_to_simulation,
    load_calibration,
    load_data,
    parse_kinds,
    plan_overrides,
    progress,
    warn_calibrated_truth,
)
from attica.kinds import axes, uses_mag
from attica.outputs import MAG_OFFSET_DTYPE, OUTPUT_DTYPE
from attica.settings import FilterKind, describe_flags

NAME = "run"
HELP = "run C filters over simulated or recorded data, print the attitude error (and check the bits)"

CHUNK = 20_000
"""Samples per C batch (the progress bar moves between batches)."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``attica run``."""
    p.add_argument("--filter", default="ars", help="filter kind, comma-separated kinds, or all (default ars)")
    p.add_argument(
        "--data", help="recording (.npz in BROAD layout, .csv, BROAD .hdf5/.mat); default: simulate"
    )
    add_sim_arguments(p)
    p.add_argument(
        "--set",
        action="append",
        metavar="NAME=VALUE",
        help="change a setting (repeatable; with several filters it applies to those that have it); "
        "`attica settings KIND` lists them with their accepted values",
    )
    add_calibration_argument(p, "the C filters (and the reference with --check)")
    p.add_argument("--check", action="store_true", help="also run the numpy reference and compare the bits")
    p.add_argument(
        "-o",
        "--output",
        metavar="FILE",
        help="write the outputs to FILE: .npz (arrays), .csv (time, q, Euler, bias, covariance, flags) or "
        ".mcap (ROS 2 sensor_msgs/Imu and /tf for Foxglove; needs attica[recordings]); several filters: "
        "NAME_<kind>.ext (docs/recordings.md)",
    )
    add_resample_argument(p)
    add_unit_check_argument(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


def run_native(
    kind: FilterKind,
    rec: Any,
    settings: Any,
    show_progress: bool,
    calibration: Any = None,
    end: dict[str, Any] | None = None,
) -> NDArray[np.void]:
    """Run the C filter over a recording in chunks (for the progress bar); (N,) output records.

    Each sample steps the filter over the periods since the one before (:attr:`Recording.steps`).
    ``end``, when given, receives what the records do not hold: where the filter's hard-iron estimate
    runs (:meth:`attica.native.Filter.mag_offset`), ``mag_offset``, its (N,) estimates after each step
    (:data:`attica.outputs.MAG_OFFSET_DTYPE`).
    """
    from attica import native

    f = native.Filter(kind, settings=settings, calibration=calibration)
    n = len(rec.gyr)
    out = np.zeros(n, OUTPUT_DTYPE)
    moff = None
    if end is not None and f.estimates_mag_offset:
        moff = end["mag_offset"] = np.zeros(n, MAG_OFFSET_DTYPE)
    steps = rec.steps  # n after n - 1 lost samples (Recording.time): the gap is integrated
    with progress(n, f"{kind.label} (C)", show_progress) as bar:
        for start in range(0, n, CHUNK):
            sl = slice(start, start + CHUNK)
            mo = moff[sl] if moff is not None else None
            out[sl] = f.run(
                rec.gyr[sl], rec.acc[sl], rec.mag[sl], check_units=False, steps=steps[sl], mag_offset=mo
            )
            bar.update(len(out[sl]))
    return out


def flag_summary(flags: NDArray[np.uint32]) -> str:
    """The most frequent flag combinations with their counts."""
    values, counts = np.unique(flags, return_counts=True)
    rows = sorted(zip(counts, values), reverse=True)[:6]
    return ", ".join(f"{describe_flags(int(v))}: {int(c)}" for c, v in rows)


def error_line(kind: FilterKind, rec: Any, out: NDArray[np.void], settings: Any = None) -> str:
    """The RMSE line of one filter (the same in ``run`` and ``demo``).

    A filter that uses the magnetometer with ``settings`` (None: the kind's defaults) is judged by its
    total, heading and inclination errors; the others (6-axis, or a 3-axis baseline) by inclination only.
    """
    from attica.metrics import evaluate

    if rec.quat_true is None:
        return f"{kind.label:>6}: no ground truth in this recording; last attitude {out['q'][-1]}"
    if rec.movement is not None and not np.any(rec.movement):
        return (
            f"{kind.label:>6}: no moving sample to score (the metric scores only the samples marked as "
            f"movement; a short simulation can be all rest: give a longer --duration); last attitude "
            f"{out['q'][-1]}"
        )
    e = evaluate(out["q"].astype(np.float64), rec.quat_true, rec.movement)
    if uses_mag(kind, settings):
        return (
            f"{kind.label:>6}: RMSE total {e.total:6.2f} deg   heading {e.heading:6.2f} deg   "
            f"inclination {e.inclination:6.2f} deg"
        )
    return (
        f"{kind.label:>6}: RMSE inclination {e.inclination:6.2f} deg "
        f"({axes(kind, settings)}-axis: heading not observable)"
    )


def crosscheck_line(
    kind: FilterKind, rec: Any, settings: Any, show_progress: bool, calibration: Any = None
) -> tuple[bool, list[str]]:
    """Run the numpy reference against the C filter; (bit-exact, report lines)."""
    import warnings

    from attica.checks import UnitWarning
    from attica.crosscheck import Stream, crosscheck

    with progress(0, f"{kind.label} reference", show_progress) as bar, warnings.catch_warnings():
        warnings.simplefilter("ignore", UnitWarning)  # the units were judged (and reported) once already

        def step(done: int, total: int) -> None:
            bar.total = total
            bar.update(done - bar.n)

        streams = [Stream(rec.gyr, rec.acc, rec.mag, rec.name)]
        r = crosscheck(kind, streams, settings, progress=step, calibration=calibration)
    verdict = "bit-exact" if r.ok else "MISMATCH"
    lines = [
        f"        C vs numpy reference: {r.steps} steps compared, {r.mismatched_steps} differ: {verdict}"
    ]
    if not r.ok:
        lines.append(f"        first difference: {r.first_mismatch}")
    return r.ok, lines


def output_paths(path: Path, kinds: list[FilterKind]) -> dict[FilterKind, Path]:
    """Where each filter's outputs go, the format by suffix (checked before any work; no suffix: .npz)."""
    from attica.data.export import output_format

    if path.is_dir():
        raise CliError(f"output {path} is a directory (give a file name, e.g. {path / 'out.csv'})")
    base = path if path.suffix else path.with_name(path.name + ".npz")
    try:
        output_format(base)
    except ValueError as exc:
        raise CliError(f"-o {exc}") from None
    if len(kinds) == 1:
        return {kinds[0]: check_output_file(base)}
    return {k: check_output_file(base.with_name(f"{base.stem}_{k.label}{base.suffix}")) for k in kinds}


def check_outputs(outputs: dict[FilterKind, Path], rec: Any) -> None:
    """Refuse, before the filters run, outputs that could not be written (.mcap: packages, stamps)."""
    from attica.data.export import check_output

    for path in outputs.values():
        try:
            check_output(path, rec)
        except (ValueError, ImportError) as exc:
            raise CliError(str(exc)) from None


def write_output(
    path: Path,
    kind: FilterKind,
    rec: Any,
    out: NDArray[np.void],
    settings: Any,
    convention: str = "enu",
    mag_offset: NDArray[np.void] | None = None,
) -> None:
    """Write one filter's outputs in the format of the suffix (:func:`attica.data.export.write_outputs`)."""
    from attica.data.export import write_outputs

    try:
        write_outputs(path, out, rec, kind, settings, convention, mag_offset)
    except OSError as exc:
        raise CliError(f"cannot write {path}: {exc.strerror or exc}") from None


def run(args: argparse.Namespace) -> int:
    """``attica run``."""
    kinds = parse_kinds(args.filter)
    check_data_or_sim(args)
    outputs = output_paths(Path(args.output), kinds) if args.output else {}
    overrides = plan_overrides(kinds, args.set or [])
    fit_to_simulation(args, overrides)
    cal = load_calibration(args)
    convention = str(cal.convention) if cal is not None else "enu"
    if convention != "enu" and any(p.suffix.lower() == ".mcap" for p in outputs.values()):
        from attica.data.export import MCAP_ENU_ONLY

        raise CliError(MCAP_ENU_ONLY.format(convention=convention))
    rec = load_data(args)
    check_outputs(outputs, rec)
    settings = {k: filter_settings(k, rec.rate, overrides[k]) for k in kinds}  # all checked before running
    print(f"{describe_source(args)}: {len(rec.gyr)} samples at {rec.rate:g} Hz")
    if rec.timing is not None:
        print(f"        {rec.timing.summary()}")
    if cal is not None:
        print(describe_calibration(cal, args.calibration))
        if rec.quat_true is not None:
            warn_calibrated_truth(cal)
    check_units(rec, args)
    status = 0
    for kind in kinds:
        t0 = time.perf_counter()
        end: dict[str, Any] = {}
        out = run_native(kind, rec, settings[kind], not args.quiet, cal, end)
        elapsed = time.perf_counter() - t0
        print(error_line(kind, rec, out, settings[kind]))
        print(f"        {len(out)} steps in {elapsed * 1e3:.0f} ms; flags: {flag_summary(out['flags'])}")
        moff = end.get("mag_offset")
        if moff is not None and len(moff):  # the on-device hard-iron estimate (also in the outputs)
            h = ", ".join(f"{v:.2f}" for v in moff["offset"][-1])
            state = "estimated" if moff["estimated"][-1] else "not observable yet: not applied"
            print(f"        hard-iron offset at the end: {h} uT ({state})")
        if args.check:
            ok, lines = crosscheck_line(kind, rec, settings[kind], not args.quiet, cal)
            print("\n".join(lines))
            status = status or (0 if ok else 1)
        if kind in outputs:
            write_output(outputs[kind], kind, rec, out, settings[kind], convention, moff)
            print(f"        wrote {outputs[kind]}")
    return status

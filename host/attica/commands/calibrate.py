"""``attica calibrate mag|gyro|accel REC``: fit a sensor calibration; ``calibrate send FILE``: apply it.

- ``mag``: hard- and soft-iron fit (robust ellipsoid fit) from a recording that turns the sensor
  through as many orientations as possible; refused when the samples cover too little of the sphere.
- ``gyro``: the gyro offset from the still periods (a few seconds untouched).
- ``accel``: accelerometer offset and sensitivity from six or more still positions (each axis up and
  down), and the misalignment from nine or more when they determine it.

It prints the parameters, the coverage or positions, and the residuals before and after; ``-o FILE``
writes the calibration file (JSON, the format of ``attica.calibration``), ``--update FILE`` merges the
fitted section into an existing file (so gyro, accel and mag can be fitted from separate recordings),
``--plot PNG`` draws the data before and after.

Recordings: .npz (BROAD layout), .csv, BROAD .hdf5/.mat; units rad/s, m/s^2, uT.

``send FILE`` applies a calibration file to a running node over CAN and with ``--verify`` proves the
node's outputs bit-exact against the reference with the same calibration (:mod:`._calsend`).
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from attica.commands._common import CliError, add_unit_check_argument, check_output_file, check_units

NAME = "calibrate"
HELP = "fit a magnetometer, gyro or accelerometer calibration (JSON file, plot); send one to a node"

SENSORS = ("mag", "gyro", "accel")
ACTIONS = (*SENSORS, "send")


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``attica calibrate``."""
    from attica.commands._calsend import add_send_arguments

    p.add_argument(
        "sensor",
        choices=ACTIONS,
        help="what to calibrate: mag, gyro or accel; or send (a calibration file to a node over CAN)",
    )
    p.add_argument(
        "recording",
        help="recording (.npz in BROAD layout, .csv, BROAD .hdf5/.mat); with send: the calibration file",
    )
    p.add_argument("-o", "--output", help="write the calibration file (JSON) here")
    p.add_argument(
        "--update",
        metavar="FILE",
        help="merge into this existing calibration file (the other sections are kept); written back to "
        "FILE unless -o is given",
    )
    p.add_argument("--plot", metavar="PNG", help="draw the data before and after the fit into this PNG")
    g = p.add_argument_group("mag")
    g.add_argument(
        "--field",
        type=float,
        metavar="UT",
        help="local field strength in uT (e.g. from the World Magnetic Model); default: det S = 1",
    )
    g.add_argument(
        "--min-coverage",
        type=float,
        metavar="FRACTION",
        help="coverage of the sphere needed, 0..1 (default 0.5)",
    )
    g = p.add_argument_group("accel")
    g.add_argument("--gravity", type=float, metavar="G", help="local gravity in m/s^2 (default 9.80665)")
    g.add_argument(
        "--misalignment",
        choices=("auto", "on", "off"),
        help="fit the misalignment: auto (when determined, 9+ positions; default), on, off",
    )
    g = p.add_argument_group("gyro")
    g.add_argument("--min-rest", type=float, metavar="S", help="still seconds needed (default 2)")
    add_unit_check_argument(p)
    add_send_arguments(p)


_ONLY = {
    "field": "mag",
    "min_coverage": "mag",
    "gravity": "accel",
    "misalignment": "accel",
    "min_rest": "gyro",
}


def _check_args(args: argparse.Namespace) -> tuple[Path, Path | None, Any, Path | None]:
    """Everything that can be refused before the work: options, paths, the file to update."""
    from attica.calibration import Calibration

    for name, sensor in _ONLY.items():
        if getattr(args, name) is not None and args.sensor != sensor:
            raise CliError(f"--{name.replace('_', '-')} applies to 'calibrate {sensor}', not {args.sensor}")
    for name in ("field", "gravity", "min_rest"):
        v = getattr(args, name)
        if v is not None and not (np.isfinite(v) and v > 0):
            raise CliError(f"--{name.replace('_', '-')} must be > 0, got {v:g}")
    if args.min_coverage is not None and not 0.0 <= args.min_coverage <= 1.0:
        raise CliError(f"--min-coverage is a fraction in [0, 1], got {args.min_coverage:g}")
    rec_path = Path(args.recording)
    if not rec_path.exists():
        raise CliError(f"no such recording: {rec_path}")
    if rec_path.is_dir():
        raise CliError(f"recording {rec_path} is a directory")
    base = Calibration()
    update = Path(args.update) if args.update else None
    if update is not None:
        if not update.is_file():
            raise CliError(f"--update {update}: no such calibration file (create one with -o)")
        try:
            base = Calibration.load(update)
        except (ValueError, OSError) as exc:
            raise CliError(f"--update: {exc}") from None
    out = Path(args.output) if args.output else update
    if out is not None:
        check_output_file(out, "calibration file")
    plot = Path(args.plot) if args.plot else None
    if plot is not None:
        if plot.suffix.lower() != ".png":
            raise CliError(f"--plot {plot}: the plot is a .png file")
        check_output_file(plot, "plot")
        from attica.calibration.plots import pyplot

        try:
            pyplot()
        except RuntimeError as exc:
            raise CliError(str(exc)) from None
    return rec_path, out, base, plot


def _vec(v: Any, fmt: str = "{:+.4f}") -> str:
    return "[" + ", ".join(fmt.format(float(x)) for x in v) + "]"


def _mat(m: Any, indent: int, fmt: str = "{:+.5f}") -> str:
    pad = "\n" + " " * indent
    return pad.join(_vec(r, fmt) for r in m)


def _fit_mag(args: argparse.Namespace, rec: Any, base: Any, plot: Path | None) -> tuple[Any, dict[str, Any]]:
    from attica.calibration.magfit import MIN_COVERAGE, fit_mag

    need = args.min_coverage if args.min_coverage is not None else MIN_COVERAGE
    f = fit_mag(rec.mag, field_strength=args.field, min_coverage=need)
    rejected = f.samples - f.inliers
    print(f"mag fit: {f.samples} samples, {rejected} rejected as outliers")
    print(f"  coverage      {f.coverage:.0%} of the sphere (needs {need:.0%})")
    std = _vec(f.hard_iron_std, "{:.3f}")
    print(f"  hard iron h   {_vec(f.model.hard_iron, '{:+.3f}')} uT (standard error {std})")
    print(f"  soft iron S   {_mat(f.model.soft_iron, 16)}")
    how = "given" if args.field is not None else "det S = 1"
    print(f"  field B       {f.field:.3f} uT ({how})")
    print(
        f"  residual | |m| - B |: before rms {f.before_rms:.3f} uT (max {f.before_max:.3f}), "
        f"after rms {f.after_rms:.3f} uT (max {f.after_max:.3f})"
    )
    if plot is not None:
        from attica.calibration.plots import plot_mag

        plot_mag(f, rec.mag, plot, rec.name)
    return dataclasses.replace(base, mag=f.model), f.record()


def _fit_gyro(args: argparse.Namespace, rec: Any, base: Any, plot: Path | None) -> tuple[Any, dict[str, Any]]:
    from attica.calibration.inertial import MIN_REST, fit_gyro

    f = fit_gyro(rec.gyr, rec.acc, rec.rate, base=base.gyro, min_rest=args.min_rest or MIN_REST)
    print(
        f"gyro fit: {f.rest.seconds:.1f} s still in {len(f.rest.segments)} period(s) "
        f"(thresholds: gyro std {f.rest.gyro_threshold:.2g} rad/s, accel std "
        f"{f.rest.accel_threshold:.2g} m/s^2)"
    )
    print(f"  offset o      {_vec(f.model.offset, '{:+.5f}')} rad/s")
    print(f"  spread        {_vec(f.spread, '{:.5f}')} rad/s between still periods")
    print(f"  noise         {_vec(f.noise, '{:.5f}')} rad/s")
    print(f"  residual |rate| when still: before rms {f.before_rms:.5f} rad/s, after rms {f.after_rms:.5f}")
    if not base.gyro.identity and (base.gyro.misalignment, base.gyro.sensitivity) != (
        f.model.misalignment,
        f.model.sensitivity,
    ):
        print("  (misalignment and sensitivity kept from the file)")
    if plot is not None:
        from attica.calibration.plots import plot_gyro

        plot_gyro(f, rec.gyr, plot, rec.name)
    return dataclasses.replace(base, gyro=f.model), f.record()


def _fit_accel(
    args: argparse.Namespace, rec: Any, base: Any, plot: Path | None
) -> tuple[Any, dict[str, Any]]:
    from attica.calibration.inertial import GRAVITY, fit_accel

    f = fit_accel(
        rec.acc, rec.gyr, rec.rate, gravity=args.gravity or GRAVITY, misalignment=args.misalignment or "auto"
    )
    what = "offset, sensitivity and misalignment" if f.misalignment else "offset and sensitivity"
    print(
        f"accel fit: {f.distinct} distinct positions in {f.positions.shape[0]} still period(s); "
        f"fitted {what} (condition number {f.condition:.3g})"
    )
    print(f"  offset o      {_vec(f.model.offset)} m/s^2 (standard error {_vec(f.offset_std, '{:.4f}')})")
    s_std = _vec(f.scale_std, "{:.5f}")
    print(f"  sensitivity s {_vec(f.model.sensitivity, '{:.5f}')} (standard error {s_std})")
    print(f"  misalignment  {_mat(f.model.misalignment, 16)}")
    print(
        f"  residual | |a| - g | over the positions: before rms {f.before_rms:.4f} m/s^2 "
        f"(max {float(np.max(np.abs(f.before))):.4f}), after rms {f.after_rms:.4f} "
        f"(max {float(np.max(np.abs(f.after))):.4f})"
    )
    if plot is not None:
        from attica.calibration.plots import plot_accel

        plot_accel(f, plot, rec.name)
    return dataclasses.replace(base, accel=f.model), f.record()


def run(args: argparse.Namespace) -> int:
    """``attica calibrate``."""
    from attica.calibration.errors import CalibrationError
    from attica.commands._calsend import check_mixed, run_send
    from attica.data import load_recording

    check_mixed(args)
    if args.sensor == "send":
        return run_send(args)
    rec_path, out, base, plot = _check_args(args)
    try:
        rec = load_recording(rec_path)
    except (ValueError, ImportError) as exc:
        raise CliError(f"{rec_path}: {exc}") from None
    print(f"{rec_path}: {rec.n} samples at {rec.rate:g} Hz ({rec.n / rec.rate:.1f} s)")
    if args.sensor == "mag" and not rec.has_mag:
        raise CliError(f"{rec_path}: the recording has no magnetometer samples")
    check_units(rec, args)
    fitter = {"mag": _fit_mag, "gyro": _fit_gyro, "accel": _fit_accel}[args.sensor]
    try:
        cal, record = fitter(args, rec, base, plot)
    except CalibrationError as exc:
        raise CliError(f"calibrate {args.sensor}: {exc}") from None
    record = {"recording": rec_path.name, **record}
    cal = dataclasses.replace(cal, fit={**base.fit, args.sensor: record})
    if plot is not None:
        print(f"wrote {plot}")
    if out is None:
        print("no calibration file written (give -o FILE, or --update FILE)")
        return 0
    cal.save(out)
    kept = [s for s in SENSORS if s != args.sensor and not getattr(base, s).identity]
    note = f"; kept {', '.join(kept)} from {args.update}" if kept else ""
    print(f"wrote {out} ({args.sensor} section{note})")
    return 0

"""Golden vectors: run the firmware as a stand-alone program on files and compare with the reference.

The runner ``tests/c/att_golden.c`` is compiled from the firmware sources with the strict flags of
firmware/cflags.txt and any compiler / optimisation level / target flags. It reads little-endian
table files and writes little-endian table files, so the same files serve native builds, qemu-user
and semihosted microcontroller builds (pass the emulator as ``prefix`` to :func:`run`).

Table file (see the comment at the top of att_golden.c): a 48-byte header (magic ``ATGV``,
version, rows, width, streams, reserved, a 24-byte tag naming the function or filter) and then
``rows * width`` little-endian 32-bit words (u32 or the bits of float32 values).

Typical use::

    runner = build_runner("clang", "-O3")
    rows = math_inputs("quat_mul", 100_000, seed=1)
    got = run_math(runner, "quat_mul", rows)
    want = reference_math("quat_mul", rows)
    assert same_bits(got, want).all()
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import re
import subprocess
import tempfile
import typing
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica import _build
from attica.outputs import OUTPUT_DTYPE
from attica.reference import detmath as dm
from attica.reference import sensor as ref_sensor
from attica.settings import FilterKind, implemented_kinds, make_settings

ROOT = _build.ROOT
RUNNER_SOURCE = ROOT / "tests" / "c" / "att_golden.c"
BUILD = ROOT / "build" / "golden"

MAGIC = b"ATGV"
VERSION = 1
HEADER_BYTES = 48
TAG_BYTES = 24
SETTINGS_FORMAT = "attica-settings-1"
OUTPUT_WIDTH = 17
"""Words per filter output row: att_output_t field by field (OUTPUT_DTYPE)."""

MATH_FUNCS: dict[str, tuple[int, int]] = {
    "sin": (1, 1),
    "cos": (1, 1),
    "atan2": (2, 1),
    "asin": (1, 1),
    "acos": (1, 1),
    "sqrt": (1, 1),
    "wrap_pi": (1, 1),
    "quat_mul": (8, 4),
    "quat_normalize": (4, 5),
    "quat_rotate": (7, 3),
    "quat_rotate_inv": (7, 3),
    "quat_from_euler": (3, 4),
    "quat_to_euler": (4, 3),
    "quat_to_matrix": (4, 9),
    "quat_from_rotvec": (3, 4),
    "quat_from_axis_angle": (4, 4),
    "vec3_normalize": (3, 4),
    "vec3_cross": (6, 3),
    "sensor_tilt": (3, 3),
}
"""Math functions of the runner: name -> (input width, output width), as in att_golden.c."""

FloatArray = NDArray[np.float32]


class GoldenError(RuntimeError):
    """The runner failed or a file is malformed."""


# --- table files -------------------------------------------------------------------------------


@dataclass(frozen=True)
class Table:
    """A table file: ``words`` (rows, width) of uint32, the tag and the number of streams."""

    tag: str
    streams: int
    words: NDArray[np.uint32]

    @property
    def floats(self) -> FloatArray:
        """The words reinterpreted as float32 (same shape)."""
        return self.words.view(np.float32)


def write_table(path: Path, data: NDArray[Any], tag: str = "", streams: int = 1) -> None:
    """Write a 2-D array of 32-bit values (float32, uint32 or int32) as a table file.

    Parameters
    ----------
    path
        File to write.
    data
        Array of shape (rows, width) and a 4-byte dtype; its bits are written little-endian.
    tag
        Name of the math function or filter the rows are for (checked by the runner), ASCII.
    streams
        Number of filter instances interleaved row by row; rows must be a multiple of it.

    """
    a = np.asarray(data)
    if a.ndim != 2 or a.dtype.itemsize != 4 or a.dtype.kind not in "fiu":
        raise ValueError(f"expected a 2-D array of 32-bit values, got {a.dtype} {a.shape}")
    rows, width = a.shape
    tag_bytes = tag.encode("ascii")
    if len(tag_bytes) > TAG_BYTES:
        raise ValueError(f"tag {tag!r} is longer than {TAG_BYTES} bytes")
    if streams < 1 or rows % streams:
        raise ValueError(f"{rows} rows are not a whole number of steps of {streams} streams")
    header = np.array([VERSION, rows, width, streams, 0], "<u4").tobytes()
    if a.dtype.kind == "f":
        bits = a.astype(np.float32, copy=False).view(np.uint32)
    elif a.dtype.kind == "i":
        bits = a.astype(np.int32, copy=False).view(np.uint32)
    else:
        bits = a.astype(np.uint32, copy=False)
    words = np.ascontiguousarray(bits).astype("<u4")
    with open(path, "wb") as fp:
        fp.write(MAGIC + header + tag_bytes.ljust(TAG_BYTES, b"\0"))
        fp.write(words.tobytes())


@dataclass(frozen=True)
class Header:
    """The header of a table file."""

    tag: str
    rows: int
    width: int
    streams: int


def _parse_header(raw: bytes, path: Path) -> Header:
    if len(raw) < HEADER_BYTES or raw[:4] != MAGIC:
        raise GoldenError(f"{path}: not an attica golden table")
    version, rows, width, streams, _ = (int(v) for v in np.frombuffer(raw, "<u4", 5, 4))
    if version != VERSION:
        raise GoldenError(f"{path}: version {version}, expected {VERSION}")
    return Header(raw[24:HEADER_BYTES].rstrip(b"\0").decode("ascii"), rows, width, streams)


def read_header(path: Path) -> Header:
    """Only the header of a table file."""
    with open(path, "rb") as fp:
        return _parse_header(fp.read(HEADER_BYTES), path)


def read_table(path: Path) -> Table:
    """Read a table file written by :func:`write_table` or the runner."""
    raw = Path(path).read_bytes()
    h = _parse_header(raw, path)
    tag, rows, width, streams = h.tag, h.rows, h.width, h.streams
    body = np.frombuffer(raw, "<u4", offset=HEADER_BYTES)
    if body.size != rows * width:
        raise GoldenError(f"{path}: {body.size} words, header says {rows} x {width}")
    return Table(tag, streams, body.astype(np.uint32).reshape(rows, width))


# --- settings files ----------------------------------------------------------------------------


def _float_bits(value: Any) -> str:
    return f"0x{int(np.float32(value).view(np.uint32)):08x}"


def settings_text(kind: str | int | FilterKind, settings: Any = None, calibration: Any = None) -> str:
    """Return the runner's key=value settings text for a settings dataclass (defaults when None).

    ``calibration`` (a Calibration or StageSettings; None: none) adds the ``calib.N`` lines of the
    input/output stages (att_calib_field_set order).

    Float fields are written as their float32 bit patterns (exact), integer/enum/bool fields as
    decimal numbers, vector fields as ``name.x``/``name.y``/``name.z`` (``name.w`` first for
    quaternions).
    """
    k = FilterKind.parse(kind)
    s = make_settings(k, settings)
    hints = typing.get_type_hints(type(s))
    lines = [f"# attica golden-runner settings for {k.label}", f"format={SETTINGS_FORMAT}", f"kind={k.label}"]
    for f in dataclasses.fields(s):
        value = getattr(s, f.name)
        hint = hints[f.name]
        if typing.get_origin(hint) is tuple:
            keys = "wxyz" if len(value) == 4 else "xyz"
            for key, v in zip(keys, value, strict=True):
                lines.append(f"{f.name}.{key}={_float_bits(v)}  # {np.float32(v)}")
        elif hint is float:
            lines.append(f"{f.name}={_float_bits(value)}  # {np.float32(value)}")
        elif hint is bool:
            lines.append(f"{f.name}={int(bool(value))}")
        else:
            lines.append(f"{f.name}={int(value)}")
    if calibration is not None:
        from attica.calibration.stages import fields
        from attica.reference.calib import as_stage_settings

        g = float(getattr(s, "gravity", 9.80665))
        for i, v in enumerate(fields(as_stage_settings(calibration, g))):
            lines.append(f"calib.{i}={_float_bits(v)}  # {np.float32(v)}")
    return "\n".join(lines) + "\n"


def write_settings(
    path: Path, kind: str | int | FilterKind, settings: Any = None, calibration: Any = None
) -> None:
    """Write :func:`settings_text` to ``path``."""
    Path(path).write_text(settings_text(kind, settings, calibration))


# --- building and running ----------------------------------------------------------------------


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.+-]+", "_", text).strip("_") or "x"


def fields_header_text() -> str:
    """The GV_FIELD table of the runner, one line per settings field of every implemented kind.

    The settings dataclasses in :mod:`attica.settings` use the C member names, so the table is derived
    from them: tuples become ``.x/.y/.z`` (3) or ``.w/.x/.y/.z`` (4) members, floats GV_F32, and
    ints, bools and enums GV_INT. A C member missing from the dataclass would fail to compile here
    only if misspelt; tests/test_settings.py checks the dataclasses against the C defaults.
    """
    lines = ["/* Generated by tools/attica_dev/golden.py from host/attica/settings.py: do not edit. */"]
    for kind in implemented_kinds():
        lines.append(f"#if ATT_WITH_{kind.name}")  # a kind compiled out has no member (att_config.h)
        settings = make_settings(kind)
        for f in dataclasses.fields(settings):
            value = getattr(settings, f.name)
            if isinstance(value, tuple):
                keys = ("x", "y", "z") if len(value) == 3 else ("w", "x", "y", "z")
                members = [(f"{f.name}.{k}", "GV_F32") for k in keys]
            elif isinstance(value, float):
                members = [(f.name, "GV_F32")]
            else:
                members = [(f.name, "GV_INT")]
            for member, typ in members:
                lines.append(f'GV_FIELD(ATT_FILTER_{kind.name}, "{member}", {kind.label}.{member}, {typ}),')
        lines.append("#endif")
    return "\n".join(lines) + "\n"


def write_fields_header(out_dir: Path) -> Path:
    """Write att_golden_fields.h into out_dir (atomically, only when it changed); return out_dir."""
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "att_golden_fields.h"
    text = fields_header_text()
    if not path.exists() or path.read_text() != text:
        fd, tmp = tempfile.mkstemp(prefix="att_golden_fields.", dir=out_dir)
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.replace(tmp, path)
    return out_dir


def build_program(
    sources: Sequence[Path],
    cc: str = "gcc",
    opt: str = "-O2",
    extra: Sequence[str] = (),
    name: str = "prog",
    out_dir: Path | None = None,
    ldflags: Sequence[str] = ("-lm",),
) -> Path:
    """Compile the firmware sources plus ``sources`` into one program with the strict firmware flags.

    Parameters
    ----------
    sources
        Extra C files (test harnesses) linked with firmware/src/**/*.c.
    cc
        Compiler command (``gcc``, ``clang``, ``arm-none-eabi-gcc``...).
    opt
        Optimisation flag, e.g. ``-O0``, ``-O2``, ``-Os``.
    extra
        More flags for compiling and linking (target, CPU, specs...), after the firmware flags.
    name
        File name of the program.
    out_dir
        Where to put it; default build/golden/<cc>_<opt>[_<hash of extra>]/.
    ldflags
        Flags for the link only, after the sources.

    Returns
    -------
    Path
        The program. It is written under a temporary name and renamed, so concurrent builds of the
        same configuration never see a half-written file.

    """
    if out_dir is None:
        tail = "_" + hashlib.sha256(" ".join(extra).encode()).hexdigest()[:8] if extra else ""
        out_dir = BUILD / _slug(f"{Path(cc).name}_{opt}{tail}")
    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / name
    fd, tmp_name = tempfile.mkstemp(prefix=name + ".", suffix=".tmp", dir=out_dir)
    os.close(fd)
    tmp = Path(tmp_name)
    cmd = [
        cc,
        *_build.cflags(),
        opt,
        *extra,
        "-I",
        str(_build.INCLUDE),
        "-I",
        str(write_fields_header(BUILD / "gen")),
        *[str(s) for s in [*_build.firmware_sources(), *sources]],
        "-o",
        str(tmp),
        *ldflags,
    ]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise GoldenError(f"build failed ({' '.join(cmd)}):\n{proc.stderr}")
        os.replace(tmp, target)
    finally:
        tmp.unlink(missing_ok=True)
    return target


def build_runner(
    cc: str = "gcc", opt: str = "-O2", extra: Sequence[str] = (), out_dir: Path | None = None
) -> Path:
    """Build the golden-vector runner (firmware + tests/c/att_golden.c); return its path."""
    return build_program([RUNNER_SOURCE], cc, opt, extra, "att_golden", out_dir)


def run(
    runner: Path, args: Sequence[str | Path], prefix: Sequence[str] = (), timeout: float | None = 600.0
) -> str:
    """Run ``prefix runner args`` (prefix e.g. ``["qemu-aarch64", "-L", sysroot]``); return stdout.

    Raises
    ------
    GoldenError
        When the program exits with a non-zero status (its stderr is in the message).

    """
    cmd = [*prefix, str(runner), *[str(a) for a in args]]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0:
        raise GoldenError(f"{' '.join(cmd)} exited with {proc.returncode}:\n{proc.stderr}")
    return proc.stdout


def _workdir(workdir: Path | None) -> tuple[Path, tempfile.TemporaryDirectory[str] | None]:
    if workdir is not None:
        workdir.mkdir(parents=True, exist_ok=True)
        return workdir, None
    tmp = tempfile.TemporaryDirectory(prefix="att_golden_")
    return Path(tmp.name), tmp


def run_math(
    runner: Path,
    fn: str,
    rows: Any,
    prefix: Sequence[str] = (),
    workdir: Path | None = None,
    in_file: Path | None = None,
) -> FloatArray:
    """Run math function ``fn`` of the runner over ``rows`` (n, in_width); return (n, out_width).

    ``in_file`` reuses an input file already written for these rows (then ``rows`` only gives the
    expected row count and may be None).
    """
    win, wout = MATH_FUNCS[fn]
    wd, tmp = _workdir(workdir)
    try:
        if in_file is None:
            a = np.ascontiguousarray(rows, np.float32)
            if a.ndim != 2 or a.shape[1] != win:
                raise ValueError(f"{fn}: expected rows of shape (n, {win}), got {a.shape}")
            in_file = wd / f"{fn}.in.bin"
            write_table(in_file, a, fn)
        out_file = wd / f"{fn}.{os.getpid()}.{Path(runner).parent.name}.out.bin"
        run(runner, ["math", fn, in_file, out_file], prefix)
        table = read_table(out_file)
        out_file.unlink()
    finally:
        if tmp is not None:
            tmp.cleanup()
    if table.tag != fn or table.words.shape[1] != wout:
        raise GoldenError(f"{fn}: runner wrote tag {table.tag!r} width {table.words.shape[1]}")
    return table.floats


def _imu_rows(gyr: Any, acc: Any, mag: Any) -> tuple[NDArray[np.float32], int, int]:
    """Turn inputs (N, 3) or (N, M, 3) into file rows (N*M, 6 or 9), step-major; returns rows, N, M."""
    g = np.asarray(gyr, np.float32)
    a = np.asarray(acc, np.float32)
    if g.ndim == 2:
        g, a = g[:, None, :], a[:, None, :]
    if g.ndim != 3 or g.shape[2] != 3 or a.shape != g.shape:
        raise ValueError(f"gyr and acc must have shape (N, 3) or (N, M, 3); got {g.shape}, {a.shape}")
    parts = [g, a]
    if mag is not None:
        m = np.asarray(mag, np.float32)
        m = m[:, None, :] if m.ndim == 2 else m
        if m.shape != g.shape:
            raise ValueError(f"mag must have the shape of gyr; got {m.shape}")
        parts.append(m)
    steps, streams = g.shape[0], g.shape[1]
    rows = np.concatenate(parts, axis=2).reshape(steps * streams, 3 * len(parts))
    return np.ascontiguousarray(rows), steps, streams


def write_filter_input(path: Path, kind: str | int | FilterKind, gyr: Any, acc: Any, mag: Any = None) -> None:
    """Write filter input rows: gyr, acc[, mag] of shape (N, 3) or (N, M, 3) (M interleaved streams)."""
    rows, _, streams = _imu_rows(gyr, acc, mag)
    write_table(path, rows, FilterKind.parse(kind).label, streams)


def run_filter(
    runner: Path,
    kind: str | int | FilterKind,
    settings: Any,
    gyr: Any,
    acc: Any,
    mag: Any = None,
    prefix: Sequence[str] = (),
    workdir: Path | None = None,
    in_file: Path | None = None,
    calibration: Any = None,
) -> NDArray[np.void]:
    """Run a filter in the runner; return (N, M) records of OUTPUT_DTYPE (att_output_t per step).

    Parameters
    ----------
    runner
        Program from :func:`build_runner`.
    kind
        Filter kind (``"ars"``...).
    settings
        Settings dataclass of the kind (None: defaults). Every instance gets the same settings.
    gyr, acc, mag
        (N, 3) or (N, M, 3) float32 inputs; M independent instances, all stepped N times.
    prefix
        Command prefix (emulator) for :func:`run`.
    workdir
        Directory for the files (default: a temporary one).
    in_file
        An input file already written by :func:`write_filter_input` for these inputs.
    calibration
        Input/output stages of every instance (Calibration or StageSettings; None: none).

    """
    k = FilterKind.parse(kind)
    if in_file is None:
        _, steps, streams = _imu_rows(gyr, acc, mag)
    else:
        h = read_header(in_file)
        steps, streams = h.rows // h.streams, h.streams
    wd, tmp = _workdir(workdir)
    try:
        tag = f"{k.label}.{os.getpid()}.{Path(runner).parent.name}"
        set_file = wd / f"{tag}.settings.txt"
        write_settings(set_file, k, settings, calibration)
        if in_file is None:
            in_file = wd / f"{tag}.in.bin"
            write_filter_input(in_file, k, gyr, acc, mag)
        out_file = wd / f"{tag}.out.bin"
        run(runner, [k.label, set_file, in_file, out_file], prefix)
        table = read_table(out_file)
        out_file.unlink()
    finally:
        if tmp is not None:
            tmp.cleanup()
    if table.tag != k.label or table.words.shape[1] != OUTPUT_WIDTH:
        raise GoldenError(f"{k.label}: runner wrote tag {table.tag!r} width {table.words.shape[1]}")
    records = table.words.astype("<u4").view(OUTPUT_DTYPE).reshape(-1)
    if records.size != steps * streams:
        raise GoldenError(f"{k.label}: {records.size} output rows for {steps} x {streams} steps")
    return records.reshape(steps, streams)


# --- reference ---------------------------------------------------------------------------------


def _q(a: FloatArray, i: int) -> dm.Quat:
    return (a[:, i], a[:, i + 1], a[:, i + 2], a[:, i + 3])


def _v(a: FloatArray, i: int) -> dm.Vec3:
    return (a[:, i], a[:, i + 1], a[:, i + 2])


def _reference_cols(fn: str, a: FloatArray) -> list[Any]:
    """Output columns of math function ``fn`` for input rows ``a`` (numpy reference)."""
    scalar: dict[str, Callable[[Any], Any]] = {
        "sin": dm.sinf,
        "cos": dm.cosf,
        "asin": dm.asinf,
        "acos": dm.acosf,
        "sqrt": dm.sqrtf,
        "wrap_pi": dm.wrap_pi,
    }
    if fn in scalar:
        return [scalar[fn](a[:, 0])]
    if fn == "atan2":
        return [dm.atan2f(a[:, 0], a[:, 1])]
    if fn == "quat_mul":
        return list(dm.quat_mul(_q(a, 0), _q(a, 4)))
    if fn == "quat_normalize":
        ok, q = dm.quat_normalize(_q(a, 0))
        return [*q, np.where(ok, dm.ONE, dm.ZERO)]
    if fn == "quat_rotate":
        return list(dm.quat_rotate(_q(a, 0), _v(a, 4)))
    if fn == "quat_rotate_inv":
        return list(dm.quat_rotate_inv(_q(a, 0), _v(a, 4)))
    if fn == "quat_from_euler":
        return list(dm.quat_from_euler(a[:, 0], a[:, 1], a[:, 2]))
    if fn == "quat_to_euler":
        return list(dm.quat_to_euler(_q(a, 0)))
    if fn == "quat_to_matrix":
        return dm.quat_to_matrix(_q(a, 0))
    if fn == "quat_from_rotvec":
        return list(dm.quat_from_rotvec(_v(a, 0)))
    if fn == "quat_from_axis_angle":
        return list(dm.quat_from_axis_angle(_v(a, 0), a[:, 3]))
    if fn == "vec3_normalize":
        ok, v = dm.vec3_normalize(_v(a, 0))
        return [*v, np.where(ok, dm.ONE, dm.ZERO)]
    if fn == "vec3_cross":
        return list(dm.vec3_cross(_v(a, 0), _v(a, 3)))
    if fn == "sensor_tilt":
        return list(ref_sensor.tilt(_v(a, 0)))
    raise KeyError(f"unknown math function {fn!r}")


def reference_math(fn: str, rows: Any) -> FloatArray:
    """Compute the numpy reference of math function ``fn`` over ``rows`` (n, in_width) -> (n, out_width)."""
    win, wout = MATH_FUNCS[fn]
    a = np.ascontiguousarray(rows, np.float32)
    if a.ndim != 2 or a.shape[1] != win:
        raise ValueError(f"{fn}: expected rows of shape (n, {win}), got {a.shape}")
    with np.errstate(all="ignore"):
        cols = _reference_cols(fn, a)
    out = np.empty((a.shape[0], wout), np.float32)
    for j, col in enumerate(cols):
        out[:, j] = np.broadcast_to(np.asarray(col, np.float32), (a.shape[0],))
    return out


def reference_filter(
    kind: str | int | FilterKind, settings: Any, gyr: Any, acc: Any, mag: Any = None, calibration: Any = None
) -> NDArray[np.void]:
    """Run the numpy reference filter on the same inputs as :func:`run_filter`: (N, M) records."""
    from attica.reference.filter import Filter

    g = np.asarray(gyr, np.float32)
    a = np.asarray(acc, np.float32)
    m = None if mag is None else np.asarray(mag, np.float32)
    if g.ndim == 2:
        g, a = g[:, None, :], a[:, None, :]
        m = None if m is None else m[:, None, :]
    f = Filter(kind, settings, n=g.shape[1], calibration=calibration)
    with np.errstate(all="ignore"):
        out = f.run(g, a, m, check_units=False)  # golden cases are adversarial on purpose
    return out.reshape(g.shape[0], g.shape[1])


# --- comparison --------------------------------------------------------------------------------


def same_bits(a: Any, b: Any) -> NDArray[np.bool_]:
    """Element-wise: identical float32 bits, or both NaN (NaN payloads are not compared)."""
    x = np.asarray(a, np.float32)
    y = np.asarray(b, np.float32)
    out: NDArray[np.bool_] = (x.view(np.uint32) == y.view(np.uint32)) | (np.isnan(x) & np.isnan(y))
    return out


def same_outputs(a: NDArray[np.void], b: NDArray[np.void]) -> NDArray[np.bool_]:
    """Per record of OUTPUT_DTYPE: every float field same_bits and flags/steps equal."""
    ok = (a["flags"] == b["flags"]) & (a["steps"] == b["steps"])
    for name in ("q", "euler", "gyro_bias", "cov"):
        ok &= same_bits(a[name], b[name]).all(axis=-1)
    return np.asarray(ok, np.bool_)


def hex32(values: Any) -> str:
    """float32 values as C99 hex-float literals, e.g. ``(0x1.99999ap-4, -0x0p+0, nan)``."""
    out = []
    for v in np.asarray(values, np.float32).ravel():
        if not np.isfinite(v):
            out.append(str(float(v)))
            continue
        text = float(v).hex()
        mant, _, exp = text.partition("p")
        if "." in mant:
            mant = mant.rstrip("0").rstrip(".")
        out.append(f"{mant}p{exp}")
    return "(" + ", ".join(out) + ")"


# --- inputs ------------------------------------------------------------------------------------


def _bits(u: Any) -> FloatArray:
    return np.asarray(u, np.uint32).view(np.float32)


def special_floats() -> FloatArray:
    """Return adversarial float32 values.

    Signed zeros, denormals, +-1 and neighbours, huge values, +-Inf, NaN, the trig domain edge
    8192 and its neighbours, multiples of pi/2 and pi and their neighbours.
    """
    f32 = np.float32
    base = np.array(
        [
            0.0,
            1.0,
            0.5,
            2.0,
            1e-30,
            1e-20,
            1e-10,
            1e-4,
            0.1,
            3.0,
            10.0,
            100.0,
            1e4,
            1e10,
            1e19,
            1e20,
            1e30,
            3.4028235e38,
            8191.0,
            8192.0,
            16384.0,
            2.0**-50,
            2.0**-63,
            9.80665,
            156.9064,
            34.906586,
        ],
        f32,
    )
    tiny = _bits([1, 2, 0x7FFFF, 0x400000, 0x7FFFFF, 0x800000, 0x800001])  # denormals and FLT_MIN
    one = np.float32(1.0)
    near_one = np.array(
        [
            np.nextafter(one, f32(0)),
            np.nextafter(one, f32(2)),
            np.nextafter(np.nextafter(one, f32(2)), f32(2)),
        ],
        f32,
    )
    edge = np.array([np.nextafter(f32(8192), f32(0)), np.nextafter(f32(8192), f32(1e9))], f32)
    k = np.array([1, 2, 3, 4, 5, 7, 8, 100, 1000, 5215, 5216], np.float64)
    pio2 = (k * (np.pi / 2)).astype(f32)
    pis = np.array([np.pi, np.pi / 4, np.pi / 8, 2 * np.pi, 3 * np.pi, 2607 * np.pi], np.float64).astype(f32)
    around = np.concatenate([pio2, pis])
    around = np.concatenate([around, np.nextafter(around, f32(0)), np.nextafter(around, f32(1e9))])
    pos = np.concatenate([base, tiny, near_one, edge, around])
    out = np.concatenate([pos, -pos, np.array([np.inf, -np.inf, np.nan, -np.nan], f32), _bits([0x7FA00000])])
    return np.asarray(out, np.float32)


def _random_bits(rng: np.random.Generator, shape: tuple[int, ...]) -> FloatArray:
    return _bits(rng.integers(0, 2**32, size=shape, dtype=np.uint64).astype(np.uint32))


def _log_uniform(rng: np.random.Generator, shape: tuple[int, ...], lo: float, hi: float) -> FloatArray:
    mag = np.exp(rng.uniform(np.log(lo), np.log(hi), size=shape))
    sign = np.where(rng.random(shape) < 0.5, -1.0, 1.0)
    return (sign * mag).astype(np.float32)


def _unit_quats(rng: np.random.Generator, n: int) -> FloatArray:
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q.astype(np.float32)


def _euler_quats(phi: NDArray[Any], theta: NDArray[Any], psi: NDArray[Any]) -> FloatArray:
    """ZYX Euler to quaternions in float64, rounded to float32 (test data, not the reference)."""
    cr, sr = np.cos(phi / 2), np.sin(phi / 2)
    cp, sp = np.cos(theta / 2), np.sin(theta / 2)
    cy, sy = np.cos(psi / 2), np.sin(psi / 2)
    q = [
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ]
    return np.stack(q, axis=1).astype(np.float32)


def _typical(fn: str, rng: np.random.Generator, n: int) -> FloatArray:
    """In-domain rows for each function (what the filters mostly feed it)."""
    f32 = np.float32
    u = rng.uniform
    if fn in ("sin", "cos"):
        return np.concatenate([u(-10, 10, n // 2), u(-8200, 8200, n - n // 2)]).astype(f32)[:, None]
    if fn == "wrap_pi":
        return np.concatenate([u(-7, 7, n // 2), u(-8200, 8200, n - n // 2)]).astype(f32)[:, None]
    if fn in ("asin", "acos"):
        near = (1.0 - _log_uniform(rng, (n // 4,), 1e-8, 1e-2).astype(np.float64)).astype(f32)
        return np.concatenate([u(-1.01, 1.01, n - n // 4).astype(f32), near]).astype(f32)[:, None]
    if fn == "sqrt":
        return np.abs(_log_uniform(rng, (n,), 1e-40, 1e38))[:, None]
    if fn == "atan2":
        y = u(-10, 10, n)
        x = u(-10, 10, n)
        ratio = rng.random(n) < 0.2  # y/x close to tan(pi/8), 1 and their reciprocals
        t = rng.choice([0.41421356, 1.0, 2.41421356], n) * (1 + u(-1e-6, 1e-6, n))
        y = np.where(ratio, x * t, y)
        return np.stack([y, x], axis=1).astype(f32)
    if fn in ("quat_mul",):
        return np.concatenate([_unit_quats(rng, n), _unit_quats(rng, n)], axis=1)
    if fn in ("quat_rotate", "quat_rotate_inv"):
        return np.concatenate([_unit_quats(rng, n), u(-20, 20, (n, 3)).astype(f32)], axis=1)
    if fn == "quat_normalize":
        return (_unit_quats(rng, n) * _log_uniform(rng, (n, 1), 1e-16, 1e16)).astype(f32)
    if fn == "quat_to_euler":
        q = _unit_quats(rng, n)
        gim = rng.random(n) < 0.25  # pitch at and near +-pi/2 (asin argument rounds to or past 1)
        eps = np.where(rng.random(n) < 0.2, 0.0, _log_uniform(rng, (n,), 1e-8, 1e-2).astype(np.float64))
        pitch = rng.choice([-1.0, 1.0], n) * (np.pi / 2 - eps)
        return np.where(gim[:, None], _euler_quats(u(-4, 4, n), pitch, u(-4, 4, n)), q).astype(f32)
    if fn == "quat_to_matrix":
        return _unit_quats(rng, n)
    if fn == "quat_from_euler":
        return np.concatenate([u(-4, 4, (n // 2, 3)), u(-16400, 16400, (n - n // 2, 3))]).astype(f32)
    if fn == "quat_from_rotvec":
        return (u(-1, 1, (n, 3)) * _log_uniform(rng, (n, 1), 1e-12, 2e4)).astype(f32)
    if fn == "quat_from_axis_angle":
        ax = rng.normal(size=(n, 3))
        ax /= np.linalg.norm(ax, axis=1, keepdims=True)
        ang = np.concatenate([u(-7, 7, n // 2), u(-16400, 16400, n - n // 2)])
        return np.concatenate([ax, ang[:, None]], axis=1).astype(f32)
    if fn == "vec3_normalize":
        return (u(-1, 1, (n, 3)) * _log_uniform(rng, (n, 1), 1e-25, 1e25)).astype(f32)
    if fn == "vec3_cross":
        return u(-100, 100, (n, 6)).astype(f32)
    if fn == "sensor_tilt":
        d = rng.normal(size=(n, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return (d * 9.80665 * u(0.5, 1.5, (n, 1))).astype(f32)
    raise KeyError(fn)


def math_inputs(fn: str, n: int, seed: int = 0) -> FloatArray:
    """Deterministic random + adversarial input rows (n, in_width) for math function ``fn``.

    About 55 % typical in-domain rows, then rows with special values (:func:`special_floats`) in
    random columns, every special value in every column at least once (when n allows), all-zero and
    all-special rows, rows scaled to huge and tiny magnitudes, log-uniform magnitudes over the whole
    float range and raw random bit patterns (every NaN payload, denormals, Inf).
    """
    win, _ = MATH_FUNCS[fn]
    rng = np.random.default_rng([seed, *fn.encode()])
    sp = special_floats()
    parts: list[FloatArray] = []
    # every special value in every column, the other columns typical
    grid = _typical(fn, rng, sp.size * win)
    for j in range(win):
        grid[j * sp.size : (j + 1) * sp.size, j] = sp
    parts.append(grid)
    # every special value in all columns at once (and zero rows)
    parts.append(np.repeat(sp[:, None], win, axis=1))
    rest = max(n - sum(p.shape[0] for p in parts), 0)
    n_typ = int(rest * 0.55)
    n_spec = int(rest * 0.15)
    n_scale = int(rest * 0.10)
    n_log = int(rest * 0.10)
    n_bits = rest - n_typ - n_spec - n_scale - n_log
    parts.append(_typical(fn, rng, n_typ))
    s = _typical(fn, rng, n_spec)
    mask = rng.random(s.shape) < 0.4
    s[mask] = rng.choice(sp, int(mask.sum()))
    parts.append(s)
    scale = _typical(fn, rng, n_scale).astype(np.float64)
    factors = np.array([0.0, 2.0**-50, 2.0**-60, 2.0**-75, 1e-30, 1e-40, 1e18, 1e19, 1e20, 1e30, 1e38])
    scale *= rng.choice(factors, (n_scale, 1))
    with np.errstate(over="ignore"):
        parts.append(scale.astype(np.float32))
    parts.append(_log_uniform(rng, (n_log, win), 1e-45, 3e38))
    parts.append(_random_bits(rng, (n_bits, win)))
    rows = np.concatenate(parts).astype(np.float32)
    return np.ascontiguousarray(rows[: max(n, 0)] if rows.shape[0] > n else rows)


def imu_inputs(
    steps: int, streams: int, seed: int = 0, dt: float = 0.01
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Deterministic synthetic IMU data (steps, streams, 3): gyr (rad/s), acc (m/s^2), mag (uT).

    Every stream is a random sequence of segments: at rest (small rates around a per-stream bias,
    gravity along a fixed tilt), slow and fast motion with accelerations, over-range gyro and
    accel, free fall. The magnetometer sees a 49 uT field with a 63 degree dip in the attitude
    implied by the accel direction, sometimes disturbed. About 1 % of the rows of each sensor get a
    corrupted component (NaN, +-Inf, huge, denormal), 0.3 % are zero vectors, and 1 % of the mag
    rows are absent (all NaN). Meant to exercise every branch of the filters, not to be physically
    consistent.
    """
    rng = np.random.default_rng([seed, 0x1A5])
    g0 = 9.80665
    b0, dip = 49.0, 1.1
    m_earth = np.array([0.0, b0 * np.cos(dip), -b0 * np.sin(dip)])
    gyr = np.empty((steps, streams, 3))
    acc = np.empty((steps, streams, 3))
    mag = np.empty((steps, streams, 3))
    for m in range(streams):
        bias = rng.normal(0, 0.01, 3)
        t = 0
        while t < steps:
            length = int(rng.integers(5, max(int(1.5 / dt), 6)))
            end = min(t + length, steps)
            k = end - t
            kind = rng.choice(5, p=[0.35, 0.3, 0.2, 0.1, 0.05])
            d = rng.normal(size=3) + np.array([0, 0, 2.0])
            d /= np.linalg.norm(d)
            ex = np.cross(d, rng.normal(size=3))
            ex /= np.linalg.norm(ex)
            ey = np.cross(d, ex)
            field_s = m_earth[0] * ex + m_earth[1] * ey + m_earth[2] * d
            if kind == 0:  # rest
                w = bias + rng.normal(0, 0.003, (k, 3))
                a = g0 * d + rng.normal(0, 0.02, (k, 3))
            elif kind == 1:  # slow motion
                w = bias + np.cumsum(rng.normal(0, 0.05, (k, 3)), axis=0) + rng.normal(0, 0.5, 3)
                a = g0 * d + rng.normal(0, 0.5, (k, 3))
            elif kind == 2:  # fast motion, linear acceleration
                w = rng.normal(0, 4.0, 3) + rng.normal(0, 0.3, (k, 3))
                a = g0 * d * rng.uniform(0.3, 2.0) + rng.normal(0, 3.0, (k, 3))
            elif kind == 3:  # over range
                w = rng.choice([-1, 1], (k, 3)) * rng.uniform(20, 50, (k, 3))
                a = rng.normal(0, 120, (k, 3))
            else:  # free fall / near-zero accel, zero rate
                w = np.zeros((k, 3)) if rng.random() < 0.5 else bias + rng.normal(0, 1e-4, (k, 3))
                a = rng.normal(0, 0.05, (k, 3)) * rng.choice([0.0, 1.0])
            disturbance = rng.choice([0.0, 0.0, 0.0, 0.3, 1.0]) * rng.normal(0, b0, 3)
            gyr[t:end, m] = w
            acc[t:end, m] = a
            mag[t:end, m] = field_s + disturbance + rng.normal(0, 0.3, (k, 3))
            t = end
    out = (gyr.astype(np.float32), acc.astype(np.float32), mag.astype(np.float32))
    specials = np.array([np.nan, np.inf, -np.inf, 0.0, -0.0, 1e30, -1e30, 1e-40, 3.4028235e38], np.float32)
    for arr in out:
        bad = rng.random((steps, streams)) < 0.01
        comp = rng.integers(0, 3, (steps, streams))
        vals = rng.choice(specials, (steps, streams))
        idx = np.nonzero(bad)
        arr[idx[0], idx[1], comp[idx]] = vals[idx]
        zero = rng.random((steps, streams)) < 0.003
        arr[zero] = 0.0
    out[2][rng.random((steps, streams)) < 0.01] = np.nan
    return out

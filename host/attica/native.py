"""cffi binding of the attica firmware (the same C sources, built with the same strict flags).

The extension is built by ``make build`` (``python -m attica._build``); if it is missing or older
than the firmware sources, importing this module builds it first (needs a C compiler).

Scalar and batch entry points take float32 numpy arrays and loop in C without copying
(``ffi.from_buffer``); arrays of another dtype or layout are converted once.
"""

from __future__ import annotations

import fcntl
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica import _build
from attica.calibration.stages import fill_c
from attica.outputs import OUTPUT_DTYPE
from attica.settings import FilterKind, Preset, make_settings, to_dict


def _load() -> tuple[Any, Any]:
    lock_path = _build.ROOT / "build" / ".native.lock"
    lock_path.parent.mkdir(parents=True, exist_ok=True)
    with open(lock_path, "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if _build.is_stale():
            _build.build()
    from attica import _native  # type: ignore[attr-defined]

    return _native.ffi, _native.lib


ffi, lib = _load()


def _f32(x: Any) -> NDArray[np.float32]:
    return np.ascontiguousarray(x, dtype=np.float32)


def _fptr(a: NDArray[Any]) -> Any:
    return ffi.from_buffer("float[]", a)


def _map1(fn: int, x: Any) -> NDArray[np.float32]:
    xa = _f32(x)
    y = np.empty_like(xa)
    if lib.att_host_map1(fn, _fptr(xa), _fptr(y), xa.size) != 0:
        raise ValueError(f"unknown function {fn}")
    return y


def sinf(x: Any) -> NDArray[np.float32]:
    """att_sinf over an array."""
    return _map1(lib.ATT_HOST_SIN, x)


def cosf(x: Any) -> NDArray[np.float32]:
    """att_cosf over an array."""
    return _map1(lib.ATT_HOST_COS, x)


def asinf(x: Any) -> NDArray[np.float32]:
    """att_asinf over an array."""
    return _map1(lib.ATT_HOST_ASIN, x)


def acosf(x: Any) -> NDArray[np.float32]:
    """att_acosf over an array."""
    return _map1(lib.ATT_HOST_ACOS, x)


def sqrtf(x: Any) -> NDArray[np.float32]:
    """att_sqrtf over an array."""
    return _map1(lib.ATT_HOST_SQRT, x)


def wrap_pi(x: Any) -> NDArray[np.float32]:
    """att_wrap_pi over an array."""
    return _map1(lib.ATT_HOST_WRAP_PI, x)


def atan2f(y: Any, x: Any) -> NDArray[np.float32]:
    """att_atan2f over arrays of equal shape."""
    ya, xa = np.broadcast_arrays(_f32(y), _f32(x))
    ya, xa = _f32(ya), _f32(xa)
    out = np.empty_like(ya)
    lib.att_host_atan2(_fptr(ya), _fptr(xa), _fptr(out), ya.size)
    return out


_MAPQ = {
    "quat_mul": (0, 8, 4),
    "quat_normalize": (1, 4, 5),
    "quat_rotate": (2, 7, 3),
    "quat_from_euler": (3, 3, 4),
    "quat_to_euler": (4, 4, 3),
    "quat_to_matrix": (5, 4, 9),
    "quat_from_rotvec": (6, 3, 4),
    "quat_from_axis_angle": (7, 4, 4),
    "vec3_normalize": (8, 3, 4),
    "vec3_cross": (9, 6, 3),
    "sensor_tilt": (10, 3, 3),
}


def mapq(name: str, rows: Any) -> NDArray[np.float32]:
    """Run a vector/quaternion kernel row by row.

    ``rows`` has shape (n, in_width) with the inputs concatenated (e.g. ``quat_mul``: a then b,
    width 8); returns (n, out_width). Kernels that report success (``*_normalize``) append 1.0 or
    0.0 as the last output column.
    """
    fn, win, wout = _MAPQ[name]
    a = _f32(rows)
    if a.ndim != 2 or a.shape[1] != win:
        raise ValueError(f"{name}: expected shape (n, {win}), got {a.shape}")
    out = np.empty((a.shape[0], wout), np.float32)
    if lib.att_host_mapq(fn, _fptr(a), win, _fptr(out), wout, a.shape[0]) != 0:
        raise ValueError(f"{name}: kernel refused its arguments")
    return out


class NativeError(RuntimeError):
    """A C function returned an error status."""


def _check(status: int, what: str) -> None:
    if status == lib.ATT_ERR_NULL:
        raise NativeError(f"{what}: NULL argument")
    if status == lib.ATT_ERR_SETTINGS:
        raise NativeError(f"{what}: a setting is out of range or not finite")
    if status == lib.ATT_ERR_KIND:
        raise NativeError(f"{what}: not supported by this filter kind (or not initialised)")
    if status == lib.ATT_ERR_STATE:
        raise NativeError(f"{what}: the filter is not initialised yet (no valid sample)")
    if status != lib.ATT_OK:
        raise NativeError(f"{what}: status {status}")


def _fill(struct: Any, values: dict[str, Any]) -> None:
    """Copy dataclass values into a cffi struct (tuples into nested vec3/quat fields)."""
    for name, value in values.items():
        if isinstance(value, tuple):
            sub = getattr(struct, name)
            keys = ("x", "y", "z") if len(value) == 3 else ("w", "x", "y", "z")
            for k, v in zip(keys, value):
                setattr(sub, k, float(v))
        elif isinstance(value, bool):
            setattr(struct, name, value)
        elif isinstance(value, int):
            setattr(struct, name, int(value))
        else:
            setattr(struct, name, float(value))


def default_settings(kind: str | int | FilterKind, dt: float = 0.01, preset: str | int = 0) -> dict[str, Any]:
    """The C settings of a kind as a dict of its settings fields.

    The defaults (att_filter_settings_default) or a named preset (att_filter_settings_preset, ``"seed"``).
    """
    k = FilterKind.parse(kind)
    p = Preset.parse(preset)
    s = ffi.new("att_filter_settings_t *")
    if p == Preset.DEFAULT:
        _check(lib.att_filter_settings_default(int(k), dt, s), "att_filter_settings_default")
    else:
        _check(lib.att_filter_settings_preset(int(k), int(p), dt, s), "att_filter_settings_preset")
    member = getattr(s, k.label)
    out: dict[str, Any] = {}
    for name in to_dict(make_settings(k)):
        v = getattr(member, name)
        if isinstance(v, ffi.CData) and ffi.typeof(v).kind == "struct":
            keys = [fname for fname, _ in ffi.typeof(v).fields]
            v = tuple(getattr(v, key) for key in keys)
        out[name] = v
    return out


class Filter:
    """Any C filter through the unified interface (``att_filter_t``).

    Parameters
    ----------
    kind
        ``"ars"``, ``"gyro"``, ``"tilt"``... or a :class:`FilterKind`.
    settings
        A settings dataclass for the kind (defaults when None).
    dt
        Sample period in s (overrides ``settings.dt``).
    calibration
        Input/output stages (att_filter_calibrate): a :class:`~attica.calibration.Calibration`, a
        :class:`~attica.calibration.stages.StageSettings` or None (identity, ENU).
    accel_outputs
        Keep each step's accel for :meth:`accel` (g: the kind's ``gravity`` setting, else 9.80665).
    **overrides
        Settings fields to change.

    """

    def __init__(
        self,
        kind: str | int | FilterKind,
        settings: Any = None,
        dt: float | None = None,
        calibration: Any = None,
        accel_outputs: bool = False,
        **overrides: Any,
    ) -> None:
        self.kind = FilterKind.parse(kind)
        self.settings = make_settings(self.kind, settings, dt, **overrides)
        self._s = ffi.new("att_filter_settings_t *")
        _check(lib.att_filter_settings_default(int(self.kind), 0.01, self._s), "att_filter_settings_default")
        _fill(getattr(self._s, self.kind.label), to_dict(self.settings))
        self._f = ffi.new("att_filter_t *")
        _check(lib.att_filter_init(self._f, int(self.kind), self._s), f"att_filter_init({self.kind.label})")
        self._in = ffi.new("att_sample_t *")
        if calibration is not None or accel_outputs:
            self.calibrate(calibration, float(getattr(self.settings, "gravity", 9.80665)), accel_outputs)

    def calibrate(self, calibration: Any, gravity: float = 9.80665, accel_outputs: bool = False) -> None:
        """att_filter_calibrate: new input/output stages, the state kept (NativeError says why if refused)."""
        from attica.reference.calib import as_stage_settings

        cs = ffi.new("att_calib_settings_t *")
        fill_c(cs, as_stage_settings(calibration, gravity, accel_outputs))
        problem = lib.att_calib_settings_check(cs)
        if problem != lib.ATT_CALIB_OK:
            why = ffi.string(lib.att_calib_error_name(problem)).decode()
            raise NativeError(f"att_filter_calibrate: {why}")
        _check(lib.att_filter_calibrate(self._f, cs), "att_filter_calibrate")

    def accel(self) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]] | None:
        """att_filter_accel: (gravity, linear, earth), each (3,) m/s^2; None when not available."""
        a = ffi.new("att_accel_t *")
        lib.att_filter_accel(self._f, a)
        if a.valid != lib.ATT_OUT_ACCEL:
            return None
        vecs = (a.gravity, a.linear, a.earth)
        return tuple(np.array([v.x, v.y, v.z], np.float32) for v in vecs)  # type: ignore[return-value]

    def set_heading(self, heading: float) -> None:
        """att_filter_set_heading (rad, the output convention's yaw)."""
        _check(lib.att_filter_set_heading(self._f, heading), "att_filter_set_heading")

    def heading_update(self, heading: float, gain: float, valid: bool = True) -> None:
        """att_filter_heading_update (ars, kf, ekf, gyro)."""
        _check(lib.att_filter_heading_update(self._f, heading, gain, valid), "att_filter_heading_update")

    def reset(self) -> None:
        """att_filter_reset."""
        lib.att_filter_reset(self._f)

    def output(self) -> NDArray[np.void]:
        """att_filter_output: the current output record (shape ())."""
        out = np.zeros((), OUTPUT_DTYPE)
        lib.att_filter_output(self._f, ffi.from_buffer("att_output_t[]", out))
        return out

    def step(self, gyr: Any, acc: Any, mag: Any = None, full: bool = True) -> NDArray[np.void]:
        """One step; 3-sequences gyr (rad/s), acc (m/s^2), mag (uT, None = absent). Returns a record.

        With ``full`` (default) the record is the whole att_filter_output after the step (Euler angles
        and covariance included); otherwise only what att_filter_step fills (see the ``valid`` field).
        """
        for name, v in (("gyr", gyr), ("acc", acc), ("mag", mag if mag is not None else (0.0, 0.0, 0.0))):
            a = _f32(v)
            if a.shape != (3,):
                raise ValueError(f"{name} must have 3 components, got shape {a.shape}")
            dst = getattr(self._in, name)
            dst.x, dst.y, dst.z = float(a[0]), float(a[1]), float(a[2])
        out = np.zeros((), OUTPUT_DTYPE)
        buf = ffi.from_buffer("att_output_t[]", out)
        lib.att_filter_step(self._f, self._in, buf)
        if full:
            lib.att_filter_output(self._f, buf)
        return out

    @property
    def state(self) -> Any:
        """The C state (``att_filter_t *``; live, not a copy)."""
        return self._f

    def run(self, gyr: Any, acc: Any, mag: Any = None, snapshot_every: int = 0, full: bool = True) -> Any:
        """N steps in C over (N, 3) arrays without copying float32 C-contiguous input; (N,) records.

        With ``full`` (default) every record is the whole att_filter_output after its step (Euler
        angles, covariance); ``full=False`` keeps only what att_filter_step fills (q, gyro_bias, flags,
        steps; see the ``valid`` field), which is what a firmware loop pays for. With
        ``snapshot_every`` > 0 returns ``(records, snapshots)`` where snapshots is a cffi array of
        ``att_filter_t`` holding the state just before steps 0, k, 2k, ...
        """
        g = _f32(gyr)
        a = _f32(acc)
        m = _f32(mag) if mag is not None else None
        if g.ndim != 2 or g.shape[1] != 3 or a.shape != g.shape or (m is not None and m.shape != g.shape):
            shapes = ", ".join(str(x.shape) for x in (g, a, m) if x is not None)
            raise ValueError(f"gyr, acc (and mag) must all have shape (N, 3); got {shapes}")
        out = np.zeros(g.shape[0], OUTPUT_DTYPE)
        every = max(int(snapshot_every), 0)
        snaps = ffi.new("att_filter_t[]", -(-g.shape[0] // every)) if every else ffi.NULL
        lib.att_host_filter_run(
            self._f,
            _fptr(g),
            _fptr(a),
            _fptr(m) if m is not None else ffi.NULL,
            g.shape[0],
            ffi.from_buffer("att_output_t[]", out),
            1 if full else 0,
            every,
            snaps,
        )
        if every:
            return out, snaps
        return out

"""cffi binding of the attica firmware (the same C sources, built with the same strict flags).

The extension ``attica._native`` is built when the wheel is built (the build hook of setup.py) or,
in an editable checkout, by ``make build`` (``python -m attica._build``). Importing this module never
compiles or writes anything: a missing extension, or one older than the checkout's sources, is an
ImportError that says what to run.

Scalar and batch entry points take float32 numpy arrays and loop in C without copying
(``ffi.from_buffer``); arrays of another dtype or layout are converted once.
"""

from __future__ import annotations

import re
from typing import Any, Literal, NamedTuple, overload

import numpy as np
from numpy.typing import NDArray

from attica.calibration.stages import fill_c
from attica.checks import filter_settings, imu_arrays, warn_units
from attica.cview import CView
from attica.outputs import MAG_OFFSET_DTYPE, OUTPUT_DTYPE
from attica.results import Outputs, as_outputs
from attica.settings import FilterKind, Preset, make_settings, to_dict


def _load() -> tuple[Any, Any]:
    from attica import _build

    try:
        from attica import _native
    except ImportError as exc:
        raise ImportError(
            f"attica's C extension (attica._native) is not built ({exc}): in a checkout run `make build`; "
            "otherwise reinstall attica (pip install attica-*.whl, or pip install . from the sources)"
        ) from exc
    if _build.STAMP.exists() and _build.is_stale():  # an editable checkout whose sources changed
        raise ImportError(
            f"attica._native ({_native.__file__}) was built from other sources than the checkout's "
            f"{_build.FIRMWARE}: run `make build`"
        )
    return _native.ffi, _native.lib


ffi, lib = _load()


try:  # the CPython method behind Filter.update (built beside attica._native; absent: the cffi path)
    from attica import _live
except ImportError:  # pragma: no cover - a build without it (another interpreter)
    _live = None


def _stepper(f: Any, out: Any, keep: Any) -> Any:
    """An ``attica._live.Stepper`` for filter ``f`` writing record ``out`` (None without _live)."""
    if _live is None:
        return None
    addr = int(ffi.cast("uintptr_t", ffi.addressof(lib, "att_host_step9")))
    return _live.Stepper(addr, int(ffi.cast("uintptr_t", f)), int(ffi.cast("uintptr_t", out)), keep)


_STEP_BLOCK = 256
"""Output records allocated at once by :meth:`Filter.step`."""


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


class SettingsError(NativeError, ValueError):
    """The C library refuses a settings field: ``att_filter_settings_check``'s answer.

    ``field`` is the first refused field as ``"<kind>.<field>"`` (``"ars.tau_acc_lp"``,
    ``"ekf.euler_init.y"``), ``value`` its value (a float, or a tuple for a vector or quaternion),
    ``rule`` the accepted values in words (``"[0, 1e4]"``, ``"(gravity, 1e4]"``), ``minimum`` and
    ``maximum`` the rule's bounds for the settings checked (the other fields' values filled in), ``unit``
    the field's unit (``""`` for none). Also a ``ValueError``, and a :class:`NativeError` as before.
    """

    def __init__(
        self, what: str, field: str, value: Any, minimum: float, maximum: float, rule: str, unit: str
    ) -> None:
        self.field = field
        self.value = value
        self.minimum = minimum
        self.maximum = maximum
        self.rule = rule
        self.unit = unit
        super().__init__(f"{what}: {field} = {_value_text(value)} is out of range: allowed {self.allowed}")

    @property
    def allowed(self) -> str:
        """The rule with its unit, and the bounds it names as numbers.

        ``"[0, 1e4] s"``; ``"(gravity, 1e4] m/s^2, here (9.80665, 10000.0]"``.
        """
        text = self.rule + (f" {self.unit}" if self.unit else "")
        interval = _INTERVAL.match(self.rule)
        if interval and not (_NUMBER.fullmatch(interval["lo"]) and _NUMBER.fullmatch(interval["hi"])):
            lo, hi = _value_text(self.minimum), _value_text(self.maximum)
            text += f", here {self.rule[0]}{lo}, {hi}{self.rule[-1]}"
        return text


_INTERVAL = re.compile(r"^[\[(](?P<lo>[^,]+), (?P<hi>[^,\])]+)[\])]$")
"""A rule that is an interval: "[lo, hi]", "(lo, hi]" ... (its bounds numbers or field names)."""
_NUMBER = re.compile(r"-?[0-9.]+(e[+-]?[0-9]+)?(\^-?[0-9]+)?")


def _value_text(value: Any) -> str:
    """A settings value as the float32 it is in C (shortest text), tuples component by component."""
    if isinstance(value, tuple):
        return "(" + ", ".join(_value_text(v) for v in value) + ")"
    if isinstance(value, float):
        return str(np.float32(value))
    return repr(value)


def _c_value(member: Any, path: str) -> Any:
    """The value of a settings field of the C struct ``member`` by dotted path (structs as tuples)."""
    v = member
    for name in path.split("."):
        try:
            v = getattr(v, name)
        except ValueError:  # a bool whose byte is neither 0 nor 1 (possible only through raw memory)
            return "invalid bool"
    if isinstance(v, ffi.CData) and ffi.typeof(v).kind == "struct":
        return tuple(getattr(v, fname) for fname, _ in ffi.typeof(v).fields)
    return v


def settings_problem(
    kind: str | int | FilterKind, settings: Any, what: str = "settings"
) -> SettingsError | None:
    """Why the C library refuses settings (``att_filter_settings_check``), or None when it accepts them.

    Parameters
    ----------
    kind
        The filter kind (name, number or :class:`FilterKind`).
    settings
        A settings dataclass of the kind, or a cffi ``att_filter_settings_t *``.
    what
        The start of the error's message (the call that refused them).

    Returns
    -------
    SettingsError or None
        The first refused field with its value, range and rule (raise it), or None (accepted).

    Raises
    ------
    NativeError
        The kind is unknown or compiled out.

    """
    k = FilterKind.parse(kind)
    if isinstance(settings, ffi.CData):
        s = settings
    else:
        s = _c_settings(k, make_settings(k, settings))
    why = ffi.new("att_settings_error_t *")
    status = lib.att_filter_settings_check(int(k), s, why)
    if status != lib.ATT_ERR_SETTINGS:
        _check(status, what)
        return None
    field = ffi.string(why.field).decode()
    member, path = field.split(".", 1)
    return SettingsError(
        what,
        field,
        _c_value(getattr(s, member), path),
        float(why.min),
        float(why.max),
        ffi.string(why.rule).decode(),
        ffi.string(why.unit).decode(),
    )


def _c_settings(kind: FilterKind, settings: Any) -> Any:
    """A new ``att_filter_settings_t *`` holding the settings dataclass of ``kind``."""
    s = ffi.new("att_filter_settings_t *")
    _check(lib.att_filter_settings_default(int(kind), 0.01, s), "att_filter_settings_default")
    _fill(getattr(s, kind.label), to_dict(settings))
    return s


def _check_settings(kind: FilterKind, s: Any, what: str) -> None:
    """Raise :class:`SettingsError` naming the refused field when the C library refuses ``s``."""
    problem = settings_problem(kind, s, what)
    if problem is not None:
        raise problem


def _check(status: int, what: str) -> None:
    if status == lib.ATT_ERR_NULL:
        raise NativeError(f"{what}: NULL argument")
    if status == lib.ATT_ERR_SETTINGS:
        raise NativeError(f"{what}: a setting is out of range or not finite")
    if status == lib.ATT_ERR_KIND:
        raise NativeError(f"{what}: not supported by this filter kind (or not initialised)")
    if status == lib.ATT_ERR_STATE:
        raise NativeError(f"{what}: the filter is not initialised yet (no valid sample)")
    if status == lib.ATT_ERR_DISABLED:
        raise NativeError(f"{what}: compiled out of this build (att_config.h ATT_WITH_*)")
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


class MagOffset(NamedTuple):
    """att_mag_offset_t: the hard-iron estimate of a mars or mekf filter (:meth:`Filter.mag_offset`)."""

    offset: NDArray[np.float32]
    """(3,) uT, the frame of the samples the filter sees; 0 until estimated."""
    on: bool
    """The estimate runs (``hard_iron_tau`` > 0)."""
    estimated: bool
    """The rotations have made the offset observable."""


def _check_mag_offset_array(a: Any, n: int, who: str) -> None:
    """ValueError unless ``a`` is a writeable C-contiguous (n,) array of MAG_OFFSET_DTYPE."""
    if not isinstance(a, np.ndarray) or a.dtype != MAG_OFFSET_DTYPE or a.shape != (n,):
        got = f"{a.shape} {a.dtype}" if isinstance(a, np.ndarray) else type(a).__name__
        raise ValueError(
            f"{who}: mag_offset must be an ({n},) array of attica.outputs.MAG_OFFSET_DTYPE, not {got}"
        )
    if not (a.flags.c_contiguous and a.flags.writeable):
        raise ValueError(
            f"{who}: mag_offset must be writeable C-contiguous memory (np.zeros(n, MAG_OFFSET_DTYPE))"
        )


class Filter:
    """Any C filter through the unified interface (``att_filter_t``).

    ``Filter("ars", 0.01)``: the ARS at 100 Hz with its default settings; the second argument is the
    sample period in seconds, as in VQF (required for every kind with a sample period).

    Parameters
    ----------
    kind
        A kind name of :mod:`attica.kinds` (``"ars"``, ``"mekf"`` ...), its number or a :class:`FilterKind`.
    dt
        Sample period in s (overrides ``settings.dt``). Required unless ``settings`` is given (it
        carries ``dt``); the accel-only ``tilt`` has none. A settings dataclass in this place is taken
        as ``settings``.
    settings
        A settings dataclass for the kind (the kind's defaults when None).
    calibration
        Input/output stages (att_filter_calibrate): a :class:`~attica.calibration.Calibration`, a
        :class:`~attica.calibration.stages.StageSettings` or None (identity, ENU).
    accel_outputs
        Keep each step's accel for :meth:`accel` (g: the kind's ``gravity`` setting, else 9.80665).
    **overrides
        Settings fields to change (unknown names raise TypeError).

    Raises
    ------
    TypeError
        No sample period, unknown settings fields.
    ValueError
        A bad ``dt``.
    SettingsError
        The C library refused the settings (a :class:`NativeError` and a ``ValueError``): the message
        names the first refused field, its value and its range.

    """

    def __init__(
        self,
        kind: str | int | FilterKind,
        dt: Any = None,
        settings: Any = None,
        calibration: Any = None,
        accel_outputs: bool = False,
        **overrides: Any,
    ) -> None:
        self.kind, self._settings = filter_settings(kind, dt, settings, overrides, "native.Filter")
        self._s = _c_settings(self.kind, self._settings)
        self._f = ffi.new("att_filter_t *")
        what = f"att_filter_init({self.kind.label})"
        _check_settings(self.kind, self._s, what)
        _check(lib.att_filter_init(self._f, int(self.kind), self._s), what)
        self._block: Outputs
        self._block_ptr: Any
        self._slot: int
        self._new_block()
        self._last = np.zeros((), OUTPUT_DTYPE).view(Outputs)
        self._last_plain = self._last.view(np.ndarray)
        self._last_ptr = ffi.from_buffer("att_output_t *", self._last)
        self._live = _stepper(self._f, self._last_ptr, (self._f, self._last))
        if calibration is not None or accel_outputs:
            self.calibrate(calibration, float(getattr(self.settings, "gravity", 9.80665)), accel_outputs)

    def calibrate(self, calibration: Any, gravity: float = 9.80665, accel_outputs: bool = False) -> None:
        """att_filter_calibrate: new input/output stages, the state kept (NativeError says why if refused)."""
        from attica.contract import calib_rules
        from attica.reference.calib import as_stage_settings

        cs = ffi.new("att_calib_settings_t *")
        stages = as_stage_settings(calibration, gravity, accel_outputs)
        fill_c(cs, stages)
        problem = lib.att_calib_settings_check(cs)
        if problem != lib.ATT_CALIB_OK:
            why = ffi.string(lib.att_calib_error_name(problem)).decode()
            line = next((r for r in calib_rules(stages) if not r.holds), None)
            where = f" ({line.name}: {line.text})" if line is not None else ""
            raise NativeError(f"att_filter_calibrate: {why}{where}")
        _check(lib.att_filter_calibrate(self._f, cs), "att_filter_calibrate")

    def accel(self) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]] | None:
        """att_filter_accel: (gravity, linear, earth), each (3,) m/s^2; None when not available."""
        a = ffi.new("att_accel_t *")
        lib.att_filter_accel(self._f, a)
        if a.valid != lib.ATT_OUT_ACCEL:
            return None
        vecs = (a.gravity, a.linear, a.earth)
        return tuple(np.array([v.x, v.y, v.z], np.float32) for v in vecs)  # type: ignore[return-value]

    def mag_offset(self) -> MagOffset:
        """att_filter_mag_offset (mars, mekf): the hard-iron offset estimated on the device.

        Returns the offset, (3,) uT, whether the estimate runs (``hard_iron_tau`` > 0) and whether it has
        become observable (the offset is 0 before).
        """
        h = ffi.new("att_mag_offset_t *")
        _check(lib.att_filter_mag_offset(self._f, h), "att_filter_mag_offset")
        o = h.offset
        return MagOffset(np.array([o.x, o.y, o.z], np.float32), bool(h.on), bool(h.estimated))

    @property
    def estimates_mag_offset(self) -> bool:
        """Whether this filter's hard-iron estimate runs: :meth:`mag_offset`'s ``on``.

        True for mars and a mekf with its magnetometer with ``hard_iron_tau`` > 0; False for other kinds.
        """
        h = ffi.new("att_mag_offset_t *")
        return lib.att_filter_mag_offset(self._f, h) == lib.ATT_OK and bool(h.on)

    def set_heading(self, heading: float) -> None:
        """att_filter_set_heading (rad, the output convention's yaw); a 6-axis heading is known from here.

        ars, the ekf and a mekf without the magnetometer then report the heading's variance (``cov[2]``)
        small and growing instead of pi^2/3, until a clipping gyro sample (docs/filters.md).
        """
        _check(lib.att_filter_set_heading(self._f, heading), "att_filter_set_heading")

    def heading_update(self, heading: float, gain: float, valid: bool = True) -> None:
        """att_filter_heading_update (ars, kf, ekf, gyro, mekf with ``use_mag`` off); gain 1 = set_heading."""
        _check(lib.att_filter_heading_update(self._f, heading, gain, valid), "att_filter_heading_update")

    @property
    def settings(self) -> Any:
        """The settings in use (a frozen dataclass: change them with :meth:`retune`)."""
        return self._settings

    def __repr__(self) -> str:
        return f"native.Filter({self.kind.label!r}, settings={self._settings!r})"

    def reset(self) -> None:
        """att_filter_reset."""
        lib.att_filter_reset(self._f)

    def output(self) -> Outputs:
        """att_filter_output: the current output record (shape ())."""
        out = np.zeros((), OUTPUT_DTYPE)
        lib.att_filter_output(self._f, ffi.from_buffer("att_output_t[]", out))
        return as_outputs(out)

    def step(self, gyr: Any, acc: Any, mag: Any = None, full: bool = True, n: int = 1) -> Outputs:
        """One step; 3-sequences gyr (rad/s), acc (m/s^2), mag (uT, None = absent). Returns a record.

        With ``full`` (default) the record is the whole att_filter_output after the step (Euler angles
        and covariance included); otherwise only what att_filter_step fills (see the ``valid`` field).
        ``n`` > 1: ``att_filter_step_n``, the sample held over n periods after n - 1 lost samples (its
        flags are the OR over them).

        The per-sample path for live loops: one C call with the nine values, the record a slot of a
        block allocated every 256 steps (each returned record is its own memory; a kept record keeps
        its block alive).
        """
        if n != 1 and (type(n) is not int or not 1 <= n <= 0xFFFFFFFF):
            self._step_args(gyr, acc, mag, n)
        try:
            gx, gy, gz = gyr.tolist() if type(gyr) is np.ndarray else gyr
            ax, ay, az = acc.tolist() if type(acc) is np.ndarray else acc
            if mag is None:
                mx = my = mz = 0.0
            else:
                mx, my, mz = mag.tolist() if type(mag) is np.ndarray else mag
            i = self._slot
            if i == _STEP_BLOCK:
                self._new_block()
                i = 0
            self._slot = i + 1
            lib.att_host_step9(
                self._f, gx, gy, gz, ax, ay, az, mx, my, mz, n, 1 if full else 0, self._block_ptr + i
            )
        except (TypeError, ValueError, OverflowError):
            self._step_args(gyr, acc, mag, n)
            raise
        return self._block[i, ...]  # type: ignore[no-any-return]

    def update(self, gyr: Any, acc: Any, mag: Any = None, n: int = 1) -> int:
        """One step, the lean per-sample path (as vqf's ``update``): returns the ATT_FLAG_* bits.

        The same step as :meth:`step` with ``full=False``; the record stays in the filter: :attr:`last`
        (overwritten by the next update), :attr:`quat` its attitude. For live loops in Python that
        read the attitude now and then; :meth:`step` returns a record of its own every call.
        """
        if self._live is not None:
            return self._live.update(gyr, acc, mag, n)  # type: ignore[no-any-return]
        if n != 1 and (type(n) is not int or not 1 <= n <= 0xFFFFFFFF):
            self._step_args(gyr, acc, mag, n)
        try:
            gx, gy, gz = gyr.tolist() if type(gyr) is np.ndarray else gyr
            ax, ay, az = acc.tolist() if type(acc) is np.ndarray else acc
            if mag is None:
                mx = my = mz = 0.0
            else:
                mx, my, mz = mag.tolist() if type(mag) is np.ndarray else mag
            return lib.att_host_step9(  # type: ignore[no-any-return]
                self._f, gx, gy, gz, ax, ay, az, mx, my, mz, n, 2, self._last_ptr
            )
        except (TypeError, ValueError, OverflowError):
            self._step_args(gyr, acc, mag, n)
            raise

    @property
    def last(self) -> Outputs:
        """The record of the last :meth:`update` (live: the next update overwrites it; copy to keep)."""
        return self._last

    @property
    def quat(self) -> NDArray[np.float32]:
        """The attitude after the last :meth:`update`: (4,) float32 w, x, y, z sensor-to-earth (a copy)."""
        return self._last_plain["q"].copy()

    def _new_block(self) -> None:
        self._block = np.zeros(_STEP_BLOCK, OUTPUT_DTYPE).view(Outputs)
        self._block_ptr = ffi.from_buffer("att_output_t[]", self._block)
        self._slot = 0

    def _step_args(self, gyr: Any, acc: Any, mag: Any, n: Any) -> None:
        """Raise the error that says what is wrong with step()'s arguments (if anything is)."""
        for name, v in (("gyr", gyr), ("acc", acc), ("mag", mag if mag is not None else (0.0, 0.0, 0.0))):
            a = _f32(v)
            if a.shape != (3,):
                raise ValueError(f"{name} must have 3 components, got shape {a.shape}")
        if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= 0xFFFFFFFF:
            raise ValueError(f"n must be a whole number of periods >= 1, got {n!r}")

    def retune(self, settings: Any = None, **changes: Any) -> None:
        """New settings, the state kept: ``att_filter_retune`` (the attitude, bias and rest memories go on).

        ``changes`` are settings fields (``f.retune(tau_acc_lp=2.0)``); the others keep their values
        (or those of ``settings``, a settings dataclass of the kind, when given).
        The same checks as at construction apply (setting only a time constant sets its per-sample gain
        to 0, unused). What a changed setting resets is the C library's rule (``att_<kind>_retune``).
        On an error nothing changes.

        Raises
        ------
        TypeError
            Unknown settings fields.
        ValueError
            A bad ``dt``.
        SettingsError
            The C library refused the new settings, naming the field (the filter is left as it was).

        """
        base = settings if settings is not None else self._settings
        _, new = filter_settings(self.kind, None, base, changes, "Filter.retune")
        s = _c_settings(self.kind, new)
        what = f"att_filter_retune({self.kind.label})"
        _check_settings(self.kind, s, what)
        _check(lib.att_filter_retune(self._f, s), what)
        self._s = s
        self._settings = new

    @property
    def state(self) -> CView:
        """The C state: a live :class:`~attica.cview.CView` of this filter's ``att_filter_t *``.

        Live, not a copy: it shows the state as it is now (later steps are seen) and writing through
        it changes the filter. It keeps the filter's C memory alive, and so does everything taken
        from it (``f.state.u.mekf.c``, ``f.state[0]``, ``f.state.ptr``), even after the Filter itself
        is gone: ``Filter("mekf", 0.01).state.u.mekf.c`` stays valid. For C calls pass
        ``f.state.ptr`` (the ``att_filter_t *``); ``f.state.copy()`` is a snapshot (new memory),
        ``bytes(f.state)`` its bytes, and ``f.state[0] = saved[0]`` restores one.
        """
        return CView(self._f, self._f, ffi)

    def run(
        self,
        gyr: Any,
        acc: Any,
        mag: Any = None,
        snapshot_every: int = 0,
        full: bool = True,
        check_units: bool = True,
        steps: Any = None,
        *,
        mag_offset: NDArray[np.void] | None = None,
    ) -> Any:
        """N steps in C over (N, 3) arrays without copying float32 C-contiguous input; (N,) records.

        For throughput when only the attitude is needed, :meth:`run_q` returns the same quaternions
        (and flags) without the output records.

        Parameters
        ----------
        gyr, acc, mag
            (N, 3): rad/s, m/s^2, uT (``mag`` None, or NaN / zero rows: no mag sample).
        snapshot_every
            > 0: return ``(records, snapshots)``: snapshots is a :class:`~attica.cview.CView` of a
            new ``att_filter_t[]`` (copies, not live: ``snapshots[j]`` is the state just before step
            ``j * k``), whose elements and members keep that array's memory alive.
        full
            True (default): every record is the whole att_filter_output after its step (Euler angles,
            covariance); False keeps only what att_filter_step fills (q, gyro_bias, flags, steps; see
            the ``valid`` field), which is what a firmware loop pays for.
        check_units
            Warn (:class:`attica.UnitWarning`) when the median magnitudes look like deg/s, g, gauss or
            nT; False skips the check.
        steps
            (N,) integers >= 1: the sample periods each row advances (``att_filter_step_n``: n after n - 1
            lost samples, e.g. :attr:`attica.data.Recording.steps`); that row's flags are the OR over
            them. None: 1 each.
        mag_offset
            An (N,) array of :data:`attica.outputs.MAG_OFFSET_DTYPE` (mars, mekf): filled with the
            hard-iron estimate after each step (:meth:`mag_offset`), for the outputs of ``attica run``.

        Raises
        ------
        ValueError
            Inputs not all of shape (N, 3) with the same N; steps of another length or below 1; a
            ``mag_offset`` array of another shape or dtype, or not writeable C-contiguous memory.
        TypeError
            Inputs that are not real numbers (bool, complex, object, text).
        NativeError
            ``mag_offset`` for a kind without a hard-iron estimate (ATT_ERR_KIND).

        """
        who = f"{self.kind.label} Filter.run"
        g, a, m = imu_arrays(gyr, acc, mag, who)
        if check_units:
            warn_units(g, a, m, who)
        st = step_counts(steps, g.shape[0], who)
        moff = ffi.NULL
        if mag_offset is not None:
            _check_mag_offset_array(mag_offset, g.shape[0], who)
            self.mag_offset()  # NativeError for a kind without the estimate, before any step
            moff = ffi.from_buffer("att_mag_offset_t[]", mag_offset)
        out = np.zeros(g.shape[0], OUTPUT_DTYPE)
        every = max(int(snapshot_every), 0)
        snaps = ffi.new("att_filter_t[]", -(-g.shape[0] // every)) if every else ffi.NULL
        lib.att_host_filter_run(
            self._f,
            _fptr(g),
            _fptr(a),
            _fptr(m) if m is not None else ffi.NULL,
            ffi.from_buffer("uint32_t[]", st) if st is not None else ffi.NULL,
            g.shape[0],
            ffi.from_buffer("att_output_t[]", out),
            1 if full else 0,
            every,
            snaps,
            moff,
        )
        if every:
            return as_outputs(out), CView(snaps, snaps, ffi)
        return as_outputs(out)

    @overload
    def run_q(
        self,
        gyr: Any,
        acc: Any,
        mag: Any = ...,
        *,
        flags: Literal[False] = ...,
        out: NDArray[np.float32] | None = ...,
        check_units: bool = ...,
        steps: Any = ...,
    ) -> NDArray[np.float32]: ...

    @overload
    def run_q(
        self,
        gyr: Any,
        acc: Any,
        mag: Any = ...,
        *,
        flags: Literal[True],
        out: NDArray[np.float32] | None = ...,
        check_units: bool = ...,
        steps: Any = ...,
    ) -> tuple[NDArray[np.float32], NDArray[np.uint32]]: ...

    def run_q(
        self,
        gyr: Any,
        acc: Any,
        mag: Any = None,
        *,
        flags: bool = False,
        out: NDArray[np.float32] | None = None,
        check_units: bool = True,
        steps: Any = None,
    ) -> NDArray[np.float32] | tuple[NDArray[np.float32], NDArray[np.uint32]]:
        """N steps in C returning only the attitude: the lean batch path, for throughput.

        The same steps as :meth:`run` (and the same state afterwards), but the C loop
        (``att_host_filter_run_q``) writes 16 bytes of quaternion (and 4 of flags) per step instead
        of a 68-byte output record, and computes no Euler angles or covariance. The quaternions are
        bit for bit the ``q`` of ``run(...)["q"]`` (also for the EKF, whose q is derived from its
        Euler-angle state exactly as att_filter_output does, and with a calibration's output
        convention applied). Input that is float32 and C-contiguous is read in place.

        Parameters
        ----------
        gyr, acc, mag
            (N, 3): rad/s, m/s^2, uT (``mag`` None, or NaN / zero rows: no mag sample).
        flags
            Also return the ATT_FLAG_* bits of every step, (N,) uint32 (what ``run(...)["flags"]``
            holds): NaN, saturated or rejected samples are reported there, the attitude kept.
        out
            Optional (N, 4) float32 C-contiguous writable array to write the quaternions into (and
            return), e.g. to reuse one buffer over chunks of a long stream; must not overlap the inputs.
        check_units
            Warn (:class:`attica.UnitWarning`) when the inputs look like deg/s, g, gauss or nT.
        steps
            (N,) integers >= 1, the sample periods each row advances (as for :meth:`run`); None: 1 each.

        Returns
        -------
        numpy.ndarray or tuple
            q (N, 4) float32 (w, x, y, z, sensor-to-earth), or ``(q, flags)`` with ``flags=True``.

        Raises
        ------
        ValueError
            Inputs not all of shape (N, 3) with the same N; ``out`` of the wrong shape, not
            C-contiguous, read-only or overlapping an input.
        TypeError
            Inputs that are not real numbers; ``out`` not a float32 numpy array.

        Examples
        --------
        >>> f = attica.Filter("ars", 0.01)                            # doctest: +SKIP
        >>> q, fl = f.run_q(rec.gyr, rec.acc, flags=True)             # doctest: +SKIP

        """
        who = f"{self.kind.label} Filter.run_q"
        g, a, m = imu_arrays(gyr, acc, mag, who)
        n = g.shape[0]
        q = _q_buffer(out, n, (g, a, m), who)
        st = step_counts(steps, n, who)
        if check_units:
            warn_units(g, a, m, who)
        fl = np.empty(n, np.uint32) if flags else None
        lib.att_host_filter_run_q(
            self._f,
            _fptr(g),
            _fptr(a),
            _fptr(m) if m is not None else ffi.NULL,
            ffi.from_buffer("uint32_t[]", st) if st is not None else ffi.NULL,
            n,
            _fptr(q),
            ffi.from_buffer("uint32_t[]", fl) if fl is not None else ffi.NULL,
        )
        if fl is not None:
            return q, fl
        return q


def step_counts(steps: Any, n: int, who: str) -> NDArray[np.uint32] | None:
    """``steps`` as a C-contiguous (n,) uint32 array of periods per row (None stays None).

    Raises
    ------
    ValueError
        Another length, a value below 1 or above ``ATT_FILTER_STEP_N_MAX``, or not integers.

    """
    if steps is None:
        return None
    arr = np.asarray(steps)
    if arr.shape != (n,):
        raise ValueError(f"{who}: steps must have shape ({n},), got {arr.shape}")
    if arr.dtype.kind not in "iu":
        if arr.dtype.kind != "f" or not np.all(np.isfinite(arr)) or np.any(arr != np.rint(arr)):
            raise ValueError(f"{who}: steps must be whole numbers of sample periods")
    if n and (arr.min() < 1 or arr.max() > lib.ATT_FILTER_STEP_N_MAX):
        raise ValueError(
            f"{who}: steps must be in 1..{lib.ATT_FILTER_STEP_N_MAX}, got {arr.min()}..{arr.max()}"
        )
    return np.ascontiguousarray(arr, dtype=np.uint32)


def _q_buffer(out: Any, n: int, inputs: tuple[Any, ...], who: str) -> NDArray[np.float32]:
    """The (n, 4) float32 array run_q writes: ``out`` when given and usable, else a new one."""
    if out is None:
        return np.empty((n, 4), np.float32)
    if not isinstance(out, np.ndarray) or out.dtype != np.float32:
        what = f"dtype {out.dtype}" if isinstance(out, np.ndarray) else type(out).__name__
        raise TypeError(f"{who}: out must be a float32 numpy array, got {what}")
    if out.shape != (n, 4):
        raise ValueError(f"{who}: out must have shape ({n}, 4), got {out.shape}")
    if not out.flags.c_contiguous or not out.flags.writeable:
        raise ValueError(f"{who}: out must be C-contiguous and writable")
    if any(x is not None and np.may_share_memory(out, x) for x in inputs):
        raise ValueError(f"{who}: out overlaps an input array")
    return out

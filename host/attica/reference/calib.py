"""Mirror of firmware/src/calib/att_calib.c and of the stage, acceleration and heading parts of att_filter.c.

:class:`Stages` is ``att_calib_t``: the settings folded into one stage per sensor when applied
(identity, a signed axis permutation, or ``v = A (raw - o)``), the convention and the acceleration
outputs. :func:`set_heading` / :func:`heading_update` mirror att_filter_set_heading /
att_filter_heading_update on a reference filter. Every operation in float32, in the C order.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from attica import kinds
from attica.calibration.model import Calibration
from attica.calibration.stages import REMAP_NAMES, StageSettings, from_calibration
from attica.reference import detmath as dm

HALF_SQRT2 = dm.c("0x1.6a09e6p-1")
PIO2 = dm.c("0x1.921fb6p+0")
ENTRY_MAX = np.float32(1000.0)
GYRO_OFFSET_MAX = np.float32(1000.0)
ACCEL_OFFSET_MAX = np.float32(10000.0)
MAG_OFFSET_MAX = np.float32(100000.0)
COND_MAX = np.float32(3100.0)
DET_MIN = dm.c("0x1p-60")
Q2_LO = np.float32(0.997)
Q2_HI = np.float32(1.003)
GRAVITY_MIN = np.float32(1.0)
GRAVITY_MAX = np.float32(100.0)
HEADING_MAX = np.float32(8192.0)

ENU, NED, NWU = 0, 1, 2
ACTIVE_INPUT, ACTIVE_CONV, ACTIVE_ACC = 0x1, 0x2, 0x4

ERRORS = (
    "ok",
    "null",
    "gyro_matrix",
    "gyro_sensitivity",
    "gyro_offset",
    "accel_matrix",
    "accel_sensitivity",
    "accel_offset",
    "mag_matrix",
    "mag_offset",
    "remap",
    "mounting",
    "convention",
    "gravity",
    "flag",
)
"""``att_calib_error_t`` by value (ATT_CALIB_OK, ATT_CALIB_ERR_NULL, ...), lower case."""

_EYE = tuple(np.float32(v) for v in (1, 0, 0, 0, 1, 0, 0, 0, 1))


def _f(values: Any) -> list[np.float32]:
    return [np.float32(v) for v in values]


def _in(v: np.float32, lo: np.float32, hi: np.float32) -> bool:
    return bool(v >= lo and v <= hi)


def matrix_ok(m: Any) -> bool:
    """att_calib_matrix_ok: finite entries within 1e3, |det| >= 2^-60, Frobenius condition <= 3100."""
    m = _f(m)
    if not all(_in(v, -ENTRY_MAX, ENTRY_MAX) for v in m):
        return False
    with np.errstate(all="ignore"):
        c = [
            m[4] * m[8] - m[5] * m[7],
            m[2] * m[7] - m[1] * m[8],
            m[1] * m[5] - m[2] * m[4],
            m[5] * m[6] - m[3] * m[8],
            m[0] * m[8] - m[2] * m[6],
            m[2] * m[3] - m[0] * m[5],
            m[3] * m[7] - m[4] * m[6],
            m[1] * m[6] - m[0] * m[7],
            m[0] * m[4] - m[1] * m[3],
        ]
        det = (m[0] * c[0] + m[1] * c[3]) + m[2] * c[6]
        if not bool(np.abs(det) >= DET_MIN):
            return False
        n2 = np.float32(0.0)
        a2 = np.float32(0.0)
        for i in range(9):
            n2 = n2 + m[i] * m[i]
            a2 = a2 + c[i] * c[i]
        return bool((n2 * a2) <= (COND_MAX * COND_MAX) * (det * det))


def _scale_ok(s: Any) -> bool:
    return all(bool(v > 0 and v <= ENTRY_MAX) for v in _f(s))


def _within(v: Any, lim: np.float32) -> bool:
    return all(_in(x, -lim, lim) for x in _f(v))


def check(s: StageSettings) -> str:
    """att_calib_settings_check: the first problem (an :data:`ERRORS` name), ``"ok"`` when valid."""
    tests = (
        ("gyro_matrix", matrix_ok(s.gyro_misalignment)),
        ("gyro_sensitivity", _scale_ok(s.gyro_sensitivity)),
        ("gyro_offset", _within(s.gyro_offset, GYRO_OFFSET_MAX)),
        ("accel_matrix", matrix_ok(s.accel_misalignment)),
        ("accel_sensitivity", _scale_ok(s.accel_sensitivity)),
        ("accel_offset", _within(s.accel_offset, ACCEL_OFFSET_MAX)),
        ("mag_matrix", matrix_ok(s.soft_iron)),
        ("mag_offset", _within(s.hard_iron, MAG_OFFSET_MAX)),
        ("remap", 0 <= s.remap <= len(REMAP_NAMES)),
    )
    for name, ok in tests:
        if not ok:
            return name
    if s.remap == 0:
        q = _f(s.mounting)
        with np.errstate(all="ignore"):
            q2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]
        if not (all(np.isfinite(q)) and _in(q2, Q2_LO, Q2_HI)):
            return "mounting"
    if s.convention not in (ENU, NED, NWU):
        return "convention"
    if not _in(np.float32(s.gravity), GRAVITY_MIN, GRAVITY_MAX):
        return "gravity"
    return "ok"


def remap_axes(r: int) -> tuple[list[int], list[bool]]:
    """Remap r (1 .. 24): body axis k = (-1 if neg[k]) * sensor axis axis[k]."""
    name = REMAP_NAMES[r - 1]
    return [ord(name[2 * k + 1]) - ord("x") for k in range(3)], [name[2 * k] == "-" for k in range(3)]


def _floats(v: Any) -> list[float]:
    """A sequence of values as float32, compared by value (-0 == 0)."""
    return [float(x) for x in np.asarray(v, np.float32)]


@dataclass
class Stage:
    """``att_calib_stage_t``: mode 0 identity, 1 signed permutation, 2 affine ``a (raw - o)``."""

    mode: int
    a: list[np.float32]
    o: list[np.float32]
    axis: list[int]
    neg: list[bool]

    def same(self, other: Stage) -> bool:
        """The same stage (att_filter_stage_same: every field, the floats by value; they are finite)."""
        return (
            self.mode == other.mode
            and _floats(self.a) == _floats(other.a)
            and _floats(self.o) == _floats(other.o)
            and list(self.axis) == list(other.axis)
            and list(self.neg) == list(other.neg)
        )

    def apply(self, v: dm.Vec3) -> dm.Vec3:
        """att_calib_stage on a Vec3 of (n,) float32 arrays."""
        if self.mode == 1:
            r = [dm.f32(c) for c in v]
            out = [-r[self.axis[k]] if self.neg[k] else r[self.axis[k]] for k in range(3)]
            return (out[0], out[1], out[2])
        if self.mode == 2:
            a = self.a
            with np.errstate(all="ignore"):
                dx = dm.f32(v[0]) - self.o[0]
                dy = dm.f32(v[1]) - self.o[1]
                dz = dm.f32(v[2]) - self.o[2]
                return (
                    (a[0] * dx + a[1] * dy) + a[2] * dz,
                    (a[3] * dx + a[4] * dy) + a[5] * dz,
                    (a[6] * dx + a[7] * dy) + a[8] * dz,
                )
        return v


def fold(m: Any, s: Any, o: Any, remap: int, rm: list[Any], mount_identity: bool) -> Stage:
    """att_calib_fold: one sensor's model M diag(s), offset o and the mounting as a :class:`Stage`."""
    m, sv, ov = _f(m), _f(s), _f(o)
    x = [m[3 * i + j] * sv[j] for i in range(3) for j in range(3)]
    model_identity = tuple(m) == _EYE and all(v == 1 for v in sv) and all(v == 0 for v in ov)
    axis, neg = ([0, 1, 2], [False, False, False]) if remap == 0 else remap_axes(remap)
    if model_identity and mount_identity:
        return Stage(0, list(_EYE), ov, axis, neg)
    if model_identity and remap > 0:
        a = [np.float32(0.0)] * 9
        for i in range(3):
            a[3 * i + axis[i]] = np.float32(-1.0 if neg[i] else 1.0)
        return Stage(1, a, ov, axis, neg)
    a = []
    for i in range(3):
        for j in range(3):
            if remap > 0:
                v = x[3 * axis[i] + j]
                a.append(-v if neg[i] else v)
            elif mount_identity:
                a.append(x[3 * i + j])
            else:
                a.append((rm[3 * i] * x[j] + rm[3 * i + 1] * x[3 + j]) + rm[3 * i + 2] * x[6 + j])
    return Stage(2, a, ov, axis, neg)


def quat_to(q: dm.Quat, conv: int) -> dm.Quat:
    """att_calib_quat_to: q (sensor-to-ENU) in the earth frame of convention conv."""
    w, x, y, z = (dm.f32(c) for c in q)
    a = HALF_SQRT2
    if conv == NED:
        return ((-x - y) * a, (w + z) * a, (w - z) * a, (y - x) * a)
    if conv == NWU:
        return ((w + z) * a, (x + y) * a, (y - x) * a, (z - w) * a)
    return (w, x, y, z)


def vec_to(v: dm.Vec3, conv: int) -> dm.Vec3:
    """att_calib_vec_to: an ENU earth-frame vector in the frame of convention conv (exact)."""
    x, y, z = (dm.f32(c) for c in v)
    if conv == NED:
        return (y, x, -z)
    if conv == NWU:
        return (y, -x, z)
    return (x, y, z)


class Stages:
    """``att_calib_t`` (att_calib_init): raises ValueError naming the first problem of the settings."""

    def __init__(self, s: StageSettings) -> None:
        problem = check(s)
        if problem != "ok":
            raise ValueError(f"calibration refused: {problem}")
        self.settings = s
        if s.remap == 0:
            _, q = dm.quat_normalize(tuple(dm.f32(v) for v in s.mounting))
            rm = dm.quat_to_matrix(q)
            mount_identity = all(bool(dm.f32(a) == b) for a, b in zip(rm, _EYE, strict=True))
        else:
            rm = dm.quat_to_matrix(dm.quat_identity())
            mount_identity = s.remap == 1
        ones = (1.0, 1.0, 1.0)
        r, mi = s.remap, mount_identity
        self.gyr = fold(s.gyro_misalignment, s.gyro_sensitivity, s.gyro_offset, r, rm, mi)
        self.acc = fold(s.accel_misalignment, s.accel_sensitivity, s.accel_offset, r, rm, mi)
        self.mag = fold(s.soft_iron, ones, s.hard_iron, r, rm, mi)
        self.convention = s.convention
        self.gravity = np.float32(s.gravity)
        self.active = 0
        if self.gyr.mode or self.acc.mode or self.mag.mode:
            self.active |= ACTIVE_INPUT
        if s.convention != ENU:
            self.active |= ACTIVE_CONV
        if s.accel_outputs:
            self.active |= ACTIVE_ACC
        self.acc_body: dm.Vec3 | None = None

    def apply(self, gyr: dm.Vec3, acc: dm.Vec3, mag: dm.Vec3) -> tuple[dm.Vec3, dm.Vec3, dm.Vec3]:
        """att_calib_apply on Vec3s of (n,) arrays: the calibrated body-frame gyr, acc, mag."""
        g = self.gyr.apply(gyr)
        a = self.acc.apply(acc)
        m = mag
        if self.mag.mode != 0:
            mx, my, mz = (dm.f32(c) for c in mag)
            present = ~((mx == 0) & (my == 0) & (mz == 0))  # the zero vector; NaN propagates
            m = dm.vec3_where(present, self.mag.apply((mx, my, mz)), (mx, my, mz))
        return g, a, m

    def accel(self, q: dm.Quat) -> tuple[dm.Vec3, dm.Vec3, dm.Vec3]:
        """att_filter_accel for the ENU attitudes q: (gravity, linear, earth), m/s^2."""
        if self.acc_body is None:
            raise ValueError("no acceleration outputs: accel_outputs is off or no step was taken")
        g = self.gravity
        a = self.acc_body
        m = dm.quat_to_matrix(q)
        grav = (m[6] * g, m[7] * g, m[8] * g)
        lin = dm.vec3_sub(a, grav)
        e = (
            (m[0] * a[0] + m[1] * a[1]) + m[2] * a[2],
            (m[3] * a[0] + m[4] * a[1]) + m[5] * a[2],
            ((m[6] * a[0] + m[7] * a[1]) + m[8] * a[2]) - g,
        )
        return grav, lin, vec_to(e, self.convention)


def heading_enu(heading: Any, conv: int) -> Any:
    """att_filter_heading_enu: the ENU yaw a heading of convention conv means (rad)."""
    h = dm.f32(heading)
    if conv == NED:
        return dm.wrap_pi(PIO2 - h)
    if conv == NWU:
        return dm.wrap_pi(h + PIO2)
    return dm.wrap_pi(h)


def _turn(v: dm.Vec3, c: Any, s: Any) -> dm.Vec3:
    return (c * v[0] - s * v[1], s * v[0] + c * v[1], v[2])


def yaw_to(kind: str, impl: Any, target: Any, gain: Any) -> None:
    """att_filter_yaw_to on every instance of a reference filter (kind its label).

    The kind's earth-frame memories (its class's ``EARTH`` vectors) turn with the attitude.
    """
    k = kinds.info(kind)
    if k.heading(impl.settings) == kinds.Heading.NONE:
        raise ValueError(f"{kind}: no heading")
    if hasattr(impl, "initialised") and not bool(np.all(impl.initialised)):  # gyro: ready from the start
        raise RuntimeError("the filter is not initialised yet (no valid sample)")
    gain = np.float32(gain)
    with np.errstate(all="ignore"):
        if k.euler_state:
            q = dm.quat_from_euler(*impl.euler)
            yaw = dm.f32(impl.euler[2])
        else:
            q = tuple(dm.f32(c) for c in impl.q)
            w, x, y, z = q
            yaw = dm.atan2f(dm.TWO * (w * z + x * y), dm.ONE - dm.TWO * (y * y + z * z))
        delta = dm.wrap_pi(target - yaw) * gain
        if not bool(np.all(dm.isfinitef(delta))):
            raise RuntimeError("yaw outside the wrap domain")
        s, c = dm.sinf(delta), dm.cosf(delta)
        for name in impl.EARTH:
            setattr(impl, name, _turn(getattr(impl, name), c, s))
        if k.euler_state:
            psi = np.broadcast_to(dm.f32(target), yaw.shape).copy() if gain == 1 else dm.wrap_pi(yaw + delta)
            impl.euler = (dm.f32(impl.euler[0]), dm.f32(impl.euler[1]), dm.f32(psi))
            if k.q_state:  # kept beside the angles (gyro)
                impl.q = dm.quat_from_euler(*impl.euler)
        else:
            hs, hc = dm.sinf(delta * dm.HALF), dm.cosf(delta * dm.HALF)
            _, qn = dm.quat_normalize_bounded(dm.quat_mul_z(hc, hs, q))
            impl.q = tuple(dm.f32(v) for v in qn)
    if gain == 1 and hasattr(impl, "heading_set"):  # the covariance's heading (ars, ekf, mekf)
        impl.heading_set()


def _heading_ok(h: Any) -> bool:
    return _in(np.float32(h), -HEADING_MAX, HEADING_MAX)


def set_heading(kind: str, impl: Any, conv: int, heading: float) -> None:
    """att_filter_set_heading; ValueError for a kind without heading (tilt) or a bad heading."""
    if kinds.heading(kind, impl.settings) == kinds.Heading.NONE or not _heading_ok(heading):
        raise ValueError(f"{kind}: set_heading({heading}) refused")
    yaw_to(kind, impl, heading_enu(np.float32(heading), conv), np.float32(1.0))


def heading_update(kind: str, impl: Any, conv: int, heading: float, gain: float, valid: bool = True) -> None:
    """att_filter_heading_update (kinds without a heading reference of their own).

    ValueError for a kind whose :func:`attica.kinds.heading` is not ``UPDATE`` (mars, 9-axis mekf, tilt)
    or a bad heading or gain.
    """
    if kinds.heading(kind, impl.settings) != kinds.Heading.UPDATE:
        raise ValueError(f"{kind}: no external heading update (6-axis filters only)")
    if not _heading_ok(heading) or not _in(np.float32(gain), np.float32(0.0), np.float32(1.0)):
        raise ValueError(f"heading_update({heading}, {gain}) refused")
    if valid:
        yaw_to(kind, impl, heading_enu(np.float32(heading), conv), np.float32(gain))


def as_stage_settings(
    calibration: Any, gravity: float = 9.80665, accel_outputs: bool = False
) -> StageSettings:
    """StageSettings from a Calibration (with gravity, accel_outputs), StageSettings or None."""
    if isinstance(calibration, StageSettings):
        return calibration
    if calibration is None or isinstance(calibration, Calibration):
        return from_calibration(calibration, gravity, accel_outputs)
    raise TypeError(f"calibration: expected a Calibration or StageSettings, got {type(calibration).__name__}")

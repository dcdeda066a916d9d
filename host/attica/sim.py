"""Deterministic IMU simulator with ground truth.

Conventions (those of the whole project): quaternions ``(w, x, y, z)`` sensor-to-earth,
``v_earth = q * v_sensor * conj(q)``, earth frame ENU (x east, y north, z up); body-rate kinematics
``q_dot = 0.5 * q * (0, w_sensor)``.

Sensor models (sample ``k`` at ``t_k = k / rate``, ``R_k`` the rotation matrix of ``quat_true[k]``):

- gyroscope ``gyr = w(t_k) + bias_k + noise``, the *instantaneous* true body rate in rad/s; the bias
  starts uniform in ``[-gyro_bias, gyro_bias]`` per axis and random-walks with ``gyro_bias_drift``
  rad/s/sqrt(s);
- accelerometer (specific force, m/s^2) ``acc = R_k^T (a_lin(t_k) + [0, 0, g]) + noise``, i.e. +g on the
  up axis at rest;
- magnetometer (uT) ``mag = R_k^T (m_earth + disturbance(t_k)) + noise`` with
  ``m_earth = B * (0, cos(dip), -sin(dip))`` (northern hemisphere, dip positive = pointing down) and the
  disturbances of :attr:`SimConfig.mag_disturbances` added in the earth frame on ``t_start <= t < t_end``.

Motion: the recording starts with ``rest_start`` s and ends with ``rest_end`` s of stillness;
``rest_breaks`` still pauses of ``break_duration`` s are spread (with seeded jitter) over the motion in
between. Each motion segment is shaped by a smooth envelope (quintic "smootherstep" ramps of ``ramp`` s,
zero with its first two derivatives at the segment ends). The body rate is the envelope times a sum of
``components`` random sinusoids per axis with frequencies in ``[0.1, 1] * rotation_bandwidth`` and an RMS
of ``rotation_rms`` (before the envelope). The linear acceleration (earth frame) is the time derivative
of a velocity built the same way (``v = envelope * sum of sinusoids``, frequencies in
``[0.2, 1] * translation_bandwidth``, acceleration RMS ``translation_rms``), so velocity is bounded and zero
whenever the sensor is still. Taps are bipolar pulses ``A sin(2 pi tau / T)`` of amplitude
``tap_amplitude`` and duration ``tap_duration`` (zero net velocity change) in a random earth-frame
direction, placed inside the motion segments.

Ground truth integrates the analytic body rate with a 4th-order Magnus (two-point Gauss) exponential map
in float64, ``substeps`` steps per sample; the per-sample increments are composed with a vectorised
prefix product, so long recordings are fast. Gyro-only integration of the noise- and bias-free rate
(:attr:`SimTruth.gyr`) therefore tracks ``quat_true`` to the accuracy of the integrator used.

Determinism: every random quantity comes from ``numpy.random.default_rng`` seeded with children of
``SeedSequence(seed)``, one independent stream per part (attitude, schedule, rotation, translation,
taps, gyro, accelerometer, magnetometer). The same config gives identical arrays; changing, say, the
number of taps does not change the rotation.

The simulator is *not* part of the bit-exact contract; only its float32 outputs are fed to the firmware.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray

from attica.data import Recording
from attica.metrics import quat_mul

__all__ = [
    "SimConfig",
    "SimTruth",
    "mag_field_earth",
    "quat_exp",
    "quat_rotate",
    "quat_rotate_inv",
    "sim_to_npz",
    "simulate",
    "simulate_with_truth",
]

F64 = NDArray[np.float64]

_TABLE = 1 << 15  # evaluation points per chunk
_MAX_SUBSTEP = 1e-3  # s, automatic substep length bound
_SQRT3 = math.sqrt(3.0)
_GAUSS = (0.5 - _SQRT3 / 6.0, 0.5 + _SQRT3 / 6.0)

_STREAMS = ("attitude", "schedule", "rotation", "translation", "taps", "gyro", "accel", "mag")


@dataclass
class SimConfig:
    """Simulation parameters; every random quantity derives from ``seed``.

    Attributes
    ----------
    duration : float
        Length in s; the recording has ``round(duration * rate)`` samples.
    rate : float
        Sampling rate in Hz.
    seed : int
        Seed of all random draws.
    gravity : float
        Gravity magnitude in m/s^2.
    rest_start, rest_end : float
        Still time at the start and end in s.
    rest_breaks : int
        Number of still pauses inside the motion.
    rotation_rms : float
        RMS per axis (before the envelope) of the random angular velocity in rad/s.
    rotation_bandwidth : float
        Highest frequency of the angular velocity in Hz.
    translation_rms : float
        RMS per axis (before the envelope) of the earth-frame linear acceleration in m/s^2.
    taps : int
        Number of acceleration taps.
    gyro_noise : float
        White gyro noise std per sample in rad/s.
    gyro_bias : float
        Initial gyro bias drawn per axis uniform in ``[-gyro_bias, gyro_bias]`` rad/s.
    gyro_bias_drift : float
        Random-walk intensity of the bias in rad/s/sqrt(s).
    accel_noise : float
        White accelerometer noise std per sample in m/s^2.
    mag_field : float
        Magnitude of the earth magnetic field in uT.
    mag_dip : float
        Inclination of the field below the horizon in rad.
    mag_noise : float
        White magnetometer noise std per sample in uT.
    mag_disturbances : tuple of (t_start, t_end, (x, y, z))
        Extra earth-frame fields in uT, present for ``t_start <= t < t_end``.
    initial_attitude : tuple of 4 floats or None
        Initial ``w, x, y, z`` (normalised); None draws a uniformly random attitude from the seed.
    translation_bandwidth : float
        Highest frequency of the linear motion in Hz.
    break_duration : float
        Length of each still pause in s.
    ramp : float
        Length of the smooth ramp at each end of a motion segment in s (at most half the segment).
    tap_amplitude : float
        Peak acceleration of a tap in m/s^2.
    tap_duration : float
        Length of a tap in s.
    components : int
        Number of sinusoids per axis in the random rotation and translation.
    substeps : int
        Integrator steps per sample; 0 picks ``max(2, ceil(1 ms * rate))``.
    name : str
        Recording name; empty gives ``sim-seed<seed>``.

    """

    duration: float = 60.0
    rate: float = 285.714
    seed: int = 0
    gravity: float = 9.80665
    rest_start: float = 3.0
    rest_end: float = 2.0
    rest_breaks: int = 2
    rotation_rms: float = 0.8
    rotation_bandwidth: float = 0.5
    translation_rms: float = 0.5
    taps: int = 0
    gyro_noise: float = 0.005
    gyro_bias: float = 0.02
    gyro_bias_drift: float = 0.0005
    accel_noise: float = 0.05
    mag_field: float = 49.0
    mag_dip: float = 1.1
    mag_noise: float = 0.3
    mag_disturbances: tuple[tuple[float, float, tuple[float, float, float]], ...] = ()
    initial_attitude: tuple[float, float, float, float] | None = None
    translation_bandwidth: float = 1.0
    break_duration: float = 2.0
    ramp: float = 1.0
    tap_amplitude: float = 30.0
    tap_duration: float = 0.01
    components: int = 8
    substeps: int = 0
    name: str = ""

    def validate(self) -> None:
        """Raise ValueError naming the first invalid field."""
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, float | int) and not isinstance(v, bool) and not math.isfinite(v):
                raise ValueError(f"SimConfig.{f.name} must be finite, got {v}")
        positive = ("duration", "rate", "rotation_bandwidth", "translation_bandwidth", "tap_duration")
        for name in positive:
            if getattr(self, name) <= 0:
                raise ValueError(f"SimConfig.{name} must be > 0, got {getattr(self, name)}")
        nonneg = (
            "rest_start", "rest_end", "rest_breaks", "rotation_rms", "translation_rms", "taps",
            "gyro_noise", "gyro_bias", "gyro_bias_drift", "accel_noise", "mag_field", "mag_noise",
            "break_duration", "ramp", "substeps",
        )  # fmt: skip
        for name in nonneg:
            if getattr(self, name) < 0:
                raise ValueError(f"SimConfig.{name} must be >= 0, got {getattr(self, name)}")
        if self.components < 1:
            raise ValueError(f"SimConfig.components must be >= 1, got {self.components}")
        for i, dist in enumerate(self.mag_disturbances):
            if len(dist) != 3 or len(dist[2]) != 3:
                raise ValueError(f"SimConfig.mag_disturbances[{i}] must be (t_start, t_end, (x, y, z))")
            if not np.all(np.isfinite(np.array([dist[0], dist[1], *dist[2]], dtype=np.float64))):
                raise ValueError(f"SimConfig.mag_disturbances[{i}] must be finite")
        if self.initial_attitude is not None:
            q = np.asarray(self.initial_attitude, dtype=np.float64)
            if q.shape != (4,) or not np.all(np.isfinite(q)) or not np.linalg.norm(q) > 0:
                raise ValueError(f"SimConfig.initial_attitude must be 4 finite numbers, not all 0; got {q}")

    @property
    def n(self) -> int:
        """Number of samples, ``round(duration * rate)``."""
        return int(round(self.duration * self.rate))


@dataclass
class SimTruth:
    """Noise-free quantities behind a simulated :class:`~attica.data.Recording` (all float64).

    Attributes
    ----------
    gyr : ndarray, shape (N, 3)
        True body rate in rad/s, sensor frame (what a perfect gyro reads).
    gyr_bias : ndarray, shape (N, 3)
        Gyro bias in rad/s added to each sample.
    acc_lin : ndarray, shape (N, 3)
        Linear acceleration in m/s^2, earth frame (taps included).
    mag_earth : ndarray, shape (N, 3)
        Magnetic field in uT, earth frame (disturbances included).
    envelope : ndarray, shape (N,)
        Motion envelope in [0, 1]; 0 during the still periods.
    segments : tuple of (start, end)
        Motion segments in s.
    tap_times : ndarray, shape (T,)
        Start time of each tap in s.
    tap_dirs : ndarray, shape (T, 3)
        Earth-frame unit direction of each tap.
    substeps : int
        Integrator steps per sample used for ``quat_true``.

    """

    gyr: F64
    gyr_bias: F64
    acc_lin: F64
    mag_earth: F64
    envelope: F64
    segments: tuple[tuple[float, float], ...]
    tap_times: F64
    tap_dirs: F64
    substeps: int


# --- quaternion helpers (float64) ---------------------------------------------------------------------


def quat_exp(rotvec: ArrayLike) -> F64:
    """Exponential map: rotation vector ``theta`` to ``(cos(|theta|/2), sin(|theta|/2) theta/|theta|)``.

    Parameters
    ----------
    rotvec : array_like, shape (..., 3)
        Rotation vectors in rad.

    Returns
    -------
    ndarray, float64, shape (..., 4)
        Quaternions ``w, x, y, z``.

    """
    v = np.asarray(rotvec, dtype=np.float64)
    angle = np.sqrt(np.sum(v * v, axis=-1))
    half = 0.5 * angle
    # sin(half) / angle without 0/0: 0.5 * sinc(half / pi) (numpy's sinc is sin(pi x) / (pi x))
    k = 0.5 * np.sinc(half / np.pi)
    return np.concatenate([np.cos(half)[..., None], v * k[..., None]], axis=-1)


def quat_rotate(q: ArrayLike, v: ArrayLike) -> F64:
    """Rotate vectors by quaternions: ``q * v * conj(q)`` (sensor to earth for a sensor-to-earth ``q``).

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Unit quaternions ``w, x, y, z``.
    v : array_like, shape (..., 3)
        Vectors.

    Returns
    -------
    ndarray, float64, shape (..., 3)
        Rotated vectors.

    """
    qa = np.asarray(q, dtype=np.float64)
    va = np.asarray(v, dtype=np.float64)
    u = qa[..., 1:]
    t = 2.0 * _cross(u, va)
    out: F64 = va + qa[..., :1] * t + _cross(u, t)
    return out


def quat_rotate_inv(q: ArrayLike, v: ArrayLike) -> F64:
    """Rotate vectors by the inverse of unit quaternions: ``conj(q) * v * q`` (earth to sensor).

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Unit quaternions ``w, x, y, z``.
    v : array_like, shape (..., 3)
        Vectors.

    Returns
    -------
    ndarray, float64, shape (..., 3)
        Rotated vectors.

    """
    qa = np.asarray(q, dtype=np.float64) * np.array([1.0, -1.0, -1.0, -1.0])
    return quat_rotate(qa, v)


def mag_field_earth(cfg: SimConfig) -> F64:
    """Undisturbed earth-frame (ENU) magnetic field ``B * (0, cos(dip), -sin(dip))`` in uT.

    Parameters
    ----------
    cfg : SimConfig
        Uses ``mag_field`` and ``mag_dip``.

    Returns
    -------
    ndarray, float64, shape (3,)
        The field vector.

    """
    return cfg.mag_field * np.array([0.0, math.cos(cfg.mag_dip), -math.sin(cfg.mag_dip)])


def _scan_quat(q: F64) -> F64:
    """Inclusive prefix product ``q[0] * q[1] * ... * q[i]`` along axis 0 (Hillis-Steele, log2 n passes)."""
    out = q.copy()
    shift = 1
    n = out.shape[0]
    while shift < n:
        nxt = out.copy()
        nxt[shift:] = quat_mul(out[:-shift], out[shift:])
        out = nxt
        shift *= 2
    return out


# --- motion ---------------------------------------------------------------------------------------------


def _smootherstep(u: F64) -> tuple[F64, F64, F64]:
    """S(u) = 6u^5 - 15u^4 + 10u^3 on clipped u, and its first two derivatives."""
    u = np.clip(u, 0.0, 1.0)
    s = u * u * u * (10.0 + u * (-15.0 + 6.0 * u))
    ds = 30.0 * u * u * (1.0 - u) * (1.0 - u)
    dds = 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u)
    return s, ds, dds


@dataclass(frozen=True)
class _Envelope:
    segments: tuple[tuple[float, float, float], ...]  # (start, end, ramp)

    def __call__(self, t: F64) -> tuple[F64, F64]:
        """Envelope and its time derivative at ``t``."""
        e = np.zeros_like(t)
        de = np.zeros_like(t)
        for a, b, r in self.segments:
            s1, d1, _ = _smootherstep((t - a) / r)
            s2, d2, _ = _smootherstep((b - t) / r)
            e += s1 * s2
            de += (d1 * s2 - s1 * d2) / r
        return e, de


def _schedule(cfg: SimConfig, rng: np.random.Generator) -> tuple[tuple[float, float, float], ...]:
    """Motion segments (start, end, ramp) between the still periods."""
    start, end = cfg.rest_start, cfg.duration - cfg.rest_end
    length = end - start
    nb = cfg.rest_breaks
    jitter = rng.uniform(-0.25, 0.25, size=nb)
    if length <= 0.0:
        return ()
    seg = (length - nb * cfg.break_duration) / (nb + 1)
    if seg <= 0.0:
        raise ValueError(
            f"{nb} breaks of {cfg.break_duration} s do not fit in {length:.3g} s of motion "
            f"(duration - rest_start - rest_end)"
        )
    bounds = [start]
    for i in range(nb):
        b0 = start + (i + 1) * seg + i * cfg.break_duration + float(jitter[i]) * seg
        bounds += [b0, b0 + cfg.break_duration]
    bounds.append(end)
    out = []
    for a, b in zip(bounds[0::2], bounds[1::2], strict=True):
        r = min(cfg.ramp, 0.5 * (b - a))
        out.append((a, b, r) if r > 0.0 else (a, b, 0.5 * (b - a)))
    return tuple(out)


@dataclass(frozen=True)
class _Sines:
    """Per-axis sums of sinusoids: ``x(t) = sum_k amp[j,k] sin(omega[j,k] t + phase[j,k])``."""

    amp: F64  # (3, K)
    omega: F64  # (3, K) rad/s
    phase: F64  # (3, K)

    @staticmethod
    def draw(rng: np.random.Generator, k: int, f_lo: float, f_hi: float, rms: float) -> _Sines:
        freq = rng.uniform(f_lo, f_hi, size=(3, k))
        phase = rng.uniform(0.0, 2.0 * np.pi, size=(3, k))
        amp = rng.uniform(0.5, 1.0, size=(3, k))
        amp *= rms / np.sqrt(0.5 * np.sum(amp * amp, axis=1, keepdims=True))  # RMS of a sum of sines
        return _Sines(amp, 2.0 * np.pi * freq, phase)

    def table(self, tau: F64) -> _SineTable:
        """Fast evaluator at ``t0 + tau`` for a fixed pattern ``tau`` and any ``t0``."""
        arg = tau[None, :, None] * self.omega[:, None, :]  # (3, P, K)
        return _SineTable(self, np.cos(arg), np.sin(arg))


@dataclass(frozen=True)
class _SineTable:
    """``sin(w (t0 + tau) + p) = sin(w t0 + p) cos(w tau) + cos(w t0 + p) sin(w tau)``: matrix products."""

    sines: _Sines
    cos_tau: F64  # (3, P, K)
    sin_tau: F64

    def value(self, t0: float, count: int) -> F64:
        """Values at ``t0 + tau[:count]``, as (count, 3)."""
        ph = self.sines.omega * t0 + self.sines.phase
        bs = self.sines.amp * np.sin(ph)
        bc = self.sines.amp * np.cos(ph)
        out = np.empty((count, 3), np.float64)
        for j in range(3):
            out[:, j] = self.cos_tau[j, :count] @ bs[j] + self.sin_tau[j, :count] @ bc[j]
        return out

    def deriv(self, t0: float, count: int) -> F64:
        """Time derivative at ``t0 + tau[:count]``, as (count, 3)."""
        ph = self.sines.omega * t0 + self.sines.phase
        aw = self.sines.amp * self.sines.omega
        bs = aw * np.sin(ph)
        bc = aw * np.cos(ph)
        out = np.empty((count, 3), np.float64)
        for j in range(3):
            out[:, j] = self.cos_tau[j, :count] @ bc[j] - self.sin_tau[j, :count] @ bs[j]
        return out


def _cross(a: F64, b: F64) -> F64:
    out = np.empty(np.broadcast_shapes(a.shape, b.shape), np.float64)
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def _initial_attitude(cfg: SimConfig, rng: np.random.Generator) -> F64:
    drawn = rng.normal(size=4)
    q = np.asarray(cfg.initial_attitude, dtype=np.float64) if cfg.initial_attitude is not None else drawn
    q = q / np.linalg.norm(q)
    return q if q[0] >= 0.0 else -q


# --- simulation -----------------------------------------------------------------------------------------


def simulate_with_truth(cfg: SimConfig | None = None) -> tuple[Recording, SimTruth]:
    """Simulate a recording and return it with its noise-free truth.

    Parameters
    ----------
    cfg : SimConfig, optional
        Parameters; defaults to ``SimConfig()``.

    Returns
    -------
    rec : Recording
        float32 ``gyr``, ``acc``, ``mag``; float64 ``quat_true``; ``movement`` True outside the still
        periods (where the envelope is > 0 or a tap is active).
    truth : SimTruth
        The true body rate, bias, linear acceleration, earth field, envelope and taps.

    Raises
    ------
    ValueError
        For an invalid configuration.

    """
    cfg = cfg if cfg is not None else SimConfig()
    cfg.validate()
    n = cfg.n
    dt = 1.0 / cfg.rate
    streams = {
        name: np.random.default_rng(s)
        for name, s in zip(_STREAMS, np.random.SeedSequence(cfg.seed).spawn(len(_STREAMS)), strict=True)
    }
    q0 = _initial_attitude(cfg, streams["attitude"])
    segments = _schedule(cfg, streams["schedule"])
    env = _Envelope(segments)
    k = cfg.components
    rot = _Sines.draw(
        streams["rotation"], k, 0.1 * cfg.rotation_bandwidth, cfg.rotation_bandwidth, cfg.rotation_rms
    )
    # velocity sinusoids whose derivative has RMS translation_rms: draw accel amplitudes, divide by omega
    trans_acc = _Sines.draw(
        streams["translation"],
        k,
        0.2 * cfg.translation_bandwidth,
        cfg.translation_bandwidth,
        cfg.translation_rms,
    )
    vel = _Sines(trans_acc.amp / trans_acc.omega, trans_acc.omega, trans_acc.phase)

    m_sub = cfg.substeps if cfg.substeps > 0 else max(2, math.ceil(dt / _MAX_SUBSTEP - 1e-9))
    h = dt / m_sub
    t = np.arange(n, dtype=np.float64) * dt

    # Chunks of `chunk` samples. Within a chunk the evaluation times form a fixed pattern after the
    # chunk's first time, so the sinusoids come from precomputed tables (see _SineTable).
    chunk = max(256, _TABLE // (2 * m_sub))
    tau_s = np.arange(chunk, dtype=np.float64) * dt
    offsets = (np.arange(m_sub, dtype=np.float64)[:, None] + np.array(_GAUSS)[None, :]) * h  # (M, 2)
    tau_g = (tau_s[:, None, None] + offsets[None, :, :]).reshape(-1)  # Gauss nodes of samples 1..chunk
    rot_s, vel_s, rot_g = rot.table(tau_s), vel.table(tau_s), rot.table(tau_g)

    quat = np.empty((n, 4), np.float64)
    gyr_true = np.empty((n, 3), np.float64)
    acc_lin = np.empty((n, 3), np.float64)
    envelope = np.empty(n, np.float64)
    carry = q0.copy()
    for start in range(0, n, chunk):
        stop = min(start + chunk, n)
        cnt = stop - start
        t0 = start * dt
        # true body rate and linear acceleration at the samples
        e, de = env(t0 + tau_s[:cnt])
        envelope[start:stop] = e
        gyr_true[start:stop] = rot_s.value(t0, cnt) * e[:, None]
        acc_lin[start:stop] = vel_s.value(t0, cnt) * de[:, None] + vel_s.deriv(t0, cnt) * e[:, None]
        # ground truth attitude over (t_{k-1}, t_k] for k in [max(start, 1), stop): Magnus-4 per
        # substep, composed per sample, then a prefix product over the chunk
        if start == 0:
            quat[0] = q0
        first = max(start, 1)
        steps = stop - first
        if steps <= 0:
            continue
        tg0 = (first - 1) * dt
        eg, _ = env(tg0 + tau_g[: steps * m_sub * 2])
        w = (rot_g.value(tg0, steps * m_sub * 2) * eg[:, None]).reshape(steps, m_sub, 2, 3)
        w1, w2 = w[:, :, 0, :], w[:, :, 1, :]
        theta = 0.5 * h * (w1 + w2) + (_SQRT3 / 12.0) * h * h * _cross(w1, w2)
        inc = quat_exp(theta)  # (steps, M, 4)
        step = inc[:, 0, :]
        for j in range(1, m_sub):
            step = quat_mul(step, inc[:, j, :])
        prefix = quat_mul(carry, _scan_quat(step))
        prefix /= np.linalg.norm(prefix, axis=1, keepdims=True)
        quat[first:stop] = prefix
        carry = prefix[-1]

    tap_times, tap_dirs = _draw_taps(cfg, segments, streams["taps"])
    tap_active = np.zeros(n, dtype=np.bool_)
    for t_tap, d in zip(tap_times, tap_dirs, strict=True):
        i0 = max(0, math.ceil(t_tap * cfg.rate - 1e-9))
        i1 = min(n, math.ceil((t_tap + cfg.tap_duration) * cfg.rate - 1e-9))
        if i1 <= i0:
            continue
        tau = t[i0:i1] - t_tap
        acc_lin[i0:i1] += (cfg.tap_amplitude * np.sin(2.0 * np.pi * tau / cfg.tap_duration))[:, None] * d
        tap_active[i0:i1] = True

    # --- sensors
    rng_g = streams["gyro"]
    b0 = rng_g.uniform(-cfg.gyro_bias, cfg.gyro_bias, size=3)
    bias = rng_g.normal(size=(n, 3))
    bias *= cfg.gyro_bias_drift * math.sqrt(dt)
    if n:
        bias[0] = b0
    np.cumsum(bias, axis=0, out=bias)
    gyr = rng_g.normal(size=(n, 3))
    gyr *= cfg.gyro_noise
    gyr += gyr_true
    gyr += bias

    mag_earth = np.broadcast_to(mag_field_earth(cfg), (n, 3)).copy()
    for t_start, t_end, extra in cfg.mag_disturbances:
        on = (t >= t_start) & (t < t_end)
        mag_earth[on] += np.asarray(extra, dtype=np.float64)

    g_earth = np.array([0.0, 0.0, cfg.gravity])
    acc = streams["accel"].normal(size=(n, 3))
    acc *= cfg.accel_noise
    mag = streams["mag"].normal(size=(n, 3))
    mag *= cfg.mag_noise
    for start in range(0, n, _TABLE):
        sl = slice(start, min(start + _TABLE, n))
        acc[sl] += quat_rotate_inv(quat[sl], acc_lin[sl] + g_earth)
        mag[sl] += quat_rotate_inv(quat[sl], mag_earth[sl])

    movement = (envelope > 0.0) | tap_active
    groups = ["simulated"]
    if cfg.rotation_rms > 0:
        groups.append("rotation")
    if cfg.translation_rms > 0:
        groups.append("translation")
    groups.append("with_breaks" if cfg.rest_breaks else "no_breaks")
    if cfg.taps:
        groups.append("tapping")
    if cfg.mag_disturbances:
        groups.append("magnet")
    rec = Recording(
        gyr=gyr.astype(np.float32),
        acc=acc.astype(np.float32),
        mag=mag.astype(np.float32),
        rate=cfg.rate,
        quat_true=quat,
        movement=movement,
        name=cfg.name or f"sim-seed{cfg.seed}",
        groups=tuple(groups),
    )
    truth = SimTruth(
        gyr=gyr_true,
        gyr_bias=bias,
        acc_lin=acc_lin,
        mag_earth=mag_earth,
        envelope=envelope,
        segments=tuple((a, b) for a, b, _ in segments),
        tap_times=tap_times,
        tap_dirs=tap_dirs,
        substeps=m_sub,
    )
    return rec, truth


def _draw_taps(
    cfg: SimConfig, segments: tuple[tuple[float, float, float], ...], rng: np.random.Generator
) -> tuple[F64, F64]:
    """Tap start times (stratified over the segment interiors, away from the ramps) and directions."""
    n_taps = cfg.taps
    dirs = rng.normal(size=(n_taps, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    u = rng.uniform(0.1, 0.9, size=n_taps)
    if n_taps == 0:
        return np.zeros(0, np.float64), np.zeros((0, 3), np.float64)
    spans = [(a + r, b - r - cfg.tap_duration) for a, b, r in segments]
    spans = [(a, b) for a, b in spans if b > a]
    if not spans:  # no room inside the motion: anywhere in the recording
        spans = [(0.0, max(0.0, cfg.duration - cfg.tap_duration))]
    lengths = np.array([b - a for a, b in spans])
    cum = np.concatenate([[0.0], np.cumsum(lengths)])
    pos = (np.arange(n_taps) + u) / n_taps * cum[-1]
    seg = np.clip(np.searchsorted(cum, pos, side="right") - 1, 0, len(spans) - 1)
    starts = np.array([spans[s][0] for s in seg]) + (pos - cum[seg])
    return starts, dirs


def simulate(cfg: SimConfig | None = None) -> Recording:
    """Simulate an IMU recording with ground truth (see the module docstring for the models).

    Parameters
    ----------
    cfg : SimConfig, optional
        Parameters; defaults to ``SimConfig()``.

    Returns
    -------
    Recording
        float32 sensor data, float64 ``quat_true`` and the ``movement`` mask.
        :func:`simulate_with_truth` also returns the noise-free quantities.

    """
    return simulate_with_truth(cfg)[0]


def sim_to_npz(rec: Recording, path: str | os.PathLike[str]) -> None:
    """Save a (simulated) recording as ``.npz`` in the BROAD layout; same as ``rec.save(path)``.

    Parameters
    ----------
    rec : Recording
        The recording.
    path : str or os.PathLike
        Destination, must end in ``.npz``.

    """
    rec.save(path)

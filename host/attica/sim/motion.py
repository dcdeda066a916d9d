"""The simulated motion: still and moving phases, smooth random rotation and translation, taps, the field."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from attica.sim.config import SimConfig
from attica.sim.rotations import F64


def mag_field_earth(cfg: SimConfig) -> F64:
    """Undisturbed earth-frame (ENU) magnetic field ``B * (cos(dip) sin(D), cos(dip) cos(D), -sin(dip))``, uT.

    Parameters
    ----------
    cfg : SimConfig
        Uses ``mag_field``, ``mag_dip`` and ``mag_declination`` (D, east of true north).

    Returns
    -------
    ndarray, float64, shape (3,)
        The field vector.

    """
    h = math.cos(cfg.mag_dip)
    d = cfg.mag_declination
    return cfg.mag_field * np.array([h * math.sin(d), h * math.cos(d), -math.sin(cfg.mag_dip)])


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


def _initial_attitude(cfg: SimConfig, rng: np.random.Generator) -> F64:
    drawn = rng.normal(size=4)
    q = np.asarray(cfg.initial_attitude, dtype=np.float64) if cfg.initial_attitude is not None else drawn
    q = q / np.linalg.norm(q)
    return q if q[0] >= 0.0 else -q


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


def _spin_rate(cfg: SimConfig, t: F64) -> F64:
    """Body rate of the :attr:`SimConfig.spins` at ``t`` (sensor frame, rad/s), shape (len(t), 3)."""
    out = np.zeros((t.size, 3), np.float64)
    for t0, length, peak, axis in cfg.spins:
        on = (t >= t0) & (t < t0 + length)
        if not on.any():
            continue
        a = np.asarray(axis, np.float64)
        s = np.sin(np.pi * (t[on] - t0) / length)
        out[on] += (peak * s * s)[:, None] * (a / np.linalg.norm(a))
    return out


def _spinning(cfg: SimConfig, t: F64) -> NDArray[np.bool_]:
    """Where a spin of :attr:`SimConfig.spins` is under way."""
    on = np.zeros(t.size, np.bool_)
    for t0, length, _, _ in cfg.spins:
        on |= (t >= t0) & (t < t0 + length)
    return on


@dataclass(frozen=True)
class _Vibration:
    """Sinusoidal vibration at ``omega`` rad/s: ``amp * sin(omega t + phase[j])`` per sensor axis ``j``."""

    amp: float
    omega: float
    phase: F64  # (3,)

    def __call__(self, t: F64) -> F64:
        """Values at ``t``, shape (len(t), 3)."""
        out: F64 = self.amp * np.sin(self.omega * t[:, None] + self.phase[None, :])
        return out


def _vibrations(cfg: SimConfig, rng: np.random.Generator) -> tuple[_Vibration | None, _Vibration | None]:
    """The accelerometer's (m/s^2) and the gyro's (rad/s) vibration; None where the amplitude is 0."""
    phase = rng.uniform(0.0, 2.0 * np.pi, size=(2, 3))
    omega = 2.0 * np.pi * cfg.vibration_frequency
    acc = _Vibration(cfg.vibration_accel, omega, phase[0]) if cfg.vibration_accel > 0 else None
    gyr = _Vibration(cfg.vibration_gyro, omega, phase[1]) if cfg.vibration_gyro > 0 else None
    return acc, gyr


MU0_4PI = 0.1
"""mu0 / (4 pi) = 1e-7 T m/A in uT m^3 / (A m^2): a dipole of 1 A m^2 gives 0.1 uT at 1 m across its
axis and 0.2 uT along it."""


def _dipole_field(cfg: SimConfig, t: F64) -> F64:
    """Earth-frame field (uT) of the moving magnets of :attr:`SimConfig.mag_dipoles` at ``t``."""
    out = np.zeros((t.size, 3), np.float64)
    for t0, t1, p0, p1, moment in cfg.mag_dipoles:
        on = (t >= t0) & (t < t1)
        if not on.any():
            continue
        u = (t[on] - t0) / (t1 - t0)
        a, b = np.asarray(p0, np.float64), np.asarray(p1, np.float64)
        r = a[None, :] + u[:, None] * (b - a)[None, :]
        dist = np.linalg.norm(r, axis=1)
        rh = r / dist[:, None]
        m = np.asarray(moment, np.float64)
        out[on] += MU0_4PI * (3.0 * rh * (rh @ m)[:, None] - m[None, :]) / (dist**3)[:, None]
    return out

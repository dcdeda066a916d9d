"""The simulation itself: integrate the motion, make the sensor readings, return recording and truth."""

from __future__ import annotations

import math
import os

import numpy as np

from attica.data import Recording
from attica.metrics import quat_mul
from attica.sim.config import SimConfig, SimTruth
from attica.sim.errors import distort, draw_errors
from attica.sim.motion import (
    _dipole_field,
    _draw_taps,
    _Envelope,
    _initial_attitude,
    _schedule,
    _Sines,
    _spin_rate,
    _spinning,
    _vibrations,
    mag_field_earth,
)
from attica.sim.rotations import F64, _cross, _scan_quat, quat_exp, quat_rotate, quat_rotate_inv

__all__ = ["sim_to_npz", "simulate", "simulate_with_truth"]


_TABLE = 1 << 15  # evaluation points per chunk
_MAX_SUBSTEP = 1e-3  # s, automatic substep length bound
_SQRT3 = math.sqrt(3.0)
_GAUSS = (0.5 - _SQRT3 / 6.0, 0.5 + _SQRT3 / 6.0)
_STREAMS = (
    "attitude",
    "schedule",
    "rotation",
    "translation",
    "taps",
    "gyro",
    "accel",
    "mag",
    "vibration",
    "errors",
)
"""One seeded stream each; streams added at the end leave the earlier ones (and their draws) unchanged."""


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
    vib_acc, vib_gyr = _vibrations(cfg, streams["vibration"])

    def extra_rate(tt: F64) -> F64 | None:
        """Body rate of the spins and the angular vibration at ``tt`` (None when there is neither)."""
        if not cfg.spins and vib_gyr is None:
            return None
        w = _spin_rate(cfg, tt)
        if vib_gyr is not None:
            w += vib_gyr(tt)
        return w

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
        more = extra_rate(t0 + tau_s[:cnt])
        if more is not None:
            gyr_true[start:stop] += more
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
        w = rot_g.value(tg0, steps * m_sub * 2) * eg[:, None]
        more = extra_rate(tg0 + tau_g[: steps * m_sub * 2])
        if more is not None:
            w += more
        w = w.reshape(steps, m_sub, 2, 3)
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
    if vib_acc is not None:  # a sensor-frame vibration, kept in the truth's earth frame
        for start in range(0, n, _TABLE):
            sl = slice(start, min(start + _TABLE, n))
            acc_lin[sl] += quat_rotate(quat[sl], vib_acc(t[sl]))

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
    if cfg.mag_dipoles:
        mag_earth += _dipole_field(cfg, t)

    g_earth = np.array([0.0, 0.0, cfg.gravity])
    acc = streams["accel"].normal(size=(n, 3))
    acc *= cfg.accel_noise
    mag = streams["mag"].normal(size=(n, 3))
    mag *= cfg.mag_noise
    for start in range(0, n, _TABLE):
        sl = slice(start, min(start + _TABLE, n))
        acc[sl] += quat_rotate_inv(quat[sl], acc_lin[sl] + g_earth)
        mag[sl] += quat_rotate_inv(quat[sl], mag_earth[sl])
    errors = None
    if cfg.sensor_errors is not None:
        seed = int(streams["errors"].integers(0, 2**63 - 1))
        errors = draw_errors(seed, cfg.sensor_errors)
        gyr, acc, mag = distort(gyr, acc, mag, errors)
    clipped = np.zeros((n, 3), np.bool_)
    if cfg.gyro_clip > 0:
        clipped = np.abs(gyr) > cfg.gyro_clip
        np.clip(gyr, -cfg.gyro_clip, cfg.gyro_clip, out=gyr)

    movement = (envelope > 0.0) | tap_active
    if cfg.spins:
        movement |= _spinning(cfg, t)
    groups = ["simulated"]
    if cfg.rotation_rms > 0:
        groups.append("rotation")
    if cfg.translation_rms > 0:
        groups.append("translation")
    groups.append("with_breaks" if cfg.rest_breaks else "no_breaks")
    if cfg.taps:
        groups.append("tapping")
    if cfg.mag_disturbances or cfg.mag_dipoles:
        groups.append("magnet")
    if cfg.vibration_accel > 0 or cfg.vibration_gyro > 0:
        groups.append("vibration")
    if cfg.sensor_errors is not None:
        groups.append("sensor_errors")
    if clipped.any():
        groups.append("gyro_clipped")
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
        gyr_clipped=clipped,
        errors=errors,
    )
    return rec, truth


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

"""Recordings made for calibration: a magnetometer sphere sweep and static multi-position sessions.

Both are what a user records before ``attica calibrate``, simulated with ground truth:

- :func:`mag_sweep`: the sensor is turned in the hand through a tumbling "figure eight": yaw
  ``psi = 2 pi t / 20 s + p0``, pitch ``theta = extent (pi/2) sin(2 pi t / 11.7 s + p1)``, roll
  ``phi = extent pi sin(2 pi t / 7.3 s + p2)`` (ZYX, body-to-ENU ``q = qz(psi) qy(theta) qx(phi)``;
  phases ``p`` seeded). ``extent = 1`` visits the whole sphere in about a minute; smaller values keep
  the sensor near level (``extent = 0``: turning on a table, a circle on the sphere).
- :func:`static_poses`: ``poses`` still positions of ``dwell`` s joined by smooth ``move`` s turns
  (slerp with a quintic ramp): first the six with each sensor axis up and down (+z, -z, +x, -x, +y, -y),
  then seeded random orientations; every position gets a random heading. The still periods serve the
  gyro offset, the positions the accelerometer fit.

The body rate is exact for :func:`static_poses` (the rotation vector of each turn times the ramp's
rate) and a central difference of the analytic attitude (step 1e-5 s, error ~1e-9 rad/s) for
:func:`mag_sweep`. Sensors: ``gyr = w + noise``, ``acc = R^T (0, 0, g) + noise`` (the sensor turns about
its own centre: no linear acceleration), ``mag = R^T m_earth + noise``; the noise levels, field,
gravity, rate and seed come from a :class:`~attica.sim.SimConfig` (its motion fields are not used).
With ``errors`` the samples are distorted by :func:`attica.sim.errors.apply_errors`.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from attica.calibration.model import Calibration
from attica.data import Recording
from attica.metrics import quat_mul
from attica.sim.config import SimConfig
from attica.sim.errors import apply_errors
from attica.sim.motion import mag_field_earth
from attica.sim.rotations import F64, quat_exp, quat_rotate_inv

__all__ = ["mag_sweep", "static_poses"]

_YAW_PERIOD, _PITCH_PERIOD, _ROLL_PERIOD = 20.0, 11.7, 7.3  # s
_DIFF_STEP = 1e-5  # s


def _axis_quat(axis: int, angle: F64) -> F64:
    q = np.zeros((*np.shape(angle), 4))
    q[..., 0] = np.cos(0.5 * angle)
    q[..., 1 + axis] = np.sin(0.5 * angle)
    return q


def _sweep_attitude(t: F64, extent: float, phase: F64) -> F64:
    psi = 2.0 * np.pi * t / _YAW_PERIOD + phase[0]
    theta = extent * 0.5 * np.pi * np.sin(2.0 * np.pi * t / _PITCH_PERIOD + phase[1])
    phi = extent * np.pi * np.sin(2.0 * np.pi * t / _ROLL_PERIOD + phase[2])
    q: F64 = quat_mul(quat_mul(_axis_quat(2, psi), _axis_quat(1, theta)), _axis_quat(0, phi))
    return q


def _sensors(cfg: SimConfig, quat: F64, gyr_true: F64, rng: np.random.Generator) -> tuple[F64, F64, F64]:
    n = quat.shape[0]
    gyr = gyr_true + cfg.gyro_noise * rng.normal(size=(n, 3))
    acc = quat_rotate_inv(quat, np.array([0.0, 0.0, cfg.gravity])) + cfg.accel_noise * rng.normal(size=(n, 3))
    mag = quat_rotate_inv(quat, mag_field_earth(cfg)) + cfg.mag_noise * rng.normal(size=(n, 3))
    return gyr, acc, mag


def _finish(
    cfg: SimConfig,
    quat: F64,
    gyr: F64,
    acc: F64,
    mag: F64,
    movement: NDArray[np.bool_],
    name: str,
    errors: Calibration | None,
) -> Recording:
    rec = Recording(
        gyr=gyr.astype(np.float32),
        acc=acc.astype(np.float32),
        mag=mag.astype(np.float32),
        rate=cfg.rate,
        quat_true=quat,
        movement=movement,
        name=cfg.name or f"{name}-seed{cfg.seed}",
        groups=("simulated", name),
    )
    return apply_errors(rec, errors) if errors is not None else rec


def mag_sweep(
    cfg: SimConfig | None = None, errors: Calibration | None = None, extent: float = 1.0
) -> Recording:
    """A magnetometer calibration recording: the sensor tumbled through the figure eight.

    Parameters
    ----------
    cfg : SimConfig, optional
        Uses ``duration``, ``rate``, ``seed``, ``gravity``, the ``*_noise`` fields, ``mag_field``,
        ``mag_dip`` and ``name``.
    errors : Calibration, optional
        Sensor errors to apply (the calibration that corrects them).
    extent : float
        In [0, 1]: amplitude of the pitch and roll swings relative to the full sweep.

    Returns
    -------
    Recording
        ``duration * rate`` samples, ``quat_true`` body-to-ENU, ``movement`` all True.

    """
    cfg = cfg if cfg is not None else SimConfig()
    cfg.validate()
    if not 0.0 <= extent <= 1.0:
        raise ValueError(f"extent must be in [0, 1], got {extent}")
    rng_phase, rng_noise = (np.random.default_rng(s) for s in np.random.SeedSequence(cfg.seed).spawn(2))
    phase = rng_phase.uniform(0.0, 2.0 * np.pi, size=3)
    t = np.arange(cfg.n, dtype=np.float64) / cfg.rate
    quat = _sweep_attitude(t, extent, phase)
    dq = (_sweep_attitude(t + _DIFF_STEP, extent, phase) - _sweep_attitude(t - _DIFF_STEP, extent, phase)) / (
        2.0 * _DIFF_STEP
    )
    conj = quat * np.array([1.0, -1.0, -1.0, -1.0])
    gyr_true = 2.0 * quat_mul(conj, dq)[:, 1:]
    gyr, acc, mag = _sensors(cfg, quat, gyr_true, rng_noise)
    return _finish(cfg, quat, gyr, acc, mag, np.ones(cfg.n, np.bool_), "mag_sweep", errors)


def _up_quat(axis: F64) -> F64:
    """A rotation (body-to-ENU) that points the body axis ``axis`` up."""
    a = axis / np.linalg.norm(axis)
    up = np.array([0.0, 0.0, 1.0])
    c = float(a @ up)
    if c < -1.0 + 1e-12:
        return np.array([0.0, 1.0, 0.0, 0.0])  # 180 deg about x
    v = np.cross(a, up)
    q = np.array([1.0 + c, v[0], v[1], v[2]])
    out: F64 = q / np.linalg.norm(q)
    return out


def _quat_log(q: F64) -> F64:
    q = q if q[0] >= 0.0 else -q
    s = float(np.linalg.norm(q[1:]))
    if s < 1e-15:
        return np.zeros(3)
    out: F64 = 2.0 * math.atan2(s, float(q[0])) * q[1:] / s
    return out


def pose_quaternions(poses: int, rng: np.random.Generator) -> F64:
    """The body-to-ENU attitudes of :func:`static_poses`: six axis-up poses, then random ones."""
    faces = np.array([[0, 0, 1], [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]], np.float64)
    out = []
    for i in range(poses):
        if i < len(faces):
            q = _up_quat(faces[i])
        else:
            q = rng.normal(size=4)
            q /= np.linalg.norm(q)
        yaw = _axis_quat(2, np.array(rng.uniform(0.0, 2.0 * np.pi)))
        out.append(quat_mul(yaw, q))
    return np.array(out)


def static_poses(
    cfg: SimConfig | None = None,
    errors: Calibration | None = None,
    poses: int = 6,
    dwell: float = 4.0,
    move: float = 2.0,
) -> Recording:
    """A multi-position recording: still positions joined by smooth turns (accel and gyro calibration).

    Parameters
    ----------
    cfg : SimConfig, optional
        Uses ``rate``, ``seed``, ``gravity``, the ``*_noise`` fields, ``mag_field``, ``mag_dip`` and
        ``name`` (the length is ``poses * dwell + (poses - 1) * move``).
    errors : Calibration, optional
        Sensor errors to apply.
    poses : int
        Number of still positions (>= 1): the six axis-up ones first, then random orientations.
    dwell, move : float
        Seconds still at each position and seconds of each turn.

    Returns
    -------
    Recording
        ``movement`` True during the turns.

    """
    cfg = cfg if cfg is not None else SimConfig()
    cfg.validate()
    if poses < 1 or not (dwell > 0.0 and move > 0.0):
        raise ValueError(f"need poses >= 1, dwell > 0 and move > 0; got {poses}, {dwell}, {move}")
    rng_pose, rng_noise = (np.random.default_rng(s) for s in np.random.SeedSequence(cfg.seed).spawn(2))
    qs = pose_quaternions(poses, rng_pose)
    duration = poses * dwell + (poses - 1) * move
    n = int(round(duration * cfg.rate))
    t = np.arange(n, dtype=np.float64) / cfg.rate
    period = dwell + move
    idx = np.minimum((t // period).astype(np.int64), poses - 1)
    u = np.clip((t - idx * period - dwell) / move, 0.0, 1.0)  # 0 while still, ramps over the turn
    u[idx == poses - 1] = 0.0
    s = u * u * u * (10.0 + u * (-15.0 + 6.0 * u))
    ds = 30.0 * u * u * (1.0 - u) * (1.0 - u) / move
    steps = np.array([_quat_log(quat_mul(qs[i] * [1, -1, -1, -1], qs[i + 1])) for i in range(poses - 1)])
    steps = steps if poses > 1 else np.zeros((1, 3))
    v = steps[np.minimum(idx, len(steps) - 1)]
    quat = quat_mul(qs[idx], quat_exp(v * s[:, None]))
    gyr_true = v * ds[:, None]
    gyr, acc, mag = _sensors(cfg, quat, gyr_true, rng_noise)
    return _finish(cfg, quat, gyr, acc, mag, (u > 0.0) & (u < 1.0), "static_poses", errors)

"""Sensor errors for the simulator: seeded misalignment, scale, offsets, hard/soft iron, mounting.

The errors are described by the :class:`~attica.calibration.Calibration` that *corrects* them (the
truth a calibration fit must find), so tests compare a fit with it directly. A simulated recording
holds the body's motion (``quat_true`` body-to-ENU, vectors in the body frame); :func:`apply_errors`
turns it into what a mis-calibrated, mis-mounted sensor reads, inverting the firmware's input stage:

- mounting ``v_body = R v_sensor``, so ``v_sensor = R^T v_body``;
- inertial model ``v = M (s * (raw - o))``, so ``raw = (M^-1 v) / s + o`` (gyro in rad/s, accel in
  m/s^2);
- magnetic model ``m = S (raw - h)``, so ``raw = S^-1 m + h`` (uT).

Applying the truth calibration to the distorted recording in float64 gives the undistorted samples
back to rounding (:meth:`InertialModel.apply`, :meth:`MagModel.apply`, ``Mounting.matrix``).

:func:`draw_errors` draws the truth from a seed. Its soft-iron matrix is symmetric positive definite:
a magnetometer alone cannot tell a rotation of its axes from a soft-iron distortion (both leave
``|S (raw - h)|`` unchanged), so an ellipsoid fit returns the symmetric ``S``; a rotation belongs to the
mounting. Its inertial misalignments are general (not symmetric): a gravity-only accelerometer fit
finds ``M diag(s)`` up to such a rotation (see :mod:`attica.calibration.inertial`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from attica.calibration.model import Calibration, InertialModel, MagModel, Mounting
from attica.data import Recording
from attica.sim.rotations import F64

__all__ = ["ErrorSizes", "apply_errors", "distort", "draw_errors"]


@dataclasses.dataclass(frozen=True)
class ErrorSizes:
    """Bounds of the drawn errors (each drawn uniform in ``[-bound, bound]``).

    Attributes
    ----------
    gyro_offset : float
        rad/s per axis.
    gyro_scale : float
        Sensitivity deviation from 1 per axis (unitless).
    gyro_misalignment : float
        Off-diagonal misalignment entries (unitless, ~rad).
    accel_offset : float
        m/s^2 per axis.
    accel_scale, accel_misalignment : float
        As for the gyro.
    hard_iron : float
        uT per axis.
    soft_iron_scale : float
        Deviation from 1 of the diagonal of the (symmetric) soft-iron matrix.
    soft_iron_coupling : float
        Off-diagonal entries of the soft-iron matrix.
    mounting : bool
        Draw a random mounting rotation (uniform over rotations); False keeps the identity.

    """

    gyro_offset: float = 0.03
    gyro_scale: float = 0.03
    gyro_misalignment: float = 0.01
    accel_offset: float = 0.3
    accel_scale: float = 0.03
    accel_misalignment: float = 0.01
    hard_iron: float = 25.0
    soft_iron_scale: float = 0.15
    soft_iron_coupling: float = 0.08
    mounting: bool = False

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if isinstance(v, float) and not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"ErrorSizes.{f.name} must be finite and >= 0, got {v}")
        for name in ("gyro_scale", "accel_scale", "soft_iron_scale"):
            if getattr(self, name) >= 0.5:
                raise ValueError(f"ErrorSizes.{name} must be < 0.5, got {getattr(self, name)}")


def mag_only(
    hard_iron: float = 25.0, soft_iron_scale: float = 0.15, soft_iron_coupling: float = 0.08
) -> ErrorSizes:
    """Error bounds for the magnetometer alone: every gyro and accel error 0, the given hard and soft iron.

    Parameters
    ----------
    hard_iron : float
        uT per axis.
    soft_iron_scale, soft_iron_coupling : float
        As in :class:`ErrorSizes`.

    Returns
    -------
    ErrorSizes
        The bounds (no mounting rotation).

    """
    return ErrorSizes(
        gyro_offset=0.0,
        gyro_scale=0.0,
        gyro_misalignment=0.0,
        accel_offset=0.0,
        accel_scale=0.0,
        accel_misalignment=0.0,
        hard_iron=hard_iron,
        soft_iron_scale=soft_iron_scale,
        soft_iron_coupling=soft_iron_coupling,
    )


def _inertial(rng: np.random.Generator, offset: float, scale: float, mis: float) -> InertialModel:
    m = np.eye(3) + rng.uniform(-mis, mis, size=(3, 3)) * (1.0 - np.eye(3))
    s = 1.0 + rng.uniform(-scale, scale, size=3)
    o = rng.uniform(-offset, offset, size=3)
    return InertialModel(misalignment=m.tolist(), sensitivity=s.tolist(), offset=o.tolist())


def draw_errors(seed: int, sizes: ErrorSizes | None = None) -> Calibration:
    """Draw sensor errors from ``seed``: the calibration that corrects them.

    Parameters
    ----------
    seed : int
        Seed (``numpy.random.default_rng``); one independent stream per sensor and the mounting.
    sizes : ErrorSizes, optional
        Bounds of the errors; the defaults are typical of a MEMS IMU near a little iron.

    Returns
    -------
    Calibration
        ``gyro``, ``accel`` (general misalignment), ``mag`` (symmetric positive definite soft iron) and
        ``mounting`` (a quaternion when ``sizes.mounting``); values rounded to float32 like any
        calibration.

    """
    z = sizes if sizes is not None else ErrorSizes()
    rg, ra, rm, rq = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(4))
    gyro = _inertial(rg, z.gyro_offset, z.gyro_scale, z.gyro_misalignment)
    accel = _inertial(ra, z.accel_offset, z.accel_scale, z.accel_misalignment)
    soft = np.diag(1.0 + rm.uniform(-z.soft_iron_scale, z.soft_iron_scale, size=3))
    c = rm.uniform(-z.soft_iron_coupling, z.soft_iron_coupling, size=3)
    soft[0, 1] = soft[1, 0] = c[0]
    soft[0, 2] = soft[2, 0] = c[1]
    soft[1, 2] = soft[2, 1] = c[2]
    if np.linalg.eigvalsh(soft)[0] <= 0.1:
        raise ValueError("soft_iron_coupling too large: the drawn soft-iron matrix is not positive definite")
    hard = rm.uniform(-z.hard_iron, z.hard_iron, size=3)
    mag = MagModel(soft_iron=soft.tolist(), hard_iron=hard.tolist())
    mounting = Mounting()
    if z.mounting:
        q = rq.normal(size=4)
        q /= np.linalg.norm(q)
        q = q if q[0] >= 0 else -q
        mounting = Mounting(quaternion=(float(q[0]), float(q[1]), float(q[2]), float(q[3])))
    return Calibration(gyro=gyro, accel=accel, mag=mag, mounting=mounting)


def _raw_inertial(model: InertialModel, v: F64) -> F64:
    m = np.array(model.misalignment, np.float64)
    out: F64 = np.linalg.solve(m, v.T).T / np.array(model.sensitivity) + np.array(model.offset)
    return out


def distort(gyr: F64, acc: F64, mag: F64, truth: Calibration) -> tuple[F64, F64, F64]:
    """Body-frame float64 samples as a sensor with the errors ``truth`` corrects reads them.

    Parameters
    ----------
    gyr, acc, mag : ndarray, float64, shape (N, 3)
        Body-frame gyro (rad/s), accelerometer (m/s^2) and magnetometer (uT) samples.
    truth : Calibration
        The calibration that undoes the errors (its ``convention`` is not used).

    Returns
    -------
    gyr, acc, mag : ndarray, float64, shape (N, 3)
        The raw readings (NaN rows stay NaN); :func:`apply_errors` on a recording, the simulator's
        :attr:`~attica.sim.SimConfig.sensor_errors` before the float32 cast.

    """
    r_t = truth.mounting.matrix().T  # sensor <- body
    g_raw = _raw_inertial(truth.gyro, gyr @ r_t.T)
    a_raw = _raw_inertial(truth.accel, acc @ r_t.T)
    soft = np.array(truth.mag.soft_iron, np.float64)
    m_sensor = mag @ r_t.T
    m_raw: F64 = np.linalg.solve(soft, m_sensor.T).T + np.array(truth.mag.hard_iron)
    return g_raw, a_raw, m_raw


def apply_errors(rec: Recording, truth: Calibration) -> Recording:
    """What a sensor with the errors ``truth`` corrects reads for the motion of ``rec``.

    Parameters
    ----------
    rec : Recording
        Body-frame samples (a simulation; its noise is distorted with the signal).
    truth : Calibration
        The calibration that undoes the errors (e.g. from :func:`draw_errors`); its ``convention`` is
        not used.

    Returns
    -------
    Recording
        The same recording (truth, movement, rate) with distorted float32 ``gyr``, ``acc``, ``mag``
        (NaN magnetometer rows stay NaN) and ``"sensor_errors"`` added to the groups.

    """
    gyr, acc, mag = distort(
        rec.gyr.astype(np.float64), rec.acc.astype(np.float64), rec.mag.astype(np.float64), truth
    )
    groups = rec.groups if "sensor_errors" in rec.groups else (*rec.groups, "sensor_errors")
    return dataclasses.replace(
        rec,
        gyr=gyr.astype(np.float32),
        acc=acc.astype(np.float32),
        mag=mag.astype(np.float32),
        groups=groups,
    )

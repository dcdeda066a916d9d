"""What the outputs' covariance holds for each kind, and the orientation covariance of ``sensor_msgs/Imu``.

``att_output_t.cov`` holds a diagonal whose meaning depends on the kind
(``firmware/include/attica/att_filter.h``); :data:`COVARIANCE` names its columns (the CSV of
:mod:`attica.data.export`) and says how it becomes the 3x3 orientation covariance of a ROS
``sensor_msgs/msg/Imu`` (:func:`orientation_covariance`: the MCAP output, the view and Foxglove).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from attica.kinds import KINDS, info
from attica.settings import OUTPUT_INVALID, FilterKind

__all__ = ["COVARIANCE", "UNKNOWN_YAW", "Covariance", "orientation_covariance"]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class Covariance:
    """What ``att_output_t.cov`` holds for one kind.

    Attributes
    ----------
    columns : tuple of str
        CSV names of ``cov[0]``, ``cov[1]``, ... (the entries the kind fills; the rest are 0).
    meaning : str
        The header comment of those columns (units and frame).
    orientation : str
        How :func:`orientation_covariance` turns them into the Imu message's 3x3 (rad^2).
    diagonal : callable
        (N, 4) ``cov`` (float64) to the (N, 3) diagonal of the orientation covariance, rad^2.

    """

    columns: tuple[str, ...]
    meaning: str
    orientation: str
    matrix: Callable[[NDArray[np.void]], F64]


UNKNOWN_YAW = float(np.float32(np.pi**2 / 3.0))
"""rad^2: the variance of a heading that is not known (uniform over a turn), as the kinds report it (ars,
ekf and a 6-axis mekf before a set heading and after a clip, mars before its reference field), and as
the kf's is written."""


def _diagonal(cov: F64) -> F64:
    """(N, 3) variances as the (N, 9) row-major matrices with them on the diagonal."""
    m = np.zeros((len(cov), 9))
    m[:, [0, 4, 8]] = cov
    return m


def _kf_matrix(out: NDArray[np.void]) -> F64:
    # P = p I (4x4) projects onto the tangent space of the unit sphere at q as p I3; a small rotation
    # dtheta moves q by q (x) (0, dtheta / 2), so dtheta = 2 dq: 4 p rad^2 about the tilt axes. The yaw of
    # this 6-axis filter is not observed: unknown.
    p = np.asarray(out["cov"], np.float64).mean(axis=1)
    return _diagonal(np.stack([4.0 * p, 4.0 * p, np.full_like(p, UNKNOWN_YAW)], axis=1))


def _ekf_matrix(out: NDArray[np.void]) -> F64:
    # The state is the ZYX Euler angles: a small change turns the sensor by
    # dr = z dpsi + Rz(psi) y dtheta + Rz(psi) Ry(theta) x dphi about the earth's axes, so the covariance
    # about them is sum_i var_i v_i v_i^T with v_phi = (c_psi c_theta, s_psi c_theta, -s_theta),
    # v_theta = (-s_psi, c_psi, 0), v_psi = (0, 0, 1) (the EKF reports no correlations: taken as 0). The
    # yaw of this 6-axis filter is observed by nothing: the output says pi^2/3 (unknown) but from a set
    # heading to the next clipping gyro sample.
    cov = np.asarray(out["cov"], np.float64)
    e = np.asarray(out["euler"], np.float64)
    cth, sth, cps, sps = np.cos(e[:, 1]), np.sin(e[:, 1]), np.cos(e[:, 2]), np.sin(e[:, 2])
    v_phi = np.stack([cps * cth, sps * cth, -sth], axis=1)
    v_theta = np.stack([-sps, cps, np.zeros_like(cps)], axis=1)
    m = cov[:, 0, None, None] * (v_phi[:, :, None] * v_phi[:, None, :])
    m += cov[:, 1, None, None] * (v_theta[:, :, None] * v_theta[:, None, :])
    m[:, 2, 2] += cov[:, 2]
    flat: F64 = m.reshape(len(cov), 9)
    return flat


def _first3(out: NDArray[np.void]) -> F64:
    return _diagonal(np.asarray(out["cov"], np.float64)[:, :3])


_COMPLEMENTARY = Covariance(
    ("var_att_e", "var_att_n", "var_att_u"),
    "variance of the attitude error about the earth's east, north, up axes from the covariance model of "
    "docs/filters.md (tilt: both horizontal axes alike; up: the heading), rad^2",
    "the model's tilt and heading variances about the earth's x (east), y (north), z (up) axes on the "
    "diagonal; the heading's pi^2/3 where it is unknown",
    _first3,
)
"""ars and mars: the covariance model of the complementary filters (att_ars.h, att_mars.h)."""

COVARIANCE: dict[FilterKind, Covariance] = {
    FilterKind.ARS: _COMPLEMENTARY,
    FilterKind.MARS: _COMPLEMENTARY,
    FilterKind.KF: Covariance(
        ("var_q_w", "var_q_x", "var_q_y", "var_q_z"),
        "variance of each quaternion component, (unit quaternion)^2 (the KF carries P = p I: all equal)",
        "4 p about the earth's x and y: the isotropic quaternion variance p as a rotation, dtheta = 2 dq; "
        "the yaw, which this 6-axis filter does not observe, pi^2/3 (unknown)",
        _kf_matrix,
    ),
    FilterKind.EKF: Covariance(
        ("var_roll", "var_pitch", "var_yaw", "var_bias"),
        "variance of the ZYX Euler angles roll, pitch, yaw, rad^2 (yaw, which nothing observes: pi^2/3, "
        "unknown, but from a set heading to the next clipping gyro sample); var_bias: mean variance of "
        "the gyro bias, (rad/s)^2",
        "the roll and pitch variances turned onto the earth's axes through the Euler angles (dr = z dpsi + "
        "Rz(psi) y dtheta + Rz(psi) Ry(theta) x dphi; no correlations reported: taken as 0), off-diagonal "
        "entries included; the yaw's about up (pi^2/3 while the heading is unknown)",
        _ekf_matrix,
    ),
    FilterKind.MEKF: Covariance(
        ("var_att_e", "var_att_n", "var_att_u", "var_bias"),
        "variance of the attitude error (a rotation vector about the earth's east, north, up axes), rad^2 "
        "(up with use_mag off: pi^2/3, unknown, but from a set heading to the next clipping gyro sample); "
        "var_bias: mean variance of the gyro bias, (rad/s)^2",
        "the attitude error variances about the earth's x (east), y (north), z (up) axes on the diagonal",
        _first3,
    ),
}
"""The kinds with a covariance (:attr:`attica.kinds.KindInfo.covariance`) and what their ``cov`` holds.
Only the diagonal is reported (``att_output_t``), so the off-diagonal entries written are 0 (but the
EKF's, whose Euler angles' variances turn onto the earth's axes)."""

if set(COVARIANCE) != {k.kind for k in KINDS if k.covariance}:  # pragma: no cover - a registry edit
    raise RuntimeError("attica.data.export.COVARIANCE must describe every kind with a covariance")


def orientation_covariance(kind: FilterKind | str, out: NDArray[np.void]) -> F64:
    """The (N, 9) row-major orientation covariance of ``sensor_msgs/msg/Imu`` for each output, rad^2.

    A 6-axis filter's yaw is observed by nothing: the kf's is written as unknown (pi^2/3, its P = p I
    cannot say more); the ekf and a mekf with ``use_mag`` off report pi^2/3 themselves but from a set
    heading to the next clipping gyro sample (their output's ``cov[2]``), as ars does.

    As the message definition asks: the kind's variances about the earth's axes (:data:`COVARIANCE`:
    on the diagonal, 0 off it where only the diagonal is reported); all zeros, "covariance unknown",
    for a kind without one (gyro, tilt); element 0 = -1, "no orientation estimate", for the samples
    whose flags say q is not one (:data:`OUTPUT_INVALID`: before the first valid sample).
    """
    k = info(kind)
    n = len(out)
    c = np.zeros((n, 9), np.float64)
    if k.kind in COVARIANCE:
        c[:] = COVARIANCE[k.kind].matrix(out)
    invalid = (np.asarray(out["flags"]) & OUTPUT_INVALID) != 0
    c[invalid] = 0.0
    c[invalid, 0] = -1.0
    return c

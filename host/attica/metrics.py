"""Orientation error metrics as defined by the BROAD benchmark (Laidig et al., Data 6(7), 2021).

Float64 numpy; not part of the bit-exact contract. Quaternions are ``(w, x, y, z)`` sensor-to-earth with the
same (ENU) earth frame for estimate and truth. Both are normalised first, then the error quaternion is
expressed in the earth frame, ``e = q_est * conj(q_true)`` (normalised again), and

- total error ``2 * acos(|e_w|)``,
- heading error ``2 * atan(|e_z / e_w|)`` (rotation about the vertical; meaningless for a 6-axis filter),
- inclination error ``2 * acos(sqrt(e_w^2 + e_z^2))``,

acos arguments clipped to [0, 1]; ``q`` and ``-q`` give the same errors. Each is reported as the RMSE in
degrees over the ``movement`` samples, skipping samples whose truth is unknown (NaN), as BROAD does.

One deliberate difference: BROAD's ``nanmean`` would also skip samples where the *estimate* is NaN, so a
filter that fails would look perfect. :func:`evaluate` instead returns NaN if any scored sample (in
``movement``, truth known) has a non-finite (or zero) estimate. And a pure 180 deg tilt error
(``e_w = e_z = 0``) has heading error 0 here, where BROAD's ``0/0`` gives NaN and skips the sample.

Beside the errors, :func:`stated` compares a method's stated orientation covariance (``sensor_msgs/Imu``'s)
with them over the same rows: mean squared error against mean stated variance (:func:`pooled_ratio`
over recordings; 1 is consistent, above 1 optimistic).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "STATED_ANGLES",
    "Errors",
    "Stated",
    "error_angles",
    "error_quat",
    "evaluate",
    "pooled_ratio",
    "quat_mul",
    "rmse_deg",
    "stated",
]

F64 = NDArray[np.float64]


def _quats(q: ArrayLike, what: str) -> F64:
    a = np.array(q, dtype=np.float64)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != 4:
        raise ValueError(f"{what}: expected shape (N, 4) or (4,), got {np.shape(q)}")
    return a


def quat_mul(a: ArrayLike, b: ArrayLike) -> F64:
    """Hamilton product ``a * b`` of ``w, x, y, z`` quaternions, row-wise with broadcasting.

    Parameters
    ----------
    a, b : array_like, shape (..., 4)
        Quaternions.

    Returns
    -------
    ndarray, float64, shape (..., 4)
        The products.

    """
    p = np.asarray(a, dtype=np.float64)
    q = np.asarray(b, dtype=np.float64)
    w1, x1, y1, z1 = (p[..., i] for i in range(4))
    w2, x2, y2, z2 = (q[..., i] for i in range(4))
    return np.stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        axis=-1,
    )


def _normalised(q: F64) -> F64:
    with np.errstate(invalid="ignore", divide="ignore"):
        out: F64 = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return out


def error_quat(q_est: ArrayLike, q_true: ArrayLike) -> F64:
    """Earth-frame error quaternion ``e = q_est * conj(q_true)``, inputs and output normalised.

    Parameters
    ----------
    q_est, q_true : array_like, shape (N, 4) or (4,)
        Estimated and true orientation, ``w, x, y, z`` sensor-to-earth. A single quaternion broadcasts.

    Returns
    -------
    ndarray, float64, shape (N, 4)
        Error quaternions; NaN rows where an input row is NaN or zero.

    """
    est = _normalised(_quats(q_est, "q_est"))
    true = _normalised(_quats(q_true, "q_true"))
    if est.shape[0] != true.shape[0] and 1 not in (est.shape[0], true.shape[0]):
        raise ValueError(f"q_est has {est.shape[0]} rows, q_true has {true.shape[0]}")
    conj = true * np.array([1.0, -1.0, -1.0, -1.0])
    return _normalised(quat_mul(est, conj))


def error_angles(q_est: ArrayLike, q_true: ArrayLike) -> tuple[F64, F64, F64]:
    """Per-sample total, heading and inclination errors in rad (BROAD definitions).

    Parameters
    ----------
    q_est, q_true : array_like, shape (N, 4) or (4,)
        Estimated and true orientation, ``w, x, y, z`` sensor-to-earth (earth frames must agree).

    Returns
    -------
    total, heading, inclination : ndarray, float64, shape (N,)
        Errors in rad, each in [0, pi]; NaN where the truth (or the estimate) is NaN.

    """
    e = error_quat(q_est, q_true)
    ew, ez = e[:, 0], e[:, 3]
    with np.errstate(invalid="ignore", divide="ignore"):
        total = 2.0 * np.arccos(np.clip(np.abs(ew), 0.0, 1.0))
        heading = 2.0 * np.arctan(np.abs(ez / ew))
        inclination = 2.0 * np.arccos(np.clip(np.sqrt(ew * ew + ez * ez), 0.0, 1.0))
    # e_w = e_z = 0 (a pure 180 deg tilt): heading is 0/0; the error is all inclination.
    heading = np.where((ew == 0.0) & (ez == 0.0), 0.0, heading)
    return total, heading, inclination


def rmse_deg(angles_rad: ArrayLike, mask: ArrayLike | None = None) -> float:
    """Root mean square of angles in rad, as degrees, over ``mask`` and ignoring NaN (BROAD's ``rmse``).

    Parameters
    ----------
    angles_rad : array_like, shape (N,)
        Per-sample errors in rad.
    mask : array_like of bool, shape (N,), optional
        Samples to include; all when None.

    Returns
    -------
    float
        RMSE in degrees; NaN when no finite sample is selected.

    """
    a = np.asarray(angles_rad, dtype=np.float64).reshape(-1)
    if mask is not None:
        m = np.asarray(mask)
        if m.dtype != np.bool_:
            raise ValueError(f"mask must be boolean, got {m.dtype}")
        if m.shape != a.shape:
            raise ValueError(f"mask shape {m.shape} does not match angles shape {a.shape}")
        a = a[m]
    a = a[~np.isnan(a)]
    if a.size == 0:
        return float("nan")
    return float(np.degrees(np.sqrt(np.mean(a * a))))


@dataclass(frozen=True)
class Errors:
    """RMSE of the orientation error in degrees (BROAD metrics).

    Attributes
    ----------
    total : float
        Total rotation angle error.
    heading : float
        Heading (rotation about the vertical) error; meaningless for 6-axis filters.
    inclination : float
        Inclination (tilt) error.
    n : int
        Number of samples scored (in ``movement`` with known truth).

    """

    total: float
    heading: float
    inclination: float
    n: int = 0

    def as_dict(self) -> dict[str, Any]:
        """Plain dict using BROAD's key names (``total_rmse_deg`` ...) plus ``n``."""
        return {
            "total_rmse_deg": self.total,
            "heading_rmse_deg": self.heading,
            "inclination_rmse_deg": self.inclination,
            "n": self.n,
        }


def _scored(
    q_est: ArrayLike, q_true: ArrayLike, movement: ArrayLike | None
) -> tuple[F64, F64, NDArray[np.bool_]]:
    """Estimate and truth as (N, 4) float64 and the rows scored: in ``movement``, truth finite.

    Raises
    ------
    ValueError
        On shape mismatches or a non-boolean ``movement``.

    """
    est = _quats(q_est, "q_est")
    true = _quats(q_true, "q_true")
    if est.shape != true.shape:
        raise ValueError(f"q_est shape {est.shape} does not match q_true shape {true.shape}")
    n = true.shape[0]
    if movement is None:
        scored = np.ones(n, dtype=np.bool_)
    else:
        mov = np.asarray(movement)
        if mov.dtype != np.bool_:
            raise ValueError(f"movement must be boolean, got {mov.dtype}")
        if mov.shape != (n,):
            raise ValueError(f"movement shape {mov.shape} does not match {n} samples")
        scored = mov.copy()
    scored &= np.all(np.isfinite(true), axis=1)
    return est, true, scored


def evaluate(q_est: ArrayLike, q_true: ArrayLike, movement: ArrayLike | None = None) -> Errors:
    """BROAD error RMSEs of an estimate against ground truth.

    Parameters
    ----------
    q_est : array_like, shape (N, 4)
        Estimated orientation, ``w, x, y, z`` sensor-to-ENU.
    q_true : array_like, shape (N, 4)
        True orientation; rows with a NaN are skipped.
    movement : array_like of bool, shape (N,), optional
        Samples that count; all when None.

    Returns
    -------
    Errors
        Total, heading and inclination RMSE in degrees (NaN if no sample is scored, or if a scored
        sample has a non-finite or zero estimate).

    Raises
    ------
    ValueError
        On shape mismatches or a non-boolean ``movement``.

    """
    est, true, scored = _scored(q_est, q_true, movement)
    count = int(np.count_nonzero(scored))
    nan = float("nan")
    if count == 0 or not np.all(np.isfinite(est[scored])):
        return Errors(nan, nan, nan, count)
    total, heading, inclination = error_angles(est[scored], true[scored])
    if np.isnan(total).any():  # a zero quaternion
        return Errors(nan, nan, nan, count)
    return Errors(rmse_deg(total), rmse_deg(heading), rmse_deg(inclination), count)


STATED_ANGLES = ("inclination", "heading")
"""The angles whose stated variance :func:`stated` compares with the error."""


@dataclass(frozen=True)
class Stated:
    """A stated orientation covariance against the errors over one recording's compared rows (rad^2).

    Attributes
    ----------
    inclination_mse, inclination_var : float
        Mean squared inclination error, and mean stated tilt variance: the sum of the variances about
        the earth's two horizontal axes (what the inclination error squared is, to first order).
    heading_mse, heading_var : float
        Mean squared heading error, and mean stated variance about the vertical (meaningful for a
        9-axis method; a 6-axis one states its unobserved heading as unknown).
    n : int
        Rows compared.

    """

    inclination_mse: float
    inclination_var: float
    heading_mse: float
    heading_var: float
    n: int = 0

    def ratio(self, angle: str) -> float:
        """Mean squared error over mean stated variance of ``angle`` (:data:`STATED_ANGLES`)."""
        return pooled_ratio([self], angle)


def pooled_ratio(rows: Sequence[Stated], angle: str) -> float:
    """Mean squared error over mean stated variance of ``angle``, each recording with rows counting alike.

    1 is a consistent covariance, above 1 an optimistic one; NaN when no recording compared a row (or
    one's figures are NaN: a failed estimate).

    Raises
    ------
    ValueError
        For an angle not in :data:`STATED_ANGLES`.

    """
    if angle not in STATED_ANGLES:
        raise ValueError(f"angle must be one of {', '.join(STATED_ANGLES)}, not {angle!r}")
    used = [r for r in rows if r.n > 0]
    if not used:
        return float("nan")
    mse = float(np.mean([getattr(r, f"{angle}_mse") for r in used]))
    var = float(np.mean([getattr(r, f"{angle}_var") for r in used]))
    return mse / var if var > 0.0 else float("nan")


def stated(q_est: ArrayLike, q_true: ArrayLike, cov: ArrayLike, movement: ArrayLike | None = None) -> Stated:
    """The errors against the stated orientation covariance (``sensor_msgs/Imu``'s, about ENU's axes).

    The rows compared are those :func:`evaluate` scores (in ``movement``, truth known) whose covariance
    is stated: not element 0 = -1 ("no orientation estimate"), not all zeros ("covariance unknown"),
    finite. As in :func:`evaluate`, a scored row whose estimate is not finite makes every figure NaN
    (a filter that fails must not look consistent).

    Parameters
    ----------
    q_est, q_true : array_like, shape (N, 4)
        Estimated and true orientation, ``w, x, y, z`` sensor-to-ENU.
    cov : array_like, shape (N, 9)
        Row-major 3x3 orientation covariance about the earth's east, north, up axes, rad^2, as
        :func:`attica.data.covariance.orientation_covariance` writes it.
    movement : array_like of bool, shape (N,), optional
        Rows that count; all when None.

    Returns
    -------
    Stated
        Means over the rows compared; NaN (n 0) when there is none.

    Raises
    ------
    ValueError
        On shape mismatches or a non-boolean ``movement``.

    """
    est, true, rows = _scored(q_est, q_true, movement)
    c = np.asarray(cov, dtype=np.float64)
    if c.shape != (true.shape[0], 9):
        raise ValueError(f"cov has shape {c.shape}, expected ({true.shape[0]}, 9)")
    nan = float("nan")
    if not np.all(np.isfinite(est[rows])):
        return Stated(nan, nan, nan, nan, 0)
    _, heading, inclination = error_angles(est, true)
    tilt_var = c[:, 0] + c[:, 4]
    rows &= np.isfinite(c).all(axis=1) & (c[:, 0] != -1.0) & np.any(c != 0.0, axis=1)
    k = int(rows.sum())
    if k == 0:
        return Stated(nan, nan, nan, nan, 0)
    return Stated(
        float(np.mean(inclination[rows] ** 2)),
        float(np.mean(tilt_var[rows])),
        float(np.mean(heading[rows] ** 2)),
        float(np.mean(c[rows, 8])),
        k,
    )

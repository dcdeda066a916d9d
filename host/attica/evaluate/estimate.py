"""What one estimator returns for one recording: attitude, optional flags and gyro bias, notes.

A method's ``run(recording)`` (:class:`attica.evaluate.Method`) returns either the bare ``(N, 4)``
quaternions or an :class:`Estimate`, which can also say which rows hold an estimate at all (a peer that
cannot start before the first magnetometer sample, say), carry the filter's status flags and gyro-bias
estimate for the plots, and notes that the evaluation prints beside its tables.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["Estimate", "as_estimate"]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class Estimate:
    """One method's output on one recording.

    Attributes
    ----------
    q : ndarray, float64, shape (N, 4)
        ``w, x, y, z`` sensor-to-ENU; rows outside ``scored`` may be NaN.
    scored : ndarray of bool, shape (N,), or None
        Rows that hold an estimate and count for the metrics (with the recording's ``movement``);
        None: every row.
    flags : ndarray, uint32, shape (N,), or None
        ``ATT_FLAG_*`` words per row (attica's filters); None when the method has none.
    gyro_bias : ndarray, shape (N, 3), or None
        Gyro-bias estimate in rad/s, sensor frame; None when the method does not estimate one.
    notes : tuple of str
        What was done to the input or the scoring that a reader of the tables must know.
    cov : ndarray, float64, shape (N, 9), or None
        The orientation covariance the method states (row-major 3x3 about the earth's east, north, up
        axes, rad^2, as :func:`attica.data.covariance.orientation_covariance` writes it; element 0 -1
        where there is no estimate); None when the method states none.

    """

    q: F64
    scored: NDArray[np.bool_] | None = None
    flags: NDArray[np.uint32] | None = None
    gyro_bias: NDArray[np.floating] | None = None
    notes: tuple[str, ...] = ()
    cov: F64 | None = None


def as_estimate(out: F64 | Estimate, n: int, who: str = "method") -> Estimate:
    """An :class:`Estimate` of a method's return value (bare quaternions are wrapped), shapes checked.

    Raises
    ------
    ValueError
        When the quaternions are not ``(n, 4)`` or an optional array does not have ``n`` rows.

    """
    est = out if isinstance(out, Estimate) else Estimate(np.asarray(out, dtype=np.float64))
    q = np.asarray(est.q, dtype=np.float64)
    if q.shape != (n, 4):
        raise ValueError(f"{who}: returned quaternions of shape {q.shape}, expected ({n}, 4)")
    for what, arr in (("scored", est.scored), ("flags", est.flags), ("gyro_bias", est.gyro_bias)):
        if arr is not None and np.shape(arr)[0] != n:
            raise ValueError(f"{who}: {what} has {np.shape(arr)[0]} rows, expected {n}")
    if est.cov is not None and np.shape(est.cov) != (n, 9):
        raise ValueError(f"{who}: cov has shape {np.shape(est.cov)}, expected ({n}, 9)")
    if q is est.q:
        return est
    return Estimate(q, est.scored, est.flags, est.gyro_bias, est.notes, est.cov)

"""Per-sample curves of one method on one trial, thinned for the plots (:mod:`attica.evaluate.plots`).

A trace keeps every ``step``-th sample (about :data:`PLOT_POINTS` per trial): the Euler angles, the
BROAD error angles against the truth, the gyro-bias estimate, and the status flags OR-ed over each
``step`` samples (so a flag set for a single sample still shows). Traces are made where the method ran
(a worker process or a Dask worker) and are small enough to send back.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from attica.data import Recording
from attica.evaluate.estimate import Estimate
from attica.metrics import error_angles

__all__ = ["PLOT_POINTS", "Trace", "euler_deg", "make_trace", "trace_index"]

PLOT_POINTS = 4000
"""About this many samples per trial are kept for the plots (every ``n // PLOT_POINTS``-th)."""

F32 = NDArray[np.float32]


def trace_index(n: int) -> NDArray[np.intp]:
    """The sample indices a trace of an ``n``-sample trial keeps."""
    return np.arange(0, n, max(1, n // PLOT_POINTS))


def euler_deg(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """ZYX roll, pitch, yaw in degrees of ``(N, 4)`` quaternions ``w, x, y, z`` (NaN rows stay NaN).

    The convention of attica's ``euler`` output: yaw about the ENU vertical, then pitch, then roll.
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        u = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = u[:, 0], u[:, 1], u[:, 2], u[:, 3]
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    out: NDArray[np.float64] = np.degrees(np.stack([roll, pitch, yaw], axis=1))
    return out


@dataclass(frozen=True)
class Trace:
    """Thinned per-sample curves (rows at :func:`trace_index` of the trial's length).

    Attributes
    ----------
    index : ndarray of int
        Sample indices kept.
    euler : ndarray, float32, shape (k, 3)
        Roll, pitch, yaw of the estimate in degrees.
    total, heading, inclination : ndarray, float32, shape (k,)
        BROAD error angles against the truth in degrees (NaN where either is unknown).
    flags : ndarray, uint32, shape (k,), or None
        ``ATT_FLAG_*`` bits set at any sample from each kept row up to the next.
    gyro_bias : ndarray, float32, shape (k, 3), or None
        Gyro-bias estimate in deg/s.

    """

    index: NDArray[np.intp]
    euler: F32
    total: F32
    heading: F32
    inclination: F32
    flags: NDArray[np.uint32] | None = None
    gyro_bias: F32 | None = None


def make_trace(est: Estimate, rec: Recording) -> Trace:
    """The trace of an estimate on a recording with ground truth."""
    assert rec.quat_true is not None
    idx = trace_index(len(rec))
    q = est.q[idx]
    total, heading, incl = error_angles(q, rec.quat_true[idx])
    flags = None
    if est.flags is not None:
        flags = np.bitwise_or.reduceat(np.asarray(est.flags, dtype=np.uint32), idx).astype(np.uint32)
    bias = None
    if est.gyro_bias is not None:
        bias = np.degrees(np.asarray(est.gyro_bias, dtype=np.float64)[idx]).astype(np.float32)
    return Trace(
        idx,
        euler_deg(q).astype(np.float32),
        np.degrees(total).astype(np.float32),
        np.degrees(heading).astype(np.float32),
        np.degrees(incl).astype(np.float32),
        flags,
        bias,
    )

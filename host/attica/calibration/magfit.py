"""Magnetometer hard- and soft-iron fit: a robust ellipsoid fit in float64.

Model (the firmware's, :class:`~attica.calibration.MagModel`): ``m = S (raw - h)`` with ``|m| = B``
for every sample of an undisturbed field, ``S`` symmetric positive definite (a rotation of the axes
cannot be seen in the magnitudes: it belongs to the mounting), ``h`` the hard-iron offset in uT.

The fit, on samples centred and scaled by a first sphere fit (for conditioning):

1. a start: a sphere fit ``|x - c|^2 = R^2`` (linear least squares, exact for samples on a sphere
   however unevenly they cover it), three rounds reweighted with Tukey's bisquare of the relative
   radial residuals (scale at least 5 %, so a soft-iron distortion is not mistaken for outliers);
2. algebraic least squares: the general quadric ``x^T A x + b^T x + c = 0`` minimising the weighted
   algebraic distance (the smallest right singular vector of the weighted design matrix). It must be
   an ellipsoid (``A`` definite), else the samples are refused. Four rounds, each reweighting with
   Tukey's bisquare of the radial residuals (``c = 4.685`` robust standard deviations, from the MAD);
3. geometric refinement with iteratively reweighted Gauss-Newton on ``r_i = |S (x_i - h)| - 1`` over the
   nine parameters (``S`` symmetric, ``h``), the bisquare weights recomputed from the residuals each
   iteration (outliers get weight 0 and are reported);
4. the scale: ``|S (raw - h)| = B`` with ``B = field`` when given (the local field strength, e.g. from the
   World Magnetic Model), otherwise ``det S = 1`` (a pure shape correction; ``B`` is then the radius of
   the sphere with the ellipsoid's volume).

The coverage (:mod:`attica.calibration.coverage`) is measured on the corrected directions of the
inlying samples; below ``min_coverage`` the fit is refused: an ellipsoid seen over a small part of the
sphere is not determined by it (see docs/calibration.md for the measured errors against coverage).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.calibration.coverage import coverage
from attica.calibration.errors import CalibrationError
from attica.calibration.model import MagModel

__all__ = ["MIN_COVERAGE", "MIN_SAMPLES", "MagFit", "fit_mag"]

F64 = NDArray[np.float64]

MIN_COVERAGE = 0.5
"""Default coverage a fit needs (fraction of the sphere's cells visited)."""

MIN_SAMPLES = 50
"""Fewest valid samples a fit accepts."""

TUKEY = 4.685
"""Bisquare tuning constant in robust standard deviations (95 % efficiency for normal noise)."""

MAX_AXIS_RATIO = 10.0
"""Largest ratio of the soft-iron matrix's eigenvalues accepted (beyond it the fit has failed)."""

_ITERATIONS = 30
_ALGEBRAIC_ROUNDS = 4
_SPHERE_ROUNDS = 3
_SPHERE_MIN_SCALE = 0.05
_MAD = 1.4826  # MAD to standard deviation for normal noise


@dataclass(frozen=True)
class MagFit:
    """The result of :func:`fit_mag`.

    Attributes
    ----------
    model : MagModel
        ``S`` and ``h`` (uT).
    field : float
        ``B``, the corrected field strength in uT.
    coverage : float
        Fraction of the sphere's cells visited by the corrected inlying samples.
    samples : int
        Valid samples (finite, not all zero).
    inliers : int
        Samples with a non-zero final weight.
    before_rms, before_max : float
        RMS and largest ``| |raw| - mean |raw| |`` of the inliers in uT (the spread the distortion makes).
    after_rms, after_max : float
        RMS and largest ``| |S (raw - h)| - B |`` of the inliers in uT.
    hard_iron_std : tuple of 3 floats
        Standard error of ``h`` in uT (from the Gauss-Newton covariance; small only with coverage).
    iterations : int
        Gauss-Newton iterations used.
    inlier_mask : ndarray of bool
        Per input row: valid and inlying.

    """

    model: MagModel
    field: float
    coverage: float
    samples: int
    inliers: int
    before_rms: float
    before_max: float
    after_rms: float
    after_max: float
    hard_iron_std: tuple[float, float, float]
    iterations: int
    inlier_mask: NDArray[np.bool_] = dataclasses.field(repr=False, compare=False)

    def record(self) -> dict[str, Any]:
        """What the calibration file's ``fit.mag`` keeps of this fit."""
        return {
            "field_uT": self.field,
            "coverage": self.coverage,
            "samples": self.samples,
            "inliers": self.inliers,
            "residual_before_rms_uT": self.before_rms,
            "residual_after_rms_uT": self.after_rms,
            "hard_iron_std_uT": list(self.hard_iron_std),
        }


def _bisquare(r: F64, scale: float) -> F64:
    c = TUKEY * max(scale, 1e-12)
    u = np.clip(r / c, -1.0, 1.0)
    w: F64 = (1.0 - u * u) ** 2
    return w


def _robust_scale(r: F64, w: F64 | None = None) -> float:
    sel = r if w is None else r[w > 0.0]
    if sel.size == 0:
        return 0.0
    return float(_MAD * np.median(np.abs(sel - np.median(sel))))


def _algebraic(y: F64, w: F64) -> tuple[F64, F64]:
    """Weighted algebraic quadric fit; (S0, h) with ``|S0 (y - h)| = 1``, or CalibrationError."""
    x1, x2, x3 = y[:, 0], y[:, 1], y[:, 2]
    design = np.stack(
        [
            x1 * x1,
            x2 * x2,
            x3 * x3,
            2 * x1 * x2,
            2 * x1 * x3,
            2 * x2 * x3,
            2 * x1,
            2 * x2,
            2 * x3,
            np.ones_like(x1),
        ],
        axis=1,
    )
    _, _, vt = np.linalg.svd(design * np.sqrt(w)[:, None], full_matrices=False)
    p = vt[-1]
    a = np.array([[p[0], p[3], p[4]], [p[3], p[1], p[5]], [p[4], p[5], p[2]]])
    b = p[6:9]
    try:
        h = -np.linalg.solve(a, b)
    except np.linalg.LinAlgError:
        raise CalibrationError(_not_ellipsoid()) from None
    r = float(h @ a @ h - p[9])
    if r == 0.0:
        raise CalibrationError(_not_ellipsoid())
    q = a / r
    ev, evec = np.linalg.eigh(q)
    if ev[0] <= 0.0:
        raise CalibrationError(_not_ellipsoid())
    s0: F64 = (evec * np.sqrt(ev)) @ evec.T
    return s0, h


def _not_ellipsoid() -> str:
    return (
        "the magnetometer samples do not determine an ellipsoid (they visit too little of the sphere, "
        "e.g. turns in one plane): record while turning the sensor through every orientation "
        "(tumble it through a figure eight, every face up and down)"
    )


def _sphere_start(x: F64) -> tuple[F64, float, F64]:
    """Robust sphere fit ``|x - c| = R`` (linear least squares, bisquare rounds); (c, R, weights)."""
    w = np.ones(x.shape[0])
    design = np.concatenate([2.0 * x, np.ones((x.shape[0], 1))], axis=1)
    rhs = np.sum(x * x, axis=1)
    c = np.median(x, axis=0)
    radius = 0.0
    for _ in range(_SPHERE_ROUNDS):
        sw = np.sqrt(w)
        sol, *_ = np.linalg.lstsq(design * sw[:, None], rhs * sw, rcond=None)
        c = sol[:3]
        r2 = float(sol[3] + c @ c)
        if not (np.isfinite(r2) and r2 > 0.0):
            raise CalibrationError(_not_ellipsoid())
        radius = math.sqrt(r2)
        rel = np.linalg.norm(x - c, axis=1) / radius - 1.0
        # the soft iron alone makes radial residuals of 10-20 %: do not reject those
        w = _bisquare(rel - np.median(rel[w > 0]), max(_robust_scale(rel, w), _SPHERE_MIN_SCALE))
    return c, radius, w


def _sym(p: F64) -> F64:
    return np.array([[p[0], p[3], p[4]], [p[3], p[1], p[5]], [p[4], p[5], p[2]]])


def _gauss_newton(y: F64, s0: F64, h0: F64, w0: F64) -> tuple[F64, F64, F64, F64 | None, int]:
    """IRLS Gauss-Newton on ``|S (y - h)| - 1``; (S, h, weights, covariance of h or None, iterations)."""
    theta = np.array([s0[0, 0], s0[1, 1], s0[2, 2], s0[0, 1], s0[0, 2], s0[1, 2], *h0])
    w = w0
    it = 0
    cov_h: F64 | None = None
    while it < _ITERATIONS:
        it += 1
        s, h = _sym(theta[:6]), theta[6:]
        d = y - h
        u = d @ s  # S symmetric: rows are S d
        n = np.linalg.norm(u, axis=1)
        r = n - 1.0
        scale = _robust_scale(r, w)
        w = _bisquare(r - np.median(r[w > 0]), scale) if scale > 0 else np.ones_like(r)
        un = u / n[:, None]
        jac = np.empty((y.shape[0], 9))
        jac[:, 0] = un[:, 0] * d[:, 0]
        jac[:, 1] = un[:, 1] * d[:, 1]
        jac[:, 2] = un[:, 2] * d[:, 2]
        jac[:, 3] = un[:, 0] * d[:, 1] + un[:, 1] * d[:, 0]
        jac[:, 4] = un[:, 0] * d[:, 2] + un[:, 2] * d[:, 0]
        jac[:, 5] = un[:, 1] * d[:, 2] + un[:, 2] * d[:, 1]
        jac[:, 6:] = -un @ s
        jw = jac * w[:, None]
        normal = jw.T @ jac
        try:
            inv = np.linalg.inv(normal)
        except np.linalg.LinAlgError:
            raise CalibrationError(_not_ellipsoid()) from None
        step = inv @ (jw.T @ -r)
        if not np.all(np.isfinite(step)):
            raise CalibrationError(_not_ellipsoid())
        theta = theta + step
        if float(np.max(np.abs(theta))) > 1e3:  # the data scaled to radius 1: the fit diverges
            raise CalibrationError(_not_ellipsoid())
        dof = max(1.0, float(np.sum(w > 0)) - 9.0)
        cov_h = np.asarray(float(np.sum(w * r * r)) / dof * inv[6:, 6:], np.float64)
        if float(np.max(np.abs(step))) < 1e-10:
            break
    s, h = _sym(theta[:6]), theta[6:]
    r = np.linalg.norm((y - h) @ s, axis=1) - 1.0
    scale = _robust_scale(r, w)
    w = _bisquare(r - np.median(r[w > 0]), scale) if scale > 0 else np.ones_like(r)
    return s, h, w, cov_h, it


def fit_mag(
    raw: NDArray[np.floating[Any]], field_strength: float | None = None, min_coverage: float = MIN_COVERAGE
) -> MagFit:
    """Fit hard iron ``h`` and symmetric soft iron ``S`` so that ``|S (raw - h)| = B``.

    Parameters
    ----------
    raw : ndarray, shape (N, 3)
        Magnetometer samples in uT (NaN or all-zero rows are skipped).
    field_strength : float, optional
        ``B``, the local field strength in uT; None: ``det S = 1``.
    min_coverage : float
        Refuse the fit when the corrected samples visit less of the sphere (0 disables the check).

    Returns
    -------
    MagFit
        The model, coverage and residuals.

    Raises
    ------
    CalibrationError
        Too few samples, samples not on an ellipsoid, a degenerate result or too little coverage.
    ValueError
        A bad ``raw`` shape or ``field_strength``.

    """
    x_all = np.asarray(raw, np.float64)
    if x_all.ndim != 2 or x_all.shape[1] != 3:
        raise ValueError(f"magnetometer samples must have shape (N, 3), got {x_all.shape}")
    if field_strength is not None and not (math.isfinite(field_strength) and field_strength > 0.0):
        raise ValueError(f"field strength must be finite and > 0 uT, got {field_strength}")
    valid = np.isfinite(x_all).all(axis=1) & (np.abs(x_all).sum(axis=1) > 0.0)
    x = x_all[valid]
    if x.shape[0] < MIN_SAMPLES:
        raise CalibrationError(
            f"{x.shape[0]} valid magnetometer samples; a fit needs at least {MIN_SAMPLES} "
            "(is the magnetometer recorded?)"
        )
    centre, k, w0 = _sphere_start(x)
    y = (x - centre) / k
    try:
        for _ in range(_ALGEBRAIC_ROUNDS):
            s0, h0 = _algebraic(y, w0)
            r0 = np.linalg.norm((y - h0) @ s0, axis=1) - 1.0
            scale = _robust_scale(r0, w0)
            w0 = _bisquare(r0 - np.median(r0[w0 > 0]), scale) if scale > 0 else w0
        s_y, h_y, w, cov_h, iters = _gauss_newton(y, s0, h0, w0)
        ev = np.linalg.eigvalsh(s_y)
        if not (ev[0] > 0.0 and ev[-1] / ev[0] <= MAX_AXIS_RATIO):
            raise CalibrationError(_not_ellipsoid())
    except CalibrationError:
        raise CalibrationError(_not_ellipsoid()) from None
    hard = centre + k * h_y
    s_raw = s_y / k
    b = float(field_strength) if field_strength is not None else float(np.linalg.det(s_raw)) ** (-1.0 / 3.0)
    soft = b * s_raw
    inl = w > 0.0
    corrected = (x - hard) @ soft.T
    cov = coverage(corrected[inl])
    if cov < min_coverage:
        raise CalibrationError(
            f"the recording covers {cov:.0%} of the sphere, a magnetometer fit needs {min_coverage:.0%}: "
            "turn the sensor through more orientations (tumble it through a figure eight, every face up "
            "and down)"
        )
    mag_before = np.linalg.norm(x[inl], axis=1)
    dev_before = np.abs(mag_before - mag_before.mean())
    dev_after = np.abs(np.linalg.norm(corrected[inl], axis=1) - b)
    std = (k * np.sqrt(np.maximum(np.diag(cov_h), 0.0))) if cov_h is not None else np.full(3, np.inf)
    mask = np.zeros(x_all.shape[0], np.bool_)
    mask[np.flatnonzero(valid)[inl]] = True
    try:
        model = MagModel(soft_iron=soft.tolist(), hard_iron=hard.tolist())
    except ValueError as exc:
        raise CalibrationError(f"the fitted model is not usable: {exc}") from None
    return MagFit(
        model=model,
        field=b,
        coverage=cov,
        samples=int(x.shape[0]),
        inliers=int(inl.sum()),
        before_rms=float(np.sqrt(np.mean(dev_before**2))),
        before_max=float(dev_before.max()),
        after_rms=float(np.sqrt(np.mean(dev_after**2))),
        after_max=float(dev_after.max()),
        hard_iron_std=(float(std[0]), float(std[1]), float(std[2])),
        iterations=iters,
        inlier_mask=mask,
    )

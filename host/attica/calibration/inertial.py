"""Gyro offset from still periods; accelerometer offset, scale and misalignment from still positions.

Both fit the firmware's inertial model ``v = M (s * (raw - o))`` (:class:`~attica.calibration.InertialModel`).

Gyro (:func:`fit_gyro`): still, the true rate is zero (the earth's 7.3e-5 rad/s is below every MEMS
gyro's noise), so ``o`` is the mean raw rate over the still periods (:mod:`attica.calibration.rest`).
``M`` and ``s`` need known rotations (a turntable) and are kept as they were.

Accelerometer (:func:`fit_accel`): still, ``|A (a - o)| = g`` with ``A = M diag(s)``. Each still period
gives one mean vector (one equation); periods whose directions lie within ``MERGE_ANGLE`` of each other
count as one position. The fit (Levenberg-Marquardt on the positions' residuals, float64) finds

- ``o`` and ``s`` (6 unknowns, ``M = I``) from six positions or more, or
- ``o`` and a symmetric ``A`` (9 unknowns) from nine or more, split as ``s_j = |A e_j|`` (column norms)
  and ``M = A diag(1/s)``. Gravity alone cannot see a rotation of the axes: a general misalignment is
  found up to it, as its symmetric (polar) factor; the rotation is the mounting's.

``misalignment="auto"`` (default) fits the symmetric ``A`` when it is well determined and the diagonal
model otherwise. "Well determined" is the condition number of the Jacobian (offsets in units of g) at
most ``MAX_CONDITION``: six positions with every axis up and down give about 1.4; positions all on one
side of the sphere, far more, and the fit is refused with what to record.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.calibration.errors import CalibrationError
from attica.calibration.model import InertialModel
from attica.calibration.rest import RestPeriods, find_rest

__all__ = [
    "GRAVITY",
    "MAX_CONDITION",
    "MERGE_ANGLE",
    "MIN_POSITIONS",
    "MIN_REST",
    "AccelFit",
    "GyroFit",
    "fit_accel",
    "fit_gyro",
]

F64 = NDArray[np.float64]

GRAVITY = 9.80665
"""Standard gravity, m/s^2 (the default ``g``)."""

MIN_REST = 2.0
"""Still seconds the gyro fit needs."""

MIN_POSITIONS = 6
"""Distinct still positions the accelerometer fit needs."""

MERGE_ANGLE = 10.0
"""Still periods within this many degrees of each other are one position."""

MAX_CONDITION = 30.0
"""Largest Jacobian condition number of an accepted accelerometer fit."""


@dataclass(frozen=True)
class GyroFit:
    """The result of :func:`fit_gyro`.

    Attributes
    ----------
    model : InertialModel
        The new gyro model (``o`` fitted; ``M``, ``s`` from ``base``).
    rest : RestPeriods
        The still periods used.
    spread : tuple of 3 floats
        Standard deviation of the per-period means in rad/s (offset drift between periods; 0 for one).
    noise : tuple of 3 floats
        Standard deviation of the still samples about their period's mean, rad/s.
    before_rms, after_rms : float
        RMS of ``|raw|`` and of ``|raw - o|`` over the still samples, rad/s.

    """

    model: InertialModel
    rest: RestPeriods
    spread: tuple[float, float, float]
    noise: tuple[float, float, float]
    before_rms: float
    after_rms: float

    def record(self) -> dict[str, Any]:
        """What the calibration file's ``fit.gyro`` keeps."""
        return {
            "rest_s": self.rest.seconds,
            "periods": len(self.rest.segments),
            "spread_rad_s": list(self.spread),
            "residual_before_rms_rad_s": self.before_rms,
            "residual_after_rms_rad_s": self.after_rms,
        }


def _t3(x: Any) -> tuple[float, float, float]:
    return (float(x[0]), float(x[1]), float(x[2]))


def fit_gyro(
    gyr: NDArray[np.floating[Any]],
    acc: NDArray[np.floating[Any]],
    rate: float,
    base: InertialModel | None = None,
    min_rest: float = MIN_REST,
    rest: RestPeriods | None = None,
) -> GyroFit:
    """Gyro offset: the mean raw rate over the still periods.

    Parameters
    ----------
    gyr, acc : ndarray, shape (N, 3)
        Raw samples, rad/s and m/s^2.
    rate : float
        Hz.
    base : InertialModel, optional
        Gyro model whose misalignment and sensitivity are kept (identity when None).
    min_rest : float
        Still seconds needed.
    rest : RestPeriods, optional
        Still periods (found with :func:`~attica.calibration.rest.find_rest` when None).

    Raises
    ------
    CalibrationError
        Less than ``min_rest`` s of stillness.

    """
    g = np.asarray(gyr, np.float64)
    periods = rest if rest is not None else find_rest(g, acc, rate)
    if periods.seconds < min_rest:
        raise CalibrationError(
            f"{periods.seconds:.1f} s of the recording is still, the gyro offset needs {min_rest:g} s: "
            "record with the sensor lying still (untouched) for a few seconds"
        )
    still = g[periods.mask(g.shape[0])]
    offset = still.mean(axis=0)
    means = np.array([g[a:b].mean(axis=0) for a, b in periods.segments])
    within = np.concatenate([g[a:b] - g[a:b].mean(axis=0) for a, b in periods.segments])
    b = base if base is not None else InertialModel()
    model = InertialModel(misalignment=b.misalignment, sensitivity=b.sensitivity, offset=offset.tolist())
    return GyroFit(
        model=model,
        rest=periods,
        spread=_t3(means.std(axis=0)),
        noise=_t3(within.std(axis=0)),
        before_rms=float(np.sqrt(np.mean(np.sum(still * still, axis=1)))),
        after_rms=float(np.sqrt(np.mean(np.sum((still - offset) ** 2, axis=1)))),
    )


@dataclass(frozen=True)
class AccelFit:
    """The result of :func:`fit_accel`.

    Attributes
    ----------
    model : InertialModel
        ``M``, ``s``, ``o`` (m/s^2).
    misalignment : bool
        Whether ``M`` was fitted (symmetric ``A``) or left the identity.
    positions : ndarray, shape (P, 3)
        Mean raw vector of each still period, m/s^2.
    counts : ndarray, shape (P,)
        Samples of each still period.
    distinct : int
        Distinct positions among them (directions more than ``MERGE_ANGLE`` apart).
    gravity : float
        ``g`` used, m/s^2.
    condition : float
        Jacobian condition number of the fitted model.
    offset_std, scale_std : tuple of 3 floats
        Standard errors from the positions' noise (m/s^2, unitless).
    before, after : ndarray, shape (P,)
        Per position ``|a| - g`` and ``|A (a - o)| - g``, m/s^2.
    rest : RestPeriods
        The still periods used.

    """

    model: InertialModel
    misalignment: bool
    positions: F64
    counts: NDArray[np.int64]
    distinct: int
    gravity: float
    condition: float
    offset_std: tuple[float, float, float]
    scale_std: tuple[float, float, float]
    before: F64
    after: F64
    rest: RestPeriods

    @property
    def before_rms(self) -> float:
        """RMS of :attr:`before`, m/s^2."""
        return float(np.sqrt(np.mean(self.before**2)))

    @property
    def after_rms(self) -> float:
        """RMS of :attr:`after`, m/s^2."""
        return float(np.sqrt(np.mean(self.after**2)))

    def record(self) -> dict[str, Any]:
        """What the calibration file's ``fit.accel`` keeps."""
        return {
            "positions": self.distinct,
            "still_periods": int(self.positions.shape[0]),
            "misalignment_fitted": self.misalignment,
            "gravity_m_s2": self.gravity,
            "condition": self.condition,
            "offset_std_m_s2": list(self.offset_std),
            "scale_std": list(self.scale_std),
            "residual_before_rms_m_s2": self.before_rms,
            "residual_after_rms_m_s2": self.after_rms,
        }


def _positions(a: F64, periods: RestPeriods) -> tuple[F64, NDArray[np.int64], F64, int]:
    """Mean vector, sample count and per-axis noise of each still period; number of distinct positions.

    Every period is one equation of the fit; periods within ``MERGE_ANGLE`` of each other count as one
    position (they are not averaged: two nearby directions would average to a shorter vector).
    """
    means = np.array([a[s:e].mean(axis=0) for s, e in periods.segments]).reshape(-1, 3)
    counts = np.array([e - s for s, e in periods.segments], np.int64)
    noise = np.array([a[s:e].std(axis=0, ddof=1) for s, e in periods.segments]).reshape(-1, 3)
    cos_merge = math.cos(math.radians(MERGE_ANGLE))
    units = means / np.maximum(np.linalg.norm(means, axis=1, keepdims=True), 1e-300)
    distinct: list[F64] = []
    for u in units:
        if not any(float(u @ d) > cos_merge for d in distinct):
            distinct.append(u)
    return means, counts, noise, len(distinct)


def _unpack(theta: F64, sym: bool) -> tuple[F64, F64]:
    o = theta[:3]
    p = theta[3:]
    if sym:
        a = np.array([[p[0], p[3], p[4]], [p[3], p[1], p[5]], [p[4], p[5], p[2]]])
    else:
        a = np.diag(p)
    return a, o


def _residual_jacobian(theta: F64, pos: F64, g: float, sym: bool) -> tuple[F64, F64]:
    a, o = _unpack(theta, sym)
    d = pos - o
    u = d @ a.T
    n = np.linalg.norm(u, axis=1)
    un = u / n[:, None]
    cols = [-(un @ a)]  # d r / d o
    diag = un * d
    cols.append(diag)
    if sym:
        cols.append(
            np.stack(
                [
                    un[:, 0] * d[:, 1] + un[:, 1] * d[:, 0],
                    un[:, 0] * d[:, 2] + un[:, 2] * d[:, 0],
                    un[:, 1] * d[:, 2] + un[:, 2] * d[:, 1],
                ],
                axis=1,
            )
        )
    return n - g, np.concatenate(cols, axis=1)


def _levenberg(pos: F64, g: float, sym: bool, a0: float) -> F64:
    theta = np.concatenate([np.zeros(3), np.full(3, a0), np.zeros(3 if sym else 0)])
    lam = 1e-3
    r, j = _residual_jacobian(theta, pos, g, sym)
    cost = float(r @ r)
    for _ in range(200):
        jtj = j.T @ j
        step = np.linalg.solve(jtj + lam * np.diag(np.diag(jtj) + 1e-12), -(j.T @ r))
        trial = theta + step
        r2, j2 = _residual_jacobian(trial, pos, g, sym)
        c2 = float(r2 @ r2)
        if np.isfinite(c2) and c2 <= cost:
            theta, r, j, cost = trial, r2, j2, c2
            lam = max(lam / 10.0, 1e-12)
            if float(np.max(np.abs(step))) < 1e-13 * max(1.0, float(np.max(np.abs(theta)))):
                break
        else:
            lam *= 10.0
            if lam > 1e12:
                break
    return theta


def _condition(j: F64, g: float) -> float:
    jn = j.copy()
    jn[:, :3] *= g  # offsets in units of g
    jn /= g  # residuals in units of g
    sv = np.linalg.svd(jn, compute_uv=False)
    return float(sv[0] / sv[-1]) if sv[-1] > 0 and jn.shape[0] >= jn.shape[1] else math.inf


def fit_accel(
    acc: NDArray[np.floating[Any]],
    gyr: NDArray[np.floating[Any]],
    rate: float,
    gravity: float = GRAVITY,
    misalignment: str = "auto",
    min_positions: int = MIN_POSITIONS,
    rest: RestPeriods | None = None,
) -> AccelFit:
    """Accelerometer offset, sensitivity (and misalignment) from still positions.

    Parameters
    ----------
    acc, gyr : ndarray, shape (N, 3)
        Raw samples, m/s^2 and rad/s (the gyro finds the still periods).
    rate : float
        Hz.
    gravity : float
        Local ``g`` in m/s^2.
    misalignment : {"auto", "on", "off"}
        Fit the symmetric ``A`` when well determined, always, or never.
    min_positions : int
        Distinct positions needed (at least 6).
    rest : RestPeriods, optional
        Still periods (found when None).

    Raises
    ------
    CalibrationError
        Too few positions, or positions that do not determine the model.

    """
    if misalignment not in ("auto", "on", "off"):
        raise ValueError(f"misalignment must be auto, on or off, got {misalignment!r}")
    if not (math.isfinite(gravity) and gravity > 0.0):
        raise ValueError(f"gravity must be finite and > 0, got {gravity}")
    a = np.asarray(acc, np.float64)
    periods = rest if rest is not None else find_rest(gyr, a, rate)
    pos, counts, noise, distinct = _positions(a, periods)
    need = max(MIN_POSITIONS, min_positions)
    if distinct < need:
        raise CalibrationError(
            f"{distinct} distinct still position(s) found (from {len(periods.segments)} still "
            f"period(s) of at least 1 s), the accelerometer fit needs {need}: hold the sensor still for "
            "a few seconds with each axis pointing up and then down (six positions), more positions "
            "for the misalignment"
        )
    if misalignment == "on" and distinct < 9:
        raise CalibrationError(
            f"{distinct} positions: the misalignment needs at least 9 (6 axis up/down and 3 tilted)"
        )
    a0 = gravity / float(np.median(np.linalg.norm(pos, axis=1)))
    choices = {"auto": [True, False] if distinct >= 9 else [False], "on": [True], "off": [False]}
    result = None
    worst = math.inf
    for sym in choices[misalignment]:
        theta = _levenberg(pos, gravity, sym, a0)
        r, j = _residual_jacobian(theta, pos, gravity, sym)
        cond = _condition(j, gravity)
        worst = min(worst, cond)
        if np.all(np.isfinite(theta)) and cond <= MAX_CONDITION:
            result = (sym, theta, r, j, cond)
            break
    if result is None:
        raise CalibrationError(
            f"the {distinct} still positions do not determine the accelerometer model (condition "
            f"number {worst:.3g}, at most {MAX_CONDITION:g} accepted): they must include every axis "
            "pointing up and pointing down"
        )
    sym, theta, r, j, cond = result
    amat, o = _unpack(theta, sym)
    if sym:
        s = np.linalg.norm(amat, axis=0)
        m = amat / s
    else:
        s, m = np.diag(amat).copy(), np.eye(3)
    # standard errors from the positions' radial noise (the mean of each position)
    sigma = np.maximum(np.linalg.norm(noise, axis=1) / np.sqrt(3.0 * counts), 1e-9)
    jw = j / sigma[:, None]
    try:
        cov = np.linalg.inv(jw.T @ jw)
        std = np.sqrt(np.maximum(np.diag(cov), 0.0))
    except np.linalg.LinAlgError:
        std = np.full(j.shape[1], math.inf)
    try:
        model = InertialModel(misalignment=m.tolist(), sensitivity=s.tolist(), offset=o.tolist())
    except ValueError as exc:
        raise CalibrationError(f"the fitted accelerometer model is not usable: {exc}") from None
    return AccelFit(
        model=model,
        misalignment=sym,
        positions=pos,
        counts=counts,
        distinct=distinct,
        gravity=gravity,
        condition=cond,
        offset_std=_t3(std[:3]),
        scale_std=_t3(std[3:6]),
        before=np.linalg.norm(pos, axis=1) - gravity,
        after=r,
        rest=periods,
    )

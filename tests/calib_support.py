"""Calibration settings for the stage tests: ordinary, adversarial, and the C stage objects."""

from __future__ import annotations

from typing import Any

import numpy as np

from attica.calibration.stages import REMAP_NAMES, StageSettings, fill_c
from attica.native import ffi, lib


def _near_identity(rng: np.random.Generator, spread: float = 0.05) -> np.ndarray:
    return (np.eye(3) + rng.normal(0.0, spread, (3, 3))).ravel()


def _conditioned(rng: np.random.Generator, cond: float, scale: float = 1.0, flip: bool = False) -> np.ndarray:
    """A random matrix with 2-norm condition number cond (float64 before rounding)."""
    u, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    v, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    s = np.array([1.0, np.sqrt(cond), cond])[::-1] / cond * scale
    m = u @ np.diag(s) @ v.T
    if flip:
        m[0] = -m[0]
    return m.ravel()


def unit_quat(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def ordinary(
    rng: np.random.Generator, remap: int = 0, convention: int = 0, accel_outputs: bool = True
) -> StageSettings:
    """Realistic non-identity settings: small misalignment, 10 % scale, offsets, hard/soft iron."""
    return StageSettings(
        gyro_misalignment=_near_identity(rng, 0.02),
        gyro_sensitivity=1.0 + rng.normal(0.0, 0.05, 3),
        gyro_offset=rng.normal(0.0, 0.05, 3),
        accel_misalignment=_near_identity(rng, 0.02),
        accel_sensitivity=1.0 + rng.normal(0.0, 0.05, 3),
        accel_offset=rng.normal(0.0, 0.3, 3),
        soft_iron=_near_identity(rng, 0.1),
        hard_iron=rng.normal(0.0, 20.0, 3),
        remap=remap,
        mounting=unit_quat(rng),
        convention=convention,
        accel_outputs=accel_outputs,
    )


def adversarial(rng: np.random.Generator, i: int) -> StageSettings:
    """Settings at the edges of the contract, cycling through kinds of trouble with i."""
    kind = i % 8
    eye = np.eye(3).ravel()
    m1 = m2 = m3 = _near_identity(rng)
    sens = 1.0 + rng.normal(0.0, 0.1, 3)
    if kind == 0:  # near the condition limit, negative determinant
        m1, m2, m3 = _conditioned(rng, 900.0), _conditioned(rng, 950.0, flip=True), _conditioned(rng, 999.0)
    elif kind == 1:  # entries at +-1e3, sensitivities at the bounds
        m1 = _conditioned(rng, 5.0, scale=999.0)
        sens = np.array([1e3, 1e-30, 0.5])
    elif kind == 2:  # tiny, subnormal and negative-zero entries
        m1 = eye.copy()
        m1[1], m1[3], m1[5] = 1e-40, -0.0, -1e-38
        m2 = eye * 1e-3
        m3 = -eye.copy()
        m3[0] = 1.0
    elif kind == 3:  # permutation-like with signs (reflections)
        m1 = np.array([0, 1, 0, 1, 0, 0, 0, 0, -1], float)
        m2 = np.array([0, 0, -1, 0, 1, 0, 1, 0, 0], float)
    elif kind == 4:  # huge offsets at the limits
        pass
    elif kind == 5:  # identity model, remap only (exact permutation path)
        m1 = m2 = m3 = eye
        sens = np.ones(3)
    elif kind == 6:  # quaternion mounting slightly off unit
        pass
    offs = [rng.normal(0.0, 0.1, 3), rng.normal(0.0, 1.0, 3), rng.normal(0.0, 30.0, 3)]
    if kind == 4:
        offs = [np.array([1e3, -1e3, 0.0]), np.array([1e4, -1e4, 1e-45]), np.array([1e5, -1e5, 0.0])]
    if kind == 5:
        offs = [np.zeros(3)] * 3
    q = unit_quat(rng) * (1.0 + (9e-4 if kind == 6 else 0.0))
    remap = 0 if kind in (0, 6) else int(rng.integers(1, len(REMAP_NAMES) + 1))
    return StageSettings(
        gyro_misalignment=m1,
        gyro_sensitivity=sens,
        gyro_offset=offs[0],
        accel_misalignment=m2,
        accel_sensitivity=np.abs(sens[::-1]),
        accel_offset=offs[1],
        soft_iron=m3,
        hard_iron=offs[2],
        remap=remap,
        mounting=q,
        convention=i % 3,
        accel_outputs=True,
    )


def c_settings(s: StageSettings) -> Any:
    """A cffi ``att_calib_settings_t *`` holding s."""
    cs = ffi.new("att_calib_settings_t *")
    fill_c(cs, s)
    return cs


def c_stages(s: StageSettings) -> Any:
    """A cffi ``att_calib_t *`` from att_calib_init(s) (AssertionError when refused)."""
    c = ffi.new("att_calib_t *")
    assert lib.att_calib_init(c, c_settings(s)) == lib.ATT_OK
    return c


def nasty_inputs(rng: np.random.Generator, n: int, scale: float) -> np.ndarray:
    """(n, 3) float32 samples: mostly ordinary, with NaN, +-Inf, -0, zero rows, huge and tiny values."""
    x = rng.normal(0.0, scale, (n, 3)).astype(np.float32)
    pick = rng.random((n, 3))
    x[pick < 0.01] = np.nan
    x[(pick >= 0.01) & (pick < 0.02)] = np.inf
    x[(pick >= 0.02) & (pick < 0.03)] = -np.inf
    x[(pick >= 0.03) & (pick < 0.04)] = -0.0
    x[(pick >= 0.04) & (pick < 0.05)] = np.float32(3e38)
    x[(pick >= 0.05) & (pick < 0.06)] = np.float32(1e-40)
    x[rng.random(n) < 0.03] = 0.0
    return x

"""The int16 scaling of att_can.h, bit for bit: ties to even, clamping to +-32767, NaN -> -32768 and back."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from attica.can.layout import ACC_FRAC, FRAC_MAX, FRAC_MIN, GYR_FRAC, MAG_FRAC, NA

_MAGIC = np.float32(1.5 * 2.0**23)
_QMAX = np.float32(32767.0)


def quantise(x: ArrayLike, frac_bits: int) -> NDArray[np.int16]:
    """``att_can_quantise`` over an array: round_half_even(x * 2^k) clamped to +-32767, NaN -> -32768."""
    xa = np.asarray(x, np.float32)
    if not FRAC_MIN <= frac_bits <= FRAC_MAX:
        return np.full(xa.shape, NA, np.int16)
    with np.errstate(over="ignore", invalid="ignore"):
        s = xa * np.float32(2.0**frac_bits)
        s = np.minimum(np.maximum(s, -_QMAX), _QMAX)
        nan = np.isnan(s)
        s = np.where(nan, np.float32(0.0), s)
        r = (s + _MAGIC) - _MAGIC
    out: NDArray[np.int16] = np.where(nan, np.int16(NA), r.astype(np.int16)).astype(np.int16)
    return out


FULL = 32767
"""The int16 code of full scale: a value at or beyond the range, clipped by the frame (``ATT_CAN_Q_FULL``)."""
CLIPPED = np.float32(32767.0 * 2.0**112)
"""What a sensor field at full scale decodes to (times its sign): about 1.7e38, beyond every filter's
range, so that a field clipped by the frame is a clipped sensor to the filter (a gyro's starts the
clipping recovery)."""


def dequantise(v: ArrayLike, frac_bits: int) -> NDArray[np.float32]:
    """``att_can_dequantise`` over an array: v * 2^-k (exact), -32768 -> NaN."""
    va = np.asarray(v, np.int16)
    if not FRAC_MIN <= frac_bits <= FRAC_MAX:
        return np.full(va.shape, np.nan, np.float32)
    out: NDArray[np.float32] = np.where(
        va == NA, np.float32(np.nan), va.astype(np.float32) * np.float32(2.0**-frac_bits)
    ).astype(np.float32)
    return out


def dequantise_sensor(v: ArrayLike, frac_bits: int) -> NDArray[np.float32]:
    """A classic IMU frame's field as the node decodes it (``att_can_decode_imu_part``).

    :func:`dequantise`, but full scale (+-:data:`FULL`) -> +-:data:`CLIPPED`.
    """
    va = np.asarray(v, np.int16)
    full = np.abs(va.astype(np.int32)) == FULL
    out: NDArray[np.float32] = np.where(full, np.copysign(CLIPPED, va), dequantise(va, frac_bits)).astype(
        np.float32
    )
    return out


def _rows3(x: ArrayLike | None, n: int) -> NDArray[np.float32]:
    if x is None:
        return np.full((n, 3), np.nan, np.float32)
    a = np.asarray(x, np.float32).reshape(-1, 3)
    if a.shape[0] != n:
        raise ValueError(f"expected {n} rows of 3, got shape {a.shape}")
    return a


def imu_values(
    gyr: ArrayLike, acc: ArrayLike, mag: ArrayLike | None = None
) -> tuple[NDArray[np.float32], ...]:
    """The floats the node receives from classic IMU frames: each value quantised and dequantised."""
    g = np.asarray(gyr, np.float32).reshape(-1, 3)
    n = g.shape[0]
    return (
        dequantise_sensor(quantise(g, GYR_FRAC), GYR_FRAC),
        dequantise_sensor(quantise(_rows3(acc, n), ACC_FRAC), ACC_FRAC),
        dequantise_sensor(quantise(_rows3(mag, n), MAG_FRAC), MAG_FRAC),
    )

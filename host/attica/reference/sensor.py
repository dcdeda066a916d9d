"""Mirror of firmware/src/core/att_sensor.c: sample checks and tilt from gravity."""

from __future__ import annotations

from typing import Any

import numpy as np

from attica.reference import detmath as dm
from attica.settings import Flag

_U0 = np.uint32(0)


def check_gyro(gyr: dm.Vec3, rng: Any) -> Any:
    """att_sensor_check_gyro: flags (uint32)."""
    rng = dm.f32(rng)
    finite = dm.vec3_isfinite(gyr)
    over = (dm.absf(gyr[0]) > rng) | (dm.absf(gyr[1]) > rng) | (dm.absf(gyr[2]) > rng)
    return np.where(~finite, np.uint32(Flag.GYRO_INVALID), np.where(over, np.uint32(Flag.GYRO_RANGE), _U0))


GYRO_RAIL = np.float32(2.0)
"""ATT_GYRO_RAIL (att_core.h): a component within this many times gyro_range is a reading at the rail."""


def gyro_usable(g: dm.Vec3, rng: Any, flags: Any) -> Any:
    """att_i_gyro_usable: whether the sample is integrated (as read), from check_gyro's flags.

    Yes for no flag, and for a GYRO_RANGE sample whose components are all within GYRO_RAIL * range.
    """
    rail = GYRO_RAIL * dm.f32(rng)
    with np.errstate(invalid="ignore"):
        at_rail = (dm.absf(g[0]) <= rail) & (dm.absf(g[1]) <= rail) & (dm.absf(g[2]) <= rail)
    return (flags == _U0) | ((flags == np.uint32(Flag.GYRO_RANGE)) & at_rail)


def check_accel(acc: dm.Vec3, rng: Any) -> tuple[Any, Any]:
    """att_sensor_check_accel: (flags, norm)."""
    rng = dm.f32(rng)
    with np.errstate(all="ignore"):
        finite = dm.vec3_isfinite(acc)
        n2 = dm.vec3_dot(acc, acc)
        small = ~(n2 >= dm.NORM2_MIN)
        n = dm.sqrtf(n2)
        invalid = ~finite | small
        flags = np.where(
            invalid, np.uint32(Flag.ACCEL_INVALID), np.where(n > rng, np.uint32(Flag.ACCEL_RANGE), _U0)
        )
        return flags, np.where(invalid, dm.ZERO, n).astype(np.float32)


def check_accel2(acc: dm.Vec3, rng2: Any) -> tuple[Any, Any]:
    """att_i_sensor_check_accel2: (flags, |a|^2) against the squared range (0 when invalid)."""
    rng2 = dm.f32(rng2)
    with np.errstate(all="ignore"):
        finite = dm.vec3_isfinite(acc)
        n2 = dm.vec3_dot(acc, acc)
        invalid = ~finite | ~(n2 >= dm.NORM2_MIN)
        flags = np.where(
            invalid, np.uint32(Flag.ACCEL_INVALID), np.where(n2 > rng2, np.uint32(Flag.ACCEL_RANGE), _U0)
        )
        return flags, np.where(invalid, dm.ZERO, n2).astype(np.float32)


def tilt(acc: dm.Vec3) -> dm.Vec3:
    """att_sensor_tilt: (phi, theta, 0) from specific force."""
    ax, ay, az = acc
    with np.errstate(all="ignore"):
        phi = dm.atan2f(ay, az)
        theta = dm.atan2f(-ax, dm.sqrtf(ay * ay + az * az))
    return (phi, theta, np.zeros(np.shape(phi), np.float32))


def samples(seconds: Any, dt: Any) -> Any:
    """att_sensor_samples: ceil(seconds / dt) limited to [0, 2^24] (uint32)."""
    with np.errstate(all="ignore"):
        ratio = dm.f32(seconds) / dm.f32(dt)
        pos = ratio > dm.ZERO
        ratio = np.where(ratio > dm.c("0x1p+24"), dm.c("0x1p+24"), ratio)
        ratio = np.where(pos, ratio, dm.ZERO)
        n = np.asarray(ratio).astype(np.uint32)
        n = np.where(n.astype(np.float32) < ratio, n + np.uint32(1), n)
        return np.where(pos, n, _U0).astype(np.uint32)


def check_mag(mag: dm.Vec3, rng: Any) -> tuple[Any, Any]:
    """att_sensor_check_mag: (flags, norm)."""
    mx, my, mz = mag
    rng = dm.f32(rng)
    with np.errstate(all="ignore"):
        absent = (mx != mx) | (my != my) | (mz != mz) | ((mx == dm.ZERO) & (my == dm.ZERO) & (mz == dm.ZERO))
        finite = dm.vec3_isfinite(mag)
        n2 = dm.vec3_dot(mag, mag)
        n = dm.sqrtf(n2)
        bad = ~absent & (~finite | ~(n2 >= dm.NORM2_MIN) | (n > rng))
        flags = np.where(absent, np.uint32(Flag.MAG_ABSENT), np.where(bad, np.uint32(Flag.MAG_INVALID), _U0))
        return flags, np.where(flags == _U0, n, dm.ZERO).astype(np.float32)

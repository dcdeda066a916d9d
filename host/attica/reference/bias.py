"""Mirror of firmware/src/core/att_bias.c: rest detector and capped running-mean gyro bias, in lockstep."""

from __future__ import annotations

from typing import Any

import numpy as np

from attica.reference import detmath as dm
from attica.settings import BiasMode, Flag

_U0 = np.uint32(0)


def bias_params(rest_gyro: Any, rest_accel: Any, gravity: Any) -> tuple[Any, Any, Any]:
    """att_i_bias_params: (rest_gyro^2, (g - rest_accel)^2, (g + rest_accel)^2)."""
    lo = gravity - rest_accel
    hi = gravity + rest_accel
    return rest_gyro * rest_gyro, lo * lo, hi * hi


def bias_step(
    mode: Any,
    n_max: Any,
    rest_n: Any,
    rest_gyro2: Any,
    acc2_lo: Any,
    acc2_hi: Any,
    bias: dm.Vec3,
    n: Any,
    rest_count: Any,
    gyr: dm.Vec3,
    gyro_ok: Any,
    accel_ok: Any,
    acc_norm2: Any,
) -> tuple[dm.Vec3, Any, Any, Any, dm.Vec3]:
    """att_bias_step: returns (bias, n, rest_count, flags, d) for every instance.

    ``mode`` .. ``acc2_hi`` are the att_bias_params_t fields as (n,) arrays; ``bias`` (rad/s), ``n`` and
    ``rest_count`` the owner's state; ``gyr`` the raw gyro sample, ``acc_norm2`` = |a|^2 in (m/s^2)^2;
    ``d`` = gyr - bias with the bias from before the step.
    """
    with np.errstate(all="ignore"):
        d = dm.vec3_sub(gyr, bias)
        rest = (
            gyro_ok
            & accel_ok
            & (dm.vec3_dot(d, d) < rest_gyro2)
            & (acc_norm2 > acc2_lo)
            & (acc_norm2 < acc2_hi)
        )
        rest_count = np.where(
            ~rest, _U0, np.where(rest_count < rest_n, rest_count + np.uint32(1), rest_count)
        ).astype(np.uint32)
        at_rest = rest & (rest_count >= rest_n)
        flags = np.where(at_rest, np.uint32(Flag.AT_REST), _U0)
        update = gyro_ok & ((mode == BiasMode.RUNNING) | ((mode == BiasMode.AT_REST) & at_rest))
        nf = n.astype(np.float32)
        den = nf + dm.ONE
        new_bias = (
            (nf * bias[0] + gyr[0]) / den,
            (nf * bias[1] + gyr[1]) / den,
            (nf * bias[2] + gyr[2]) / den,
        )
        bias = dm.vec3_where(update, new_bias, bias)
        n = np.where(update & (n < n_max), n + np.uint32(1), n).astype(np.uint32)
        flags = flags | np.where(update, np.uint32(Flag.BIAS_UPDATED), _U0)
    return bias, n, rest_count, flags, d


def bias_retune(obj: Any) -> None:
    """att_i_bias_retune on reference filter ``obj`` (new coefficients, old state).

    The bias takes its fixed value for OFF / FROZEN, the counters are limited to the new rest_n and
    bias_n_max.
    """
    fixed = (obj.bias_mode == BiasMode.OFF) | (obj.bias_mode == BiasMode.FROZEN)
    zero = np.zeros(obj.n, np.float32)
    init = dm.vec3_where(obj.bias_mode == BiasMode.OFF, (zero, zero, zero), obj.bias_init)
    obj.bias = dm.vec3_where(fixed, init, obj.bias)
    obj.rest_count = np.minimum(obj.rest_count, obj.rest_n).astype(np.uint32)
    obj.bias_n = np.minimum(obj.bias_n, obj.bias_n_max).astype(np.uint32)

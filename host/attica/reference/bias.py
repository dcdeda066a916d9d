"""Mirror of firmware/src/core/att_bias.c: rest detector and capped running-mean gyro bias, in lockstep."""

from __future__ import annotations

from typing import Any

import numpy as np

from attica.reference import detmath as dm
from attica.settings import BiasMode, Flag

_U0 = np.uint32(0)


UNKNOWN2 = dm.c("0x1.61e4f8p-9")
"""ATT_BIAS_UNKNOWN2: the rest gate's widening before the first rest sample, (rad/s)^2."""


def bias_params(mode: Any, rest_gyro: Any, rest_accel: Any, gravity: Any) -> tuple[Any, Any, Any, Any]:
    """att_i_bias_params: (rest_gyro^2, rest_first2, (g - rest_accel)^2, (g + rest_accel)^2).

    ``rest_first2`` is the gyro gate while no sample has been at rest (n = 0): rest_gyro^2 +
    :data:`UNKNOWN2` in AT_REST mode with rest_gyro^2 > 0, else rest_gyro^2.
    """
    lo = gravity - rest_accel
    hi = gravity + rest_accel
    r2 = rest_gyro * rest_gyro
    widen = (mode == BiasMode.AT_REST) & (r2 > dm.ZERO)
    first2 = np.where(widen, r2 + UNKNOWN2, r2).astype(np.float32)
    return r2, first2, lo * lo, hi * hi


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
    gate2: Any,
    gyr: dm.Vec3,
    gyro_ok: Any,
    accel_ok: Any,
    acc_norm2: Any,
) -> tuple[dm.Vec3, Any, Any, Any, Any, dm.Vec3]:
    """att_i_bias_step: returns (bias, n, rest_count, gate2, flags, d) for every instance.

    ``mode`` .. ``acc2_hi`` are the att_bias_params_t fields as (n,) arrays; ``bias`` (rad/s), ``n``,
    ``rest_count`` and ``gate2`` (the gyro gate, :func:`bias_gate`: ``rest_first2`` until the first
    bias update, then ``rest_gyro2``) the owner's state; ``gyr`` the raw gyro sample, ``acc_norm2`` =
    |a|^2 in (m/s^2)^2; ``d`` = gyr - bias with the bias from before the step.
    """
    with np.errstate(all="ignore"):
        d = dm.vec3_sub(gyr, bias)
        rest = (
            gyro_ok & accel_ok & (dm.vec3_dot(d, d) < gate2) & (acc_norm2 > acc2_lo) & (acc_norm2 < acc2_hi)
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
        gate2 = np.where(update & (n == _U0), rest_gyro2, gate2).astype(np.float32)
        n = np.where(update & (n < n_max), n + np.uint32(1), n).astype(np.uint32)
        flags = flags | np.where(update, np.uint32(Flag.BIAS_UPDATED), _U0)
    return bias, n, rest_count, gate2, flags, d


def bias_gate(rest_gyro2: Any, rest_first2: Any, n: Any) -> Any:
    """att_i_bias_gate: the gyro gate of a running mean of ``n`` samples (``rest_first2`` while 0)."""
    return np.where(n == _U0, rest_first2, rest_gyro2).astype(np.float32)


def bias_retune(obj: Any) -> None:
    """att_i_bias_retune on reference filter ``obj`` (new coefficients, old state).

    The bias takes its fixed value for OFF / FROZEN, the counters are limited to the new rest_n and
    bias_n_max, the gate follows the new parameters.
    """
    fixed = (obj.bias_mode == BiasMode.OFF) | (obj.bias_mode == BiasMode.FROZEN)
    zero = np.zeros(obj.n, np.float32)
    init = dm.vec3_where(obj.bias_mode == BiasMode.OFF, (zero, zero, zero), obj.bias_init)
    obj.bias = dm.vec3_where(fixed, init, obj.bias)
    obj.rest_count = np.minimum(obj.rest_count, obj.rest_n).astype(np.uint32)
    obj.bias_n = np.minimum(obj.bias_n, obj.bias_n_max).astype(np.uint32)
    obj.rest_gate2 = bias_gate(obj.rest_gyro2, obj.rest_first2, obj.bias_n)

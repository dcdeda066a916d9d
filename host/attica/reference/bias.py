"""Mirror of firmware/src/att_bias.c: rest detector and capped running-mean gyro bias, in lockstep."""

from __future__ import annotations

from typing import Any

import numpy as np

from attica.reference import detmath as dm
from attica.settings import BiasMode, Flag

_U0 = np.uint32(0)


def bias_step(
    mode: Any,
    n_max: Any,
    rest_n: Any,
    rest_gyro: Any,
    rest_accel: Any,
    gravity: Any,
    bias: dm.Vec3,
    n: Any,
    rest_count: Any,
    gyr: dm.Vec3,
    gyro_ok: Any,
    accel_ok: Any,
    norm: Any,
) -> tuple[dm.Vec3, Any, Any, Any]:
    """att_bias_step: returns (bias, n, rest_count, flags) for every instance.

    ``mode`` .. ``gravity`` are the att_bias_params_t fields as (n,) arrays; ``bias`` (rad/s), ``n`` and
    ``rest_count`` the owner's state; ``gyr`` the raw gyro sample, ``norm`` = |a| in m/s^2.
    """
    with np.errstate(all="ignore"):
        rest = (
            gyro_ok
            & accel_ok
            & (dm.vec3_norm(dm.vec3_sub(gyr, bias)) < rest_gyro)
            & (dm.absf(norm - gravity) < rest_accel)
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
    return bias, n, rest_count, flags

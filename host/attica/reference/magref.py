"""Mirror of the learnt reference field (firmware att_magref.h, att_core.h's att_i_magref_*), in lockstep.

Shared by :mod:`attica.reference.mars` and :mod:`attica.reference.mekf`: the functions work on the owner
``f``, which holds the coefficients (``k_ref``, ``cand_tol_n``, ``cand_tol_s``, ``blk_n``, ``new_n``,
``ref_on``: C's ``c.ref``) and the statistics (``acc_norm`` .. ``cand_n``: C's ``st.ref``) as attributes
of its own, one array element per instance. Every C branch an ``np.where``, every operation the C one in
the same order.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from attica.reference import detmath as dm
from attica.reference import sensor

_U0 = np.uint32(0)
_U1 = np.uint32(1)

BLOCK_S = dm.ONE  # ATT_MAGREF_BLOCK_S, s
M0_MIN = dm.c("0x1.0624dep-10")  # ATT_MAGREF_M0_MIN, uT

STATE_FIELDS: tuple[tuple[str, str], ...] = (
    ("acc_norm", "f32"),
    ("acc_z", "f32"),
    ("rej_norm", "f32"),
    ("rej_z", "f32"),
    ("cand_norm", "f32"),
    ("cand_sin", "f32"),
    ("blk", "u32"),
    ("acc_n", "u32"),
    ("rej_n", "u32"),
    ("cand_n", "u32"),
)
"""The fields of att_magref_t, in C's order, with their layouts (reference._common.StateSpec)."""

COEFF_FIELDS: tuple[tuple[str, str], ...] = (
    ("k_ref", "f32"),
    ("cand_tol_n", "f32"),
    ("cand_tol_s", "f32"),
    ("blk_n", "u32"),
    ("new_n", "u32"),
    ("ref_on", "bool"),
)
"""The fields of att_magref_params_t, in C's order."""


def params(f: Any, dt: Any, ref_tau: Any, new_time: Any, norm_reject: Any, dip_reject: Any) -> Any:
    """att_i_magref_params: the coefficients into ``f`` (per-instance arrays; s, rad).

    Returns the block length in s (blk_n dt).
    """
    blk_n = sensor.samples(BLOCK_S, dt)
    f.blk_n = np.where(blk_n > _U0, blk_n, _U1).astype(np.uint32)
    t = f.blk_n.astype(np.float32) * dt
    f.ref_on = ref_tau > dm.ZERO
    with np.errstate(all="ignore"):
        f.k_ref = np.where(f.ref_on, t / (ref_tau + t), dm.ZERO).astype(np.float32)
        f.new_n = sensor.samples(new_time, t)
        f.cand_tol_n = np.where(norm_reject > dm.ZERO, dm.HALF * norm_reject, dm.INF).astype(np.float32)
        f.cand_tol_s = np.where(dip_reject > dm.ZERO, dm.HALF * dip_reject, dm.INF).astype(np.float32)
    return t


def clear(f: Any, cond: Any) -> None:
    """att_i_magref_clear where ``cond``: a new block."""
    for name in ("acc_norm", "acc_z", "rej_norm", "rej_z"):
        setattr(f, name, np.where(cond, dm.ZERO, getattr(f, name)).astype(np.float32))
    for name in ("blk", "acc_n", "rej_n"):
        setattr(f, name, np.where(cond, _U0, getattr(f, name)).astype(np.uint32))


def reset(f: Any, n: int) -> None:
    """att_i_magref_reset: no candidate, an empty block (every instance)."""
    for name, layout in STATE_FIELDS:
        setattr(f, name, np.zeros(n, np.float32 if layout == "f32" else np.uint32))


def count(f: Any, cond: Any, accepted: Any, gated: Any, mnorm: Any, mz: Any) -> Any:
    """att_i_magref_count where ``cond``: the sample's use, the block; returns where a block ends."""
    f32 = np.float32
    acc = cond & accepted
    rej = cond & gated
    f.acc_norm = np.where(acc, f.acc_norm + mnorm, f.acc_norm).astype(f32)
    f.acc_z = np.where(acc, f.acc_z + mz, f.acc_z).astype(f32)
    f.acc_n = np.where(acc, f.acc_n + _U1, f.acc_n).astype(np.uint32)
    f.rej_norm = np.where(rej, f.rej_norm + mnorm, f.rej_norm).astype(f32)
    f.rej_z = np.where(rej, f.rej_z + mz, f.rej_z).astype(f32)
    f.rej_n = np.where(rej, f.rej_n + _U1, f.rej_n).astype(np.uint32)
    f.blk = np.where(cond, f.blk + _U1, f.blk).astype(np.uint32)
    return cond & (f.blk >= f.blk_n)


def block(f: Any, end: Any, m0: dm.Vec3) -> tuple[Any, Any, Any, Any]:
    """att_i_magref_block where ``end``: (follow, adopt, norm, sin(dip)) of the new reference; a new block."""
    f32 = np.float32
    with np.errstate(all="ignore"):
        most = f.acc_n > f.rej_n
        # the reference follows the accepted samples
        follow = end & most & f.ref_on & (f.acc_norm > dm.ZERO)
        n0 = dm.vec3_norm(m0)
        s0 = m0[2] / n0
        nb = f.acc_norm / f.acc_n.astype(f32)
        sb = f.acc_z / f.acc_norm
        n_a = n0 + f.k_ref * (nb - n0)
        s_a = s0 + f.k_ref * (sb - s0)
        # or the rejected ones form a candidate
        cand = end & ~most & (f.rej_n > _U0) & (f.new_n > _U0) & (f.rej_norm > dm.ZERO)
        nr = f.rej_norm / f.rej_n.astype(f32)
        sr = f.rej_z / f.rej_norm
        steady = (
            (f.cand_n > _U0)
            & (dm.absf(nr - f.cand_norm) <= f.cand_tol_n * f.cand_norm)
            & (dm.absf(sr - f.cand_sin) <= f.cand_tol_s)
        )
        w = dm.ONE / (f.cand_n + _U1).astype(f32)
        cn = np.where(steady, f.cand_norm + (nr - f.cand_norm) * w, nr).astype(f32)
        cs = np.where(steady, f.cand_sin + (sr - f.cand_sin) * w, sr).astype(f32)
        ck = np.where(steady, f.cand_n + _U1, _U1).astype(np.uint32)
        adopt = cand & (ck >= f.new_n)
    f.cand_norm = np.where(cand, cn, f.cand_norm).astype(f32)
    f.cand_sin = np.where(cand, cs, f.cand_sin).astype(f32)
    f.cand_n = np.where(end & most, _U0, np.where(cand, np.where(adopt, _U0, ck), f.cand_n)).astype(np.uint32)
    clear(f, end)
    return follow, adopt, np.where(adopt, cn, n_a).astype(f32), np.where(adopt, cs, s_a).astype(f32)


def m0_from(m0: dm.Vec3, n: Any, s: Any, decl_sin: Any, decl_cos: Any) -> dm.Vec3:
    """att_i_magref_m0: norm ``n``, sin(dip) ``s``, the horizontal direction of ``m0`` (else D's azimuth)."""
    with np.errstate(all="ignore"):
        s2 = s * s
        h = np.where(s2 < dm.ONE, n * dm.sqrtf(dm.ONE - s2), dm.ZERO)
        mx, my, _ = m0
        h0 = dm.sqrtf(mx * mx + my * my)
        r = h / h0
        big = h0 >= M0_MIN
        return (np.where(big, mx * r, h * decl_sin), np.where(big, my * r, h * decl_cos), n * s)


def state_spec(prefix: str) -> dict[str, str]:
    """StateSpec entries of the statistics under the C path ``prefix`` (e.g. ``st.ref``)."""
    return {f"{prefix}.{name}": layout for name, layout in STATE_FIELDS}


def coeff_spec(prefix: str) -> dict[str, str]:
    """StateSpec entries of the coefficients under the C path ``prefix`` (e.g. ``c.ref``)."""
    return {f"{prefix}.{name}": layout for name, layout in COEFF_FIELDS}

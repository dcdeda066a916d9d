"""Helpers shared by the reference filters: settings as float32 arrays, batch input handling."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.reference import detmath as dm
from attica.reference import sensor


def setting(value: Any, n: int, dtype: Any = np.float32) -> NDArray[Any]:
    """A settings value (scalar or per-instance sequence) as an array of shape (n,)."""
    arr = np.asarray(value, dtype=dtype)
    return np.broadcast_to(arr, (n,)).copy()


def split3(x: Any, n: int) -> dm.Vec3:
    """(n,3) or (3,) float data to a Vec3 of (n,) float32 arrays."""
    a = np.asarray(x, dtype=np.float32)
    a = np.broadcast_to(a, (n, 3))
    return (a[:, 0].copy(), a[:, 1].copy(), a[:, 2].copy())


def stack(parts: tuple[Any, ...]) -> NDArray[np.float32]:
    """Components of shape (n,) to an array of shape (n, len(parts))."""
    return np.stack([np.asarray(p, dtype=np.float32) for p in parts], axis=-1)


def as_batch(x: Any, width: int) -> tuple[NDArray[np.float32], bool]:
    """Batch input of shape (N, width) or (N, M, width) as (N, M, width) plus whether M was given."""
    a = np.asarray(x, dtype=np.float32)
    if a.ndim == 2 and a.shape[1] == width:
        return a[:, None, :], False
    if a.ndim == 3 and a.shape[2] == width:
        return a, True
    raise ValueError(f"expected shape (N, {width}) or (N, M, {width}), got {a.shape}")


def run_steps(obj: Any, *inputs: Any) -> tuple[NDArray[np.float32], NDArray[np.uint32]]:
    """Step reference filter ``obj`` through N samples of each input ((N, 3) or (N, n, 3)).

    Calls ``obj.step(*rows)`` per sample and records ``obj.quat``. Returns quats (N, 4) and flags (N,)
    when the inputs were 2-D (``obj.n`` must be 1 then, or every instance gets the same input and
    instance 0 is returned), else (N, n, 4) and (N, n).
    """
    batches = [as_batch(x, 3) for x in inputs]
    multi = batches[0][1]
    count = batches[0][0].shape[0]
    if any(b.shape[0] != count for b, _ in batches):
        raise ValueError("every input must have the same number of samples")
    quats = np.empty((count, obj.n, 4), np.float32)
    flags = np.empty((count, obj.n), np.uint32)
    for i in range(count):
        flags[i] = obj.step(*(b[i] for b, _ in batches))
        quats[i] = obj.quat
    if multi:
        return quats, flags
    return quats[:, 0, :], flags[:, 0]


StateSpec = dict[str, str]
"""C state field path -> layout; the reference attribute is the last part of the path.

A path is a member name of the kind's C struct, dotted for nested members (``"st.q"`` is ``f.st.q``
in C and ``self.q`` in the reference). Layouts: ``quat`` (w,x,y,z tuple of (n,) float32), ``vec3``
(x,y,z tuple), ``f32``, ``u32``, ``bool``,
``f32xN`` (tuple of N (n,) float32 arrays from a C ``float[N]`` or ``float[a][b]`` field). A layout
may name the reference attribute after a colon when it differs from the path's last part
(``"c.bias.mode": "u32:bias_mode"``).
"""

_QUAT_KEYS = ("w", "x", "y", "z")
_VEC_KEYS = ("x", "y", "z")


def _c_values(layout: str, value: Any) -> list[Any]:
    layout = layout.partition(":")[0]
    if layout == "quat":
        return [getattr(value, k) for k in _QUAT_KEYS]
    if layout == "vec3":
        return [getattr(value, k) for k in _VEC_KEYS]
    if layout.startswith("f32x"):
        count = int(layout[4:])
        flat: list[Any] = []

        def walk(v: Any) -> None:
            try:
                for item in v:
                    walk(item)
            except TypeError:
                flat.append(v)

        walk(value)
        if len(flat) != count:
            raise ValueError(f"layout {layout}: C field has {len(flat)} values")
        return flat
    return [value]


def _arrays(value: Any) -> list[Any]:
    """The (n,) arrays of a reference state attribute, flattening tuples and nested lists."""
    if isinstance(value, (tuple, list)):
        out: list[Any] = []
        for item in value:
            out.extend(_arrays(item))
        return out
    return [value]


def _c_field(c_state: Any, path: str) -> Any:
    for part in path.split("."):
        c_state = getattr(c_state, part)
    return c_state


def _ref_name(path: str, layout: str = "") -> str:
    alias = layout.partition(":")[2]
    return alias or path.rsplit(".", 1)[-1]


def load_c_state(obj: Any, spec: StateSpec, i: int, c_state: Any) -> None:
    """Set instance ``i`` of reference object ``obj`` from a cffi C state struct."""
    for name, layout in spec.items():
        vals = _c_values(layout, _c_field(c_state, name))
        arrays = _arrays(getattr(obj, _ref_name(name, layout)))
        if len(arrays) != len(vals):
            raise ValueError(f"state field {name}: {len(arrays)} reference arrays, {len(vals)} C values")
        for arr, v in zip(arrays, vals):
            arr[i] = v


def state_values(obj: Any, spec: StateSpec, i: int) -> list[Any]:
    """Instance ``i``'s state as a flat list (numpy scalars), in spec order."""
    out: list[Any] = []
    for name, layout in spec.items():
        out.extend(a[i] for a in _arrays(getattr(obj, _ref_name(name, layout))))
    return out


def c_state_values(spec: StateSpec, c_state: Any) -> list[Any]:
    """A C state struct as a flat list in the same order as :func:`state_values`."""
    out: list[Any] = []
    for name, layout in spec.items():
        out.extend(_c_values(layout, _c_field(c_state, name)))
    return out


def _deep_copy(value: Any) -> Any:
    if isinstance(value, tuple):
        return tuple(_deep_copy(v) for v in value)
    if isinstance(value, list):
        return [_deep_copy(v) for v in value]
    return np.copy(value)


def carry_state(old: Any, new: Any) -> None:
    """Copy the state attributes (``old.STATE``) of reference filter ``old`` into ``new`` (a retune)."""
    for path, layout in old.STATE.items():
        name = _ref_name(path, layout)
        setattr(new, name, _deep_copy(getattr(old, name)))


# the recovery after a clipping gyro (att_core.h: att_i_recovery_params, att_i_recovery_step)
REC_CLIP = dm.c("0x1.f5c29p-1")  # ATT_REC_CLIP_F, 0.98
REC_TAU = dm.c("0x1p-3")  # ATT_REC_TAU, 1/8


def recovery_params(
    recovery_time: Any, gyro_range: Any, dt: Any
) -> tuple[NDArray[np.uint32], NDArray[np.float32], NDArray[np.float32]]:
    r"""att_i_recovery_params: the recovery's samples, clipping threshold (rad/s; Inf: none) and gain.

    Returns
    -------
    rec_n, clip, k
        Samples of a recovery (0: none), the \|w_i\| at and above which a gyro sample clips, and
        dt / (recovery_time / 8 + dt).

    """
    tau = recovery_time * REC_TAU
    with np.errstate(all="ignore"):
        k = dt / (tau + dt)
    rec_n = sensor.samples(recovery_time, dt)
    clip = np.where(rec_n > np.uint32(0), REC_CLIP * gyro_range, dm.INF).astype(np.float32)
    return rec_n, clip, np.asarray(k, np.float32)


def recovery_q(k: Any, r: Any, cap: Any) -> NDArray[np.float32]:
    """att_i_recovery_q: the process noise whose steady-state Kalman gain is k (noise r), at most cap."""
    with np.errstate(all="ignore"):
        q = ((k * k) / (dm.ONE - k)) * r
    out: NDArray[np.float32] = np.where(q < cap, q, cap).astype(np.float32)
    return out


# the covariance model of the complementary filters (att_core.h: att_i_cov_first, att_i_cov_tilt)
COV_UNKNOWN = dm.c("0x1.a51a66p+1")  # ATT_COV_UNKNOWN, pi^2 / 3
COV_TILT_MAX = dm.c("0x1.a51a66p-1")  # ATT_COV_TILT_MAX, pi^2 / 12
COV_CLIP = dm.c("0x1.a51a66p-3")  # ATT_COV_CLIP, pi^2 / 48
_F4 = np.float32(4.0)
_F5 = np.float32(5.0)
_F12 = np.float32(12.0)
_F14 = np.float32(14.0)
COV_TC_MAX = np.float32(1000000.0)  # ATT_COV_TC_MAX, s


def cov_first(dt: Any, k: Any, s2: Any, a2: Any) -> NDArray[np.float32]:
    """att_i_cov_first: the steady-state variance of a first-order correction of per-sample gain k."""
    with np.errstate(all="ignore"):
        k1 = dm.ONE - k
        out = (k1 * k1 * (s2 * dt) + k * k * (a2 / dt)) / (k * (dm.TWO - k))
    return np.asarray(out, np.float32)


def cov_tilt(dt: Any, k_lp: Any, k: Any, s2: Any, a2: Any) -> NDArray[np.float32]:
    """att_i_cov_tilt: the steady-state tilt variance of the low-pass stages and the correction."""
    with np.errstate(all="ignore"):
        tl = dt * (dm.ONE - k_lp) / k_lp
        tc = dt * (dm.ONE - k) / k
        tc = np.where(k < dm.ONE, np.where(tc < COV_TC_MAX, tc, COV_TC_MAX), dm.ZERO).astype(np.float32)
        t = tc + tl
        g = ((dm.TWO * tc + _F12 * tl) * tc + _F14 * (tl * tl)) * tc + _F5 * ((tl * tl) * tl)
        lp = (a2 * (dm.TWO * tc + tl) + s2 * g) / (_F4 * (t * t))
    lp_on = (k_lp > dm.ZERO) & (k_lp < dm.ONE)
    out: NDArray[np.float32] = np.where(lp_on, lp, cov_first(dt, k, s2, a2)).astype(np.float32)
    return out


def cov_grow(v: Any, s2dt: Any, steps: Any, stamp: Any, cap: Any) -> NDArray[np.float32]:
    """att_i_cov_grow: v grown by s2dt per step after the stamped one (steps - stamp - 1, uint32), capped."""
    d = (np.asarray(steps, np.uint32) - np.asarray(stamp, np.uint32)).astype(np.uint32)
    n = np.where(d > np.uint32(0), d - np.uint32(1), np.uint32(0)).astype(np.uint32)
    with np.errstate(all="ignore"):
        g = v + s2dt * n.astype(np.float32)
    out: NDArray[np.float32] = np.where(g < cap, g, cap).astype(np.float32)
    return out


def cov_tilt_now(f: Any, var_tilt_rec: Any) -> NDArray[np.float32]:
    """att_i_cov_tilt_now for ars's and mars's reference ``f`` (its coefficients and state), rad^2."""
    with np.errstate(all="ignore"):
        rec = var_tilt_rec + COV_CLIP * (f.rec_left.astype(np.float32) / f.rec_n.astype(np.float32))
    tilt = np.where(f.rec_left > np.uint32(0), rec, f.var_tilt).astype(np.float32)
    tilt = cov_grow(tilt, f.var_step, f.steps, f.acc_step, COV_TILT_MAX)
    out: NDArray[np.float32] = np.where(f.initialised, tilt, COV_TILT_MAX).astype(np.float32)
    return out


def recovery_step(
    g: dm.Vec3, clip: Any, rec_n: Any, left: Any, run: Any, lp_n: Any
) -> tuple[NDArray[np.uint32], NDArray[np.bool_], NDArray[np.uint32]]:
    """att_i_recovery_step where run: the counter restarted by a clipping gyro sample, else counted down.

    Returns
    -------
    left, ended, lp_n
        The new counter (unchanged where not run), where this step ended a recovery, and the low-pass
        count (0 where a clipping sample was run, else unchanged).

    """
    ag = (dm.absf(g[0]), dm.absf(g[1]), dm.absf(g[2]))
    clipped = (ag[0] >= clip) | (ag[1] >= clip)
    clipped = clipped | (ag[2] >= clip)
    nxt = np.where(left > np.uint32(0), left - np.uint32(1), left)
    nxt = np.where(clipped, rec_n, nxt)
    ended = run & ~clipped & (left == np.uint32(1))
    lp_n_new = np.where(run & clipped, np.uint32(0), lp_n).astype(np.uint32)
    return np.where(run, nxt, left).astype(np.uint32), ended, lp_n_new


def recovery_start(
    start: Any, rec_n: Any, left: Any, lp_n: Any
) -> tuple[NDArray[np.uint32], NDArray[np.uint32]]:
    """att_i_recovery_start where ``start``: the recovery counter at rec_n, the stages' count at 1."""
    return (
        np.where(start, rec_n, left).astype(np.uint32),
        np.where(start, np.uint32(1), lp_n).astype(np.uint32),
    )


REC_MEAN_END = np.float32(0.25)
"""ATT_I_REC_MEAN_END: a recovery's running mean ends at this fraction of the cascade's gain (n = 4 / k)."""


def recovery_lp_gain(
    n: Any, k_lp: Any, k_end: Any
) -> tuple[NDArray[np.float32], NDArray[np.uint32], NDArray[np.float32]]:
    """att_i_recovery_lp_gain: the low-pass gains of a running mean's update and the count after it.

    1 / (n + 1) after n earlier updates since the last clipping sample or the start (n: rec_lp_n; 1
    after the start, whose sample the stages start from) while that is at least ``k_end`` (the mean's
    end, REC_MEAN_END k_lp for the cascades), then k_lp (the stages' own gain, or the mekf start's fast
    window); the caller commits the count n + 1 where the C calls the helper. The third value is the
    second stage's gain (the C's *k2): 1 while the mean runs, k_lp after it.
    """
    n1 = (np.asarray(n, np.uint32) + np.uint32(1)).astype(np.uint32)
    m = (dm.ONE / n1.astype(np.float32)).astype(np.float32)
    below = m < k_end
    k2 = np.where(below, k_lp, dm.ONE).astype(np.float32)
    return np.where(below, k_lp, m).astype(np.float32), n1, k2


def recovery_lp_gain2(
    n: Any, k_lp: Any
) -> tuple[NDArray[np.float32], NDArray[np.uint32], NDArray[np.float32]]:
    """att_i_recovery_lp_gain2: :func:`recovery_lp_gain` for two cascaded first-order stages.

    The mean's end is REC_MEAN_END k_lp.
    """
    return recovery_lp_gain(n, k_lp, (REC_MEAN_END * np.asarray(k_lp, np.float32)).astype(np.float32))


def p6(i: int, j: int) -> int:
    """ATT_I_P6: index of P_ij in a symmetric 6x6 matrix packed as its upper triangle, row by row."""
    lo, hi = min(i, j), max(i, j)
    return lo * (11 - lo) // 2 + hi


def pd6(p: Sequence[Any], margin: Any) -> Any:
    """att_i_pd6: L D L^T pivots d_0 > 0, d_j > margin (P_jj + sum_{i<j} m_ji^2 P_ii), m = L^-1.

    ``p`` is the packed upper triangle (21 arrays). The C loop stops at the first failure; here the test
    of each pivot is accumulated, which gives the same answer.
    """
    with np.errstate(all="ignore"):
        ok = np.ones(np.shape(p[0]), np.bool_)
        lo: dict[tuple[int, int], Any] = {}
        mi: dict[tuple[int, int], Any] = {}
        d: list[Any] = []
        for j in range(6):
            dj = p[p6(j, j)]
            sj = dj
            for k in range(j):
                dj = dj - (lo[(j, k)] * lo[(j, k)]) * d[k]
            # row j of L^-1 (unit diagonal), i from j - 1 down
            for i in range(j - 1, -1, -1):
                v = lo[(j, i)]
                for k in range(i + 1, j):
                    v = v + lo[(j, k)] * mi[(k, i)]
                mi[(j, i)] = -v
                sj = sj + (mi[(j, i)] * mi[(j, i)]) * p[p6(i, i)]
            limit = dm.ZERO if j == 0 else margin * sj
            ok = ok & (dj > limit)
            d.append(dj)
            for i in range(j + 1, 6):
                v = p[p6(j, i)]
                for k in range(j):
                    v = v - (lo[(i, k)] * lo[(j, k)]) * d[k]
                lo[(i, j)] = v / dj
    return ok

"""Quaternion helpers of the simulator (float64; not part of the bit-exact contract)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from attica.metrics import quat_mul

F64 = NDArray[np.float64]
"""float64 arrays (the simulator works in float64; only its float32 outputs meet the firmware)."""


def quat_exp(rotvec: ArrayLike) -> F64:
    """Exponential map: rotation vector ``theta`` to ``(cos(|theta|/2), sin(|theta|/2) theta/|theta|)``.

    Parameters
    ----------
    rotvec : array_like, shape (..., 3)
        Rotation vectors in rad.

    Returns
    -------
    ndarray, float64, shape (..., 4)
        Quaternions ``w, x, y, z``.

    """
    v = np.asarray(rotvec, dtype=np.float64)
    angle = np.sqrt(np.sum(v * v, axis=-1))
    half = 0.5 * angle
    # sin(half) / angle without 0/0: 0.5 * sinc(half / pi) (numpy's sinc is sin(pi x) / (pi x))
    k = 0.5 * np.sinc(half / np.pi)
    return np.concatenate([np.cos(half)[..., None], v * k[..., None]], axis=-1)


def quat_rotate(q: ArrayLike, v: ArrayLike) -> F64:
    """Rotate vectors by quaternions: ``q * v * conj(q)`` (sensor to earth for a sensor-to-earth ``q``).

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Unit quaternions ``w, x, y, z``.
    v : array_like, shape (..., 3)
        Vectors.

    Returns
    -------
    ndarray, float64, shape (..., 3)
        Rotated vectors.

    """
    qa = np.asarray(q, dtype=np.float64)
    va = np.asarray(v, dtype=np.float64)
    u = qa[..., 1:]
    t = 2.0 * _cross(u, va)
    out: F64 = va + qa[..., :1] * t + _cross(u, t)
    return out


def quat_rotate_inv(q: ArrayLike, v: ArrayLike) -> F64:
    """Rotate vectors by the inverse of unit quaternions: ``conj(q) * v * q`` (earth to sensor).

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Unit quaternions ``w, x, y, z``.
    v : array_like, shape (..., 3)
        Vectors.

    Returns
    -------
    ndarray, float64, shape (..., 3)
        Rotated vectors.

    """
    qa = np.asarray(q, dtype=np.float64) * np.array([1.0, -1.0, -1.0, -1.0])
    return quat_rotate(qa, v)


def _scan_quat(q: F64) -> F64:
    """Inclusive prefix product ``q[0] * q[1] * ... * q[i]`` along axis 0 (Hillis-Steele, log2 n passes)."""
    out = q.copy()
    shift = 1
    n = out.shape[0]
    while shift < n:
        nxt = out.copy()
        nxt[shift:] = quat_mul(out[:-shift], out[shift:])
        out = nxt
        shift *= 2
    return out


def _cross(a: F64, b: F64) -> F64:
    out = np.empty(np.broadcast_shapes(a.shape, b.shape), np.float64)
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out

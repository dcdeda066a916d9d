"""Helpers shared by the reference filters: settings as float32 arrays, batch input handling."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.reference import detmath as dm


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

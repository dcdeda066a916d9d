"""How much of the sphere a set of directions visits: equal-area cells from a Fibonacci lattice.

The sphere is cut into ``CELLS`` cells, the Voronoi cells of a Fibonacci lattice (points spaced by the
golden angle in longitude, evenly in ``z``): they have equal area to within a few percent and compact
shapes, unlike latitude-longitude bins. A direction belongs to the cell of its nearest lattice point;
the *coverage* is the fraction of cells holding at least ``min_count`` directions (a lone glitch does not
count). With ``CELLS = 100`` one cell is a cap of about 23 deg across; a flat turn on a table (a
circle) visits about 20 % of the cells, a hemisphere about 60 % (the cells along its edge count).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["CELLS", "cell_centres", "cell_counts", "coverage"]

CELLS = 100
"""Number of equal-area cells."""

_CHUNK = 8192


def cell_centres(cells: int = CELLS) -> NDArray[np.float64]:
    """The Fibonacci lattice of ``cells`` unit vectors, shape (cells, 3)."""
    i = np.arange(cells, dtype=np.float64) + 0.5
    z = 1.0 - 2.0 * i / cells
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    lon = np.pi * (3.0 - np.sqrt(5.0)) * i
    return np.stack([r * np.cos(lon), r * np.sin(lon), z], axis=1)


def cell_counts(directions: NDArray[np.floating[Any]], cells: int = CELLS) -> NDArray[np.int64]:
    """Samples per cell, shape (cells,); rows that are zero or not finite are left out.

    Parameters
    ----------
    directions : ndarray, shape (N, 3)
        Vectors (any length; only the direction counts).
    cells : int
        Number of cells.

    """
    d = np.asarray(directions, np.float64)
    if d.ndim != 2 or d.shape[1] != 3:
        raise ValueError(f"directions must have shape (N, 3), got {d.shape}")
    norm = np.linalg.norm(d, axis=1)
    ok = np.isfinite(norm) & (norm > 0.0)
    u = d[ok] / norm[ok, None]
    centres = cell_centres(cells)
    counts = np.zeros(cells, np.int64)
    for start in range(0, u.shape[0], _CHUNK):
        nearest = np.argmax(u[start : start + _CHUNK] @ centres.T, axis=1)
        counts += np.bincount(nearest, minlength=cells)
    return counts


def coverage(directions: NDArray[np.floating[Any]], min_count: int = 3, cells: int = CELLS) -> float:
    """Fraction of the sphere's equal-area cells holding at least ``min_count`` of the directions.

    Parameters
    ----------
    directions : ndarray, shape (N, 3)
        Vectors from the centre of the sphere (e.g. calibrated magnetometer samples).
    min_count : int
        Samples a cell needs to count as visited.
    cells : int
        Number of cells.

    Returns
    -------
    float
        In [0, 1].

    """
    return float(np.mean(cell_counts(directions, cells) >= max(1, min_count)))

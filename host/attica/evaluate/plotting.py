"""What the evaluation's figures share: matplotlib (Agg), size, colours, the axis-scale rule, legends."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "DPI",
    "LOG_DECADES",
    "WIDTH_PX",
    "colour",
    "curve_levels",
    "legend_right",
    "pyplot",
    "save",
    "set_scale",
    "wants_log",
]

WIDTH_PX = 1600
DPI = 100
LOG_DECADES = 2.0
"""An axis is logarithmic only when its values are positive and span more than this many decades."""


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the Agg backend; RuntimeError naming the extra when missing."""
    try:
        import matplotlib
    except ImportError:
        raise RuntimeError("plots need matplotlib: pip install '.[eval]' (or use --no-plots)") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def colour(i: int) -> Any:
    """The colour of the ``i``-th method of a figure (the same in every panel)."""
    from matplotlib.colors import ListedColormap

    cmap = pyplot().get_cmap("tab10")
    assert isinstance(cmap, ListedColormap)
    colours: Any = cmap.colors
    return colours[i % 10]


def wants_log(low: Iterable[float], high: Iterable[float]) -> bool:
    """Whether values from ``low`` to ``high`` call for a log axis (see :data:`LOG_DECADES`).

    ``low`` are the smallest typical values (a curve's median, a bar's height), ``high`` the largest
    (a curve's 99.5th percentile). Any value not positive and finite keeps the axis linear.
    """
    lo = np.array(list(low), np.float64)
    hi = np.array(list(high), np.float64)
    if lo.size == 0 or hi.size == 0 or not (np.all(np.isfinite(lo)) and np.all(lo > 0.0)):
        return False
    return bool(np.nanmax(hi) / lo.min() > 10.0**LOG_DECADES)


def curve_levels(values: NDArray[Any]) -> tuple[float, float] | None:
    """(median, 99.5th percentile) of a curve's finite values; None when it has none."""
    v = np.asarray(values, np.float64)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return None
    return float(np.median(v)), float(np.percentile(v, 99.5))


def set_scale(ax: Any, low: Iterable[float], high: Iterable[float]) -> str:
    """Log y axis when :func:`wants_log`, else linear from 0; returns the scale set."""
    if wants_log(low, high):
        ax.set_yscale("log")
        return "log"
    ax.set_ylim(bottom=0)
    return "linear"


def legend_right(ax: Any) -> None:
    """The axes' legend right of its data."""
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.005, 1.0), borderaxespad=0.0)


def save(fig: Any, path: Path) -> None:
    """Write and close a figure (nothing when None)."""
    if fig is None:
        return
    try:
        fig.savefig(path)
    finally:
        pyplot().close(fig)

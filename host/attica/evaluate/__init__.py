"""Accuracy on recorded data with the BROAD metrics (``attica eval``).

- :mod:`attica.evaluate.core`: methods (attica's C filters, the peers), scores per trial and group,
  the grid search of the defaults;
- :mod:`attica.evaluate.tables`: text tables that fit 110 columns (6-axis and 9-axis apart);
- :mod:`attica.evaluate.plots`: PNG plots (1600 px, 6-axis and 9-axis charts apart).
"""

from __future__ import annotations

from attica.evaluate.core import (
    DATA_SUFFIXES,
    GRIDS,
    GROUP_ORDER,
    METRICS,
    NINE_AXIS,
    VARIANT_GRIDS,
    VARIANTS,
    Method,
    MethodResult,
    Report,
    TrialScore,
    attica_method,
    grid_search,
    load_trials,
    peer_methods,
    run_methods,
)
from attica.evaluate.tables import format_summary, format_tables

__all__ = [
    "DATA_SUFFIXES",
    "GRIDS",
    "GROUP_ORDER",
    "METRICS",
    "NINE_AXIS",
    "Method",
    "MethodResult",
    "Report",
    "TrialScore",
    "VARIANTS",
    "VARIANT_GRIDS",
    "attica_method",
    "format_summary",
    "format_tables",
    "grid_search",
    "load_trials",
    "peer_methods",
    "run_methods",
]

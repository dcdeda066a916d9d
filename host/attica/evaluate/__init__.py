"""Accuracy on recorded data with the BROAD metrics (``attica eval``).

- :mod:`attica.evaluate.core`: methods (attica's C filters, the peers), scores per trial and group,
  the grid search of the defaults;
- :mod:`attica.evaluate.estimate`: what a method returns (attitude, rows scored, flags, bias, notes);
- :mod:`attica.evaluate.parallel`: the trials on worker processes or a Dask cluster, bit for bit the
  serial figures;
- :mod:`attica.evaluate.trace`: thinned per-sample curves for the plots;
- :mod:`attica.evaluate.tables`: text tables that fit 110 columns (6-axis and 9-axis apart), notes;
- :mod:`attica.evaluate.plots`, :mod:`attica.evaluate.trialplot`: PNG plots (1600 px): per trial the
  angles against the truth, the errors, flags and bias over time; per group the RMSE bars.
- :mod:`attica.evaluate.suite`: the generalisation suite (``attica eval --suite``): attica's filters,
  VQF and Fusion on a fixed set of simulated conditions; its figures :mod:`attica.evaluate.suite_result`,
  its tables :mod:`attica.evaluate.suite_tables`.
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
    method_kind,
    peer_methods,
    run_methods,
)
from attica.evaluate.estimate import Estimate
from attica.evaluate.parallel import TrialPool
from attica.evaluate.tables import format_notes, format_stated, format_summary, format_tables

__all__ = [
    "DATA_SUFFIXES",
    "Estimate",
    "GRIDS",
    "GROUP_ORDER",
    "METRICS",
    "NINE_AXIS",
    "Method",
    "MethodResult",
    "Report",
    "TrialPool",
    "TrialScore",
    "VARIANTS",
    "VARIANT_GRIDS",
    "attica_method",
    "method_kind",
    "format_notes",
    "format_stated",
    "format_summary",
    "format_tables",
    "grid_search",
    "load_trials",
    "peer_methods",
    "run_methods",
]

"""Accuracy on recorded data with the BROAD metrics: methods, scores, group means, the grid search.

Runs attica's C filters (through the cffi binding, in batch) and optionally other people's filters
(:mod:`attica.peers`) over every recording of a directory, scores each with :func:`attica.metrics.evaluate`
(total, heading and inclination RMSE in degrees over the ``movement`` samples, as BROAD defines them),
averages per trial group (the recordings' ``groups``: undisturbed/disturbed, rotation/translation,
tapping, vibration, magnet ...) and over all trials (:class:`Report`, also as JSON-able data). The
tables are :mod:`attica.evaluate.tables`, the plots :mod:`attica.evaluate.plots`, the command
:mod:`attica.commands.eval`.

9-axis methods (attica ``mars``, the peers' 9D variants) are ranked by the total error; 6-axis methods
cannot know the heading and are judged by the inclination error only, as BROAD prescribes.

``--grid`` runs the small grid search that chose attica's defaults (:data:`GRIDS`): one parameter set for
all trials, ranked by the mean over trials (the dataset authors' "TAGP").
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.checks import implied_gains
from attica.data import Recording, load_recording
from attica.kinds import KINDS, uses_mag
from attica.metrics import Errors, error_angles, evaluate
from attica.settings import FilterKind, Preset, make_settings, preset_settings

__all__ = [
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
    "grid_search",
    "load_trials",
    "peer_methods",
    "run_methods",
]

F64 = NDArray[np.float64]

NINE_AXIS = frozenset(k.kind for k in KINDS if k.uses_mag())
"""attica kinds that use the magnetometer by default (judged by total error); from :mod:`attica.kinds`."""


def _variant(kind: FilterKind, **overrides: Any) -> tuple[FilterKind, dict[str, Any], bool]:
    return kind, overrides, uses_mag(kind, make_settings(kind, **overrides))


VARIANTS: dict[str, tuple[FilterKind, dict[str, Any], bool]] = {
    "mekf6": _variant(FilterKind.MEKF, use_mag=False),
}
"""Named variants of a kind: name -> (kind, setting overrides, nine_axis); ``--filter all`` runs them
after their kind, ``--filter mekf6`` alone. ``nine_axis`` is :func:`attica.kinds.uses_mag` of the
variant's settings."""

DATA_SUFFIXES = (".npz", ".csv", ".hdf5", ".h5", ".mat")
"""Recording files ``load_trials`` picks up from a directory."""

GROUP_ORDER = (
    "undisturbed",
    "rotation",
    "translation",
    "combined",
    "slow",
    "fast",
    "no_breaks",
    "with_breaks",
    "disturbed",
    "tapping",
    "vibration",
    "stationary_magnet",
    "attached_magnet",
    "office_environment",
    "mixed",
)
"""BROAD's groups in its own order (``all_trials`` is the average row)."""

METRICS = ("total", "heading", "inclination")

GRIDS: dict[FilterKind, dict[str, list[Any]]] = {
    FilterKind.ARS: {"tau_acc_lp": [0.75, 1.0, 1.5, 2.0, 3.0], "gain": [0.1, 0.5, 1.0]},
    FilterKind.MARS: {
        "tau_acc_lp": [1.0, 1.3, 2.0],
        "tau_mag": [10.0, 20.0, 40.0],
        "mag_norm_reject": [0.1, 0.2],
        "mag_dip_reject": [0.17, 0.3],
    },
    FilterKind.KF: {
        "tau_acc_lp": [1.0, 1.5, 2.0],
        "q_noise": [3e-4, 1e-3, 3e-3],
        "r_noise": [3e-6, 1e-5, 3e-5],
    },
    FilterKind.EKF: {
        "tau_acc_lp": [1.0, 1.5, 2.0],
        "q_phi,q_theta": [3e-4, 1e-3, 3e-3],
        "r_phi,r_theta": [3e-5, 1e-4, 3e-4],
    },
    FilterKind.GYRO: {},
    FilterKind.TILT: {},
    FilterKind.MEKF: {
        "mag_noise": [0.3, 0.6, 1.0],
        "mag_norm_reject": [0.1, 0.2],
        "mag_dip_reject": [0.3, 0.5],
    },
}
"""The grid searched for each kind, around the default settings (``a,b`` sets both fields); empty for the
baselines, which have nothing to tune. Every kind has an entry (tests/test_kinds.py checks it)."""

VARIANT_GRIDS: dict[str, dict[str, list[Any]]] = {
    "mekf6": {
        "accel_noise": [0.001, 0.003, 0.01],
        "gyro_rate_noise": [0.003, 0.01, 0.03],
        "tau_acc_lp": [1.0, 1.25, 1.6],
        "gyro_scale_sd": [0.0, 0.002, 0.003, 0.005],
    },
}
"""The grid of a variant (the MEKF's 6-axis noise densities and gyro scale prior: the 9-axis grid tunes
the mag on top)."""


@dataclass(frozen=True)
class Method:
    """One estimator to score.

    Attributes
    ----------
    name : str
        Column label (``mars``, ``ars@seed``, ``vqf9@tuned`` ...).
    family : str
        ``attica`` or the peer's library.
    nine_axis : bool
        Uses the magnetometer: ranked by total error (else by inclination).
    setting : str
        ``default``, ``seed`` or ``tuned``.
    run : callable
        ``run(recording) -> (N, 4)`` float64 quaternions sensor-to-ENU.
    note : str
        Description of the setting.

    """

    name: str
    family: str
    nine_axis: bool
    setting: str
    run: Callable[[Recording], F64] = field(compare=False, repr=False)
    note: str = ""

    @property
    def score_metric(self) -> str:
        """``total`` for 9-axis methods, ``inclination`` for 6-axis ones."""
        return "total" if self.nine_axis else "inclination"


def attica_method(
    kind: FilterKind,
    preset: str | Preset = Preset.DEFAULT,
    overrides: dict[str, Any] | None = None,
    variant: str = "",
    calibration: Any = None,
) -> Method:
    """An attica C filter (through the cffi binding) with a preset and optional setting overrides.

    ``variant`` names an entry of :data:`VARIANTS` (its overrides apply first, its name and axes are used).
    ``calibration`` (a :class:`~attica.calibration.Calibration`) sets the filter's input/output stages.
    """
    nine = uses_mag(kind)
    if variant:
        kind, base, nine = VARIANTS[variant]
        overrides = {**base, **(overrides or {})}
    p = Preset.parse(preset)
    extra = dict(overrides or {})

    def run(rec: Recording) -> F64:
        from attica import native

        settings = preset_settings(kind, p, dt=1.0 / rec.rate)
        if extra:  # a time constant set here takes over from the preset's per-sample gain
            settings = make_settings(kind, settings, **implied_gains(kind, settings, extra))
        f = native.Filter(kind, settings=settings, calibration=calibration)
        out = f.run(rec.gyr, rec.acc, rec.mag, check_units=False)
        return np.asarray(out["q"], dtype=np.float64)

    label = variant or kind.label
    name = label if p == Preset.DEFAULT else f"{label}@{p.label}"
    shown = {k: v for k, v in extra.items() if not variant or k not in VARIANTS[variant][1]}
    if shown:
        name += "[" + ",".join(f"{k}={v}" for k, v in shown.items()) + "]"
    note = f"attica {label}, preset {p.label}" + (", calibrated" if calibration is not None else "")
    return Method(name, "attica", nine, p.label, run, note)


def peer_methods(names: Sequence[str] | None = None) -> list[Method]:
    """The installed peers (:mod:`attica.peers`) as methods; ``names`` selects (``vqf9``, ``fusion`` ...)."""
    from attica.peers import available_peers

    chosen = available_peers(list(names) if names is not None else None)
    return [Method(p.name, p.library, p.nine_axis, p.setting, p.run, p.note) for p in chosen]


def load_trials(path: str | Path, limit: int | None = None) -> list[Recording]:
    """Recordings from a file or a directory (every ``.npz/.csv/.hdf5/.h5/.mat``, sorted by name).

    Raises
    ------
    FileNotFoundError
        When ``path`` does not exist or a directory holds no recording.

    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"no such file or directory: {p}")
    if p.is_dir():
        files = sorted(f for f in p.iterdir() if f.suffix.lower() in DATA_SUFFIXES)
        if not files:
            raise FileNotFoundError(f"{p}: no recordings ({', '.join(DATA_SUFFIXES)})")
    else:
        files = [p]
    if limit is not None:
        files = files[:limit]
    return [load_recording(f) for f in files]


@dataclass
class TrialScore:
    """Errors of one method on one trial."""

    trial: str
    groups: tuple[str, ...]
    errors: Errors
    seconds: float


@dataclass
class MethodResult:
    """All trial scores of one method, with group and overall means."""

    method: Method
    trials: list[TrialScore] = field(default_factory=list)

    def values(self, metric: str, group: str | None = None) -> list[float]:
        """Per-trial values of ``metric`` (``total``/``heading``/``inclination``), optionally of a group."""
        return [getattr(t.errors, metric) for t in self.trials if group is None or group in t.groups]

    def mean(self, metric: str, group: str | None = None) -> float:
        """Mean over trials (of a group) of ``metric``; NaN when none, or when a trial is NaN."""
        v = self.values(metric, group)
        return float(np.mean(v)) if v else float("nan")

    def score(self, group: str | None = None) -> float:
        """Mean of the method's score metric (total for 9-axis, inclination for 6-axis)."""
        return self.mean(self.method.score_metric, group)


@dataclass
class Report:
    """Results of :func:`run_methods`."""

    results: list[MethodResult]
    trials: list[str]
    groups: list[str]
    curves: dict[tuple[str, str], tuple[F64, F64]] = field(default_factory=dict)
    """(method, trial) -> (per-sample score error in deg, per-sample inclination error in deg)."""

    def result(self, name: str) -> MethodResult:
        """The result of a method by name."""
        for r in self.results:
            if r.method.name == name:
                return r
        raise KeyError(name)

    def as_dict(self) -> dict[str, Any]:
        """Every figure as plain JSON-able data."""

        def clean(x: float) -> float | None:
            return None if not np.isfinite(x) else round(float(x), 4)

        methods: dict[str, Any] = {}
        for r in self.results:
            m = r.method
            methods[m.name] = {
                "family": m.family,
                "nine_axis": m.nine_axis,
                "setting": m.setting,
                "note": m.note,
                "score_metric": m.score_metric,
                "trials": {
                    t.trial: {**{k: clean(getattr(t.errors, k)) for k in METRICS}, "n": t.errors.n}
                    for t in r.trials
                },
                "groups": {g: {k: clean(r.mean(k, g)) for k in METRICS} for g in self.groups},
                "mean": {k: clean(r.mean(k)) for k in METRICS},
                "seconds": round(sum(t.seconds for t in r.trials), 3),
            }
        return {"trials": self.trials, "groups": self.groups, "methods": methods}


def _groups_of(recs: Sequence[Recording]) -> list[str]:
    present = {g for r in recs for g in r.groups}
    ordered = [g for g in GROUP_ORDER if g in present]
    return ordered + sorted(present - set(ordered) - {"all_trials"})


def _progress(total: int, desc: str, enabled: bool) -> Any:
    from tqdm import tqdm

    return tqdm(
        total=total, desc=desc, disable=not (enabled and sys.stderr.isatty()), leave=False, file=sys.stderr
    )


def run_methods(
    methods: Sequence[Method],
    recs: Sequence[Recording],
    progress: bool = True,
    curves: bool = False,
) -> Report:
    """Score every method on every recording (each needs ``quat_true``; ``movement`` when given).

    Parameters
    ----------
    methods : sequence of Method
        What to run.
    recs : sequence of Recording
        Trials with ground truth.
    progress : bool
        Show a progress bar (only when stderr is a terminal).
    curves : bool
        Keep the per-sample errors (for the plots).

    Returns
    -------
    Report
        Per method and trial the BROAD errors, plus group names and optional curves.

    Raises
    ------
    ValueError
        When a recording has no ground truth.

    """
    for r in recs:
        if r.quat_true is None:
            raise ValueError(f"{r.name}: no ground truth (opt_quat / quat_* columns)")
    report = Report([MethodResult(m) for m in methods], [r.name for r in recs], _groups_of(recs))
    with _progress(len(methods) * len(recs), "eval", progress) as bar:
        for res in report.results:
            for rec in recs:
                bar.set_postfix_str(f"{res.method.name} {rec.name[:24]}")
                t0 = time.perf_counter()
                q = res.method.run(rec)
                elapsed = time.perf_counter() - t0
                assert rec.quat_true is not None
                errors = evaluate(q, rec.quat_true, rec.movement)
                res.trials.append(TrialScore(rec.name, rec.groups, errors, elapsed))
                if curves:
                    total, _, incl = error_angles(q, rec.quat_true)
                    score = total if res.method.nine_axis else incl
                    report.curves[(res.method.name, rec.name)] = (np.degrees(score), np.degrees(incl))
                bar.update(1)
    return report


# --- grid search ------------------------------------------------------------------------------------------


def grid_search(
    kind: FilterKind,
    recs: Sequence[Recording],
    grid: dict[str, list[Any]] | None = None,
    progress: bool = True,
) -> list[tuple[dict[str, Any], Errors]]:
    """Score every point of ``grid`` (default :data:`GRIDS`), applied to the default settings.

    Returns ``(overrides, mean errors over trials)`` sorted best first (9-axis kinds by total error, the
    others by inclination error): one parameter set for all trials, as BROAD's authors tune.
    """
    from attica.tuning import grid_scores

    g = grid if grid is not None else GRIDS[kind]
    return grid_scores(kind, recs, g, progress=progress).ranked()

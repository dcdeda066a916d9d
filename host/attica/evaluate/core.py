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
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.checks import implied_gains
from attica.data import Recording, load_recording
from attica.evaluate.estimate import Estimate
from attica.evaluate.parallel import TrialPool
from attica.evaluate.trace import Trace
from attica.kinds import KINDS, info, uses_mag
from attica.metrics import STATED_ANGLES, Errors, Stated, pooled_ratio
from attica.outputs import OUT_BIAS
from attica.settings import FilterKind, Preset, make_settings, preset_settings
from attica.tuning import grid_search

__all__ = [
    "GRIDS",
    "GROUP_ORDER",
    "METRICS",
    "NINE_AXIS",
    "Estimate",
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


def method_kind(name: str) -> FilterKind:
    """The kind behind a kind or variant name (``mekf6`` -> MEKF); a ValueError for an unknown name."""
    return VARIANTS[name][0] if name in VARIANTS else FilterKind.parse(name)


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
        "tau_acc_lp": [1.25, 1.45, 1.6],
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
        ``run(recording)`` -> ``(N, 4)`` float64 quaternions sensor-to-ENU (or an
        :class:`~attica.evaluate.estimate.Estimate`).
    note : str
        Description of the setting.
    estimate : callable, optional
        ``estimate(recording)`` -> :class:`~attica.evaluate.estimate.Estimate` (the quaternions with the
        rows scored, flags, gyro bias, notes); the evaluation calls it instead of ``run`` when given.

    To run on worker processes (``jobs`` > 1) ``run`` and ``estimate`` must pickle: module-level
    functions, ``functools.partial`` objects of them, or (methods of) instances of module-level classes.

    """

    name: str
    family: str
    nine_axis: bool
    setting: str
    run: Callable[[Recording], F64 | Estimate] = field(compare=False, repr=False)
    note: str = ""
    estimate: Callable[[Recording], Estimate] | None = field(default=None, compare=False, repr=False)

    def outcome(self, rec: Recording) -> F64 | Estimate:
        """What the evaluation scores: :attr:`estimate` of the recording when given, else :attr:`run`."""
        return self.estimate(rec) if self.estimate is not None else self.run(rec)

    @property
    def score_metric(self) -> str:
        """``total`` for 9-axis methods, ``inclination`` for 6-axis ones."""
        return "total" if self.nine_axis else "inclination"


@dataclass(frozen=True)
class AtticaRun:
    """The ``run`` of :func:`attica_method`: a module-level class, so that it pickles for worker processes.

    Calling it returns the quaternions; :meth:`estimate` also the filter's flags, (when it estimates one)
    gyro bias and, with ``covariance``, the orientation covariance it states (:attr:`Estimate.cov`).
    """

    kind: FilterKind
    preset: Preset
    overrides: dict[str, Any]
    calibration: Any = None
    covariance: bool = False

    def __call__(self, rec: Recording) -> F64:
        """The quaternions ``(N, 4)`` float64 of the C filter run over the recording in batch."""
        return self.estimate(rec).q

    def estimate(self, rec: Recording) -> Estimate:
        """The C filter run over the recording in batch: quaternions, flags, gyro bias, covariance."""
        from attica import native
        from attica.data.covariance import COVARIANCE, orientation_covariance

        settings = preset_settings(self.kind, self.preset, dt=1.0 / rec.rate)
        if self.overrides:  # a time constant set here takes over from the preset's per-sample gain
            settings = make_settings(
                self.kind, settings, **implied_gains(self.kind, settings, self.overrides)
            )
        f = native.Filter(self.kind, settings=settings, calibration=self.calibration)
        steps = rec.steps if rec.lost else None  # lost samples are stepped over (Recording.steps)
        out = f.run(rec.gyr, rec.acc, rec.mag, check_units=False, steps=steps)
        bias = np.asarray(out["gyro_bias"])
        has_bias = bool(np.all(out["valid"] & OUT_BIAS)) and bool(np.any(bias != 0.0))
        states = self.covariance and self.kind in COVARIANCE
        return Estimate(
            np.asarray(out["q"], dtype=np.float64),
            flags=np.asarray(out["flags"], dtype=np.uint32),
            gyro_bias=bias if has_bias else None,
            cov=orientation_covariance(self.kind, out) if states else None,
        )


def attica_method(
    kind: FilterKind,
    preset: str | Preset = Preset.DEFAULT,
    overrides: dict[str, Any] | None = None,
    variant: str = "",
    calibration: Any = None,
    covariance: bool = False,
) -> Method:
    """An attica C filter (through the cffi binding) with a preset and optional setting overrides.

    ``variant`` names an entry of :data:`VARIANTS` (its overrides apply first, its name and axes are used).
    ``calibration`` (a :class:`~attica.calibration.Calibration`) sets the filter's input/output stages.
    ``covariance``: its estimates carry the orientation covariance the kind states, which the evaluation
    then compares with the errors (:attr:`TrialScore.stated`; ``attica eval`` asks for it, the grids
    and the suite do not).
    """
    nine = uses_mag(kind)
    if variant:
        kind, base, nine = VARIANTS[variant]
        overrides = {**base, **(overrides or {})}
    p = Preset.parse(preset)
    extra = dict(overrides or {})
    switch = info(kind).mag_switch
    if switch is not None and switch in extra:  # the mekf's use_mag set: the axes follow it
        nine = bool(extra[switch])
    run = AtticaRun(kind, p, extra, calibration, covariance)
    label = variant or kind.label
    name = label if p == Preset.DEFAULT else f"{label}@{p.label}"
    shown = {k: v for k, v in extra.items() if not variant or k not in VARIANTS[variant][1]}
    if shown:
        name += "[" + ",".join(f"{k}={v}" for k, v in shown.items()) + "]"
    note = f"attica {label}, preset {p.label}" + (", calibrated" if calibration is not None else "")
    return Method(name, "attica", nine, p.label, run, note, estimate=run.estimate)


def peer_methods(names: Sequence[str] | None = None) -> list[Method]:
    """The installed peers (:mod:`attica.peers`) as methods; ``names`` selects (``vqf9``, ``fusion`` ...)."""
    from attica.peers import available_peers

    chosen = available_peers(list(names) if names is not None else None)
    return [Method(p.name, p.library, p.nine_axis, p.setting, p.run, p.note, p.estimate) for p in chosen]


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
    notes: tuple[str, ...] = ()
    """What the method did to this trial's input or scoring (a peer started late, a sample held ...)."""
    stated: Stated | None = None
    """The method's stated orientation covariance against its errors (None: it states none)."""


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

    def stated_ratio(self, angle: str) -> float:
        """The stated covariance of ``angle`` against the errors, pooled over the trials that compared rows.

        :func:`attica.metrics.pooled_ratio` of the trials' :attr:`TrialScore.stated`; NaN when the
        method states no covariance.
        """
        return pooled_ratio([t.stated for t in self.trials if t.stated is not None], angle)


@dataclass
class Report:
    """Results of :func:`run_methods`."""

    results: list[MethodResult]
    trials: list[str]
    groups: list[str]
    traces: dict[tuple[str, str], Trace] = field(default_factory=dict)
    """(method, trial) -> thinned per-sample curves for the plots (``run_methods(curves=True)``)."""

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
                    t.trial: {
                        **{k: clean(getattr(t.errors, k)) for k in METRICS},
                        "n": t.errors.n,
                        **({"notes": list(t.notes)} if t.notes else {}),
                        **({"stated": _stated_dict(m, t.stated, clean)} if t.stated is not None else {}),
                    }
                    for t in r.trials
                },
                "groups": {g: {k: clean(r.mean(k, g)) for k in METRICS} for g in self.groups},
                "mean": {k: clean(r.mean(k)) for k in METRICS},
                **(
                    {"stated_ratio": {a: clean(r.stated_ratio(a)) for a in _stated_angles(m)}}
                    if any(t.stated is not None for t in r.trials)
                    else {}
                ),
                "seconds": round(sum(t.seconds for t in r.trials), 3),
            }
        return {"trials": self.trials, "groups": self.groups, "methods": methods}


def _stated_angles(m: Method) -> tuple[str, ...]:
    """The angles whose stated variance is compared: the heading only where the method observes it."""
    return STATED_ANGLES if m.nine_axis else STATED_ANGLES[:1]


def _stated_dict(m: Method, st: Stated, clean: Callable[[float], float | None]) -> dict[str, Any]:
    """One trial's stated covariance against its errors, for ``results.json``."""
    return {**{a: clean(st.ratio(a)) for a in _stated_angles(m)}, "n": st.n}


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
    jobs: int = 1,
    scheduler: str | None = None,
    pool: TrialPool | None = None,
    desc: str = "eval",
) -> Report:
    """Score every method on every recording (each needs ``quat_true``; ``movement`` when given).

    Parameters
    ----------
    methods : sequence of Method
        What to run.
    recs : sequence of Recording
        Trials with ground truth.
    progress : bool
        Show a progress bar (only when stderr is a terminal), advancing as trials finish.
    curves : bool
        Keep thinned per-sample curves (:class:`~attica.evaluate.trace.Trace`) for the plots.
    jobs : int
        Worker processes (1: in this process); ignored when ``pool`` is given.
    scheduler : str, optional
        A Dask scheduler's address to run on; ignored when ``pool`` is given.
    pool : TrialPool, optional
        Where to run (kept open by the caller across calls, as ``--grid`` does).
    desc : str
        Progress bar label.

    Returns
    -------
    Report
        Per method and trial the BROAD errors, plus group names and optional traces; identical whatever
        runs the tasks (but for the measured ``seconds``).

    Raises
    ------
    ValueError
        When a recording has no ground truth, or a method cannot be sent to worker processes.

    """
    for r in recs:
        if r.quat_true is None:
            raise ValueError(f"{r.name}: no ground truth (opt_quat / quat_* columns)")
    report = Report([MethodResult(m) for m in methods], [r.name for r in recs], _groups_of(recs))
    if pool is None:
        with TrialPool(jobs, scheduler) as own:
            return _fill(report, methods, recs, progress, curves, own, desc)
    return _fill(report, methods, recs, progress, curves, pool, desc)


def _fill(
    report: Report,
    methods: Sequence[Method],
    recs: Sequence[Recording],
    progress: bool,
    curves: bool,
    pool: TrialPool,
    desc: str,
) -> Report:
    with _progress(len(methods) * len(recs), desc, progress) as bar:

        def done(i: int, j: int) -> None:
            bar.set_postfix_str(f"{methods[i].name} {recs[j].name[:24]}", refresh=False)
            bar.update(1)

        outcomes = pool.run(methods, recs, curves, done)
    for res, row in zip(report.results, outcomes, strict=True):
        for rec, o in zip(recs, row, strict=True):
            res.trials.append(TrialScore(rec.name, rec.groups, o.errors, o.seconds, o.notes, o.stated))
            if o.trace is not None:
                report.traces[(res.method.name, rec.name)] = o.trace
    return report

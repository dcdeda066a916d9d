"""Accuracy on recorded data with the BROAD metrics: ``attica eval``.

Runs attica's C filters (through the cffi binding, in batch) and optionally other people's filters
(:mod:`attica.peers`) over every recording of a directory, scores each with :func:`attica.metrics.evaluate`
(total, heading and inclination RMSE in degrees over the ``movement`` samples, as BROAD defines them),
averages per trial group (the recordings' ``groups``: undisturbed/disturbed, rotation/translation,
tapping, vibration, magnet ...) and over all trials, prints the tables, and writes a JSON of every figure
and PNG plots (error over time per trial with the movement phases shaded; per-group bars).

9-axis methods (attica ``mars``, the peers' 9D variants) are ranked by the total error; 6-axis methods
cannot know the heading and are judged by the inclination error only, as BROAD prescribes.

``--grid`` runs the small grid search that chose attica's defaults (:data:`GRIDS`): one parameter set for
all trials, ranked by the mean over trials (the dataset authors' "TAGP").
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.data import Recording, load_recording
from attica.metrics import Errors, error_angles, evaluate
from attica.settings import FilterKind, Preset, implemented_kinds, make_settings, preset_settings

__all__ = [
    "GRIDS",
    "VARIANT_GRIDS",
    "GROUP_ORDER",
    "Method",
    "MethodResult",
    "Report",
    "add_eval_subcommand",
    "attica_method",
    "cmd_eval",
    "grid_search",
    "load_trials",
    "run_methods",
]

F64 = NDArray[np.float64]

NINE_AXIS = {FilterKind.MARS, FilterKind.MEKF}
"""attica kinds that use the magnetometer by default (judged by total error)."""

VARIANTS: dict[str, tuple[FilterKind, dict[str, Any], bool]] = {
    "mekf6": (FilterKind.MEKF, {"use_mag": False}, False),
}
"""Named variants of a kind: name -> (kind, setting overrides, nine_axis); ``--filter all`` runs them
after their kind, ``--filter mekf6`` alone."""

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
    FilterKind.ARS: {"tau_acc_lp": [1.0, 1.5, 2.0, 3.0], "tau": [0.02, 0.2, 1.0], "gain_c": [0.0, 100.0]},
    FilterKind.MARS: {
        "tau_acc_lp": [1.0, 1.5, 2.0],
        "tau_acc": [0.02, 0.5],
        "tau_mag": [10.0, 20.0, 40.0],
        "mag_norm_reject": [0.1, 0.2],
        "mag_dip_reject": [0.17, 0.3],
    },
    FilterKind.KF: {"q_noise": [3e-4, 1e-3, 3e-3], "r_noise": [0.03, 0.1, 0.3], "accel_reject": [0.1, 0.2]},
    FilterKind.EKF: {
        "q_phi,q_theta": [3e-3, 1e-2, 3e-2],
        "r_phi,r_theta": [0.3, 1.0, 3.0],
        "accel_reject": [0.1, 0.2],
    },
    FilterKind.MEKF: {
        "mag_noise": [0.3, 0.6, 1.0],
        "mag_norm_reject": [0.1, 0.2],
        "mag_dip_reject": [0.3, 0.5],
    },
}
"""The grid searched for each tunable kind, around the default settings (``a,b`` sets both fields)."""

VARIANT_GRIDS: dict[str, dict[str, list[Any]]] = {
    "mekf6": {
        "accel_noise": [0.001, 0.003, 0.01],
        "gyro_rate_noise": [0.003, 0.01, 0.03],
        "tau_acc_lp": [1.0, 1.5, 2.5],
    },
}
"""The grid of a variant (the MEKF's 6-axis noise densities: the 9-axis grid tunes the mag on top)."""


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
) -> Method:
    """An attica C filter (through the cffi binding) with a preset and optional setting overrides.

    ``variant`` names an entry of :data:`VARIANTS` (its overrides apply first, its name and axes are used).
    """
    nine = kind in NINE_AXIS
    if variant:
        kind, base, nine = VARIANTS[variant]
        overrides = {**base, **(overrides or {})}
    p = Preset.parse(preset)
    extra = dict(overrides or {})

    def run(rec: Recording) -> F64:
        from attica import native

        settings = preset_settings(kind, p, dt=1.0 / rec.rate)
        if extra:
            settings = make_settings(kind, settings, **extra)
        out = native.Filter(kind, settings).run(rec.gyr, rec.acc, rec.mag)
        return np.asarray(out["q"], dtype=np.float64)

    label = variant or kind.label
    name = label if p == Preset.DEFAULT else f"{label}@{p.label}"
    shown = {k: v for k, v in extra.items() if not variant or k not in VARIANTS[variant][1]}
    if shown:
        name += "[" + ",".join(f"{k}={v}" for k, v in shown.items()) + "]"
    return Method(name, "attica", nine, p.label, run, f"attica {label}, preset {p.label}")


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


# --- tables -----------------------------------------------------------------------------------------


def _fmt(x: float) -> str:
    return f"{x:7.2f}" if np.isfinite(x) else "    nan"


def format_tables(report: Report) -> str:
    """Plain-text tables of the RMSE in degrees, per trial, per group and averaged over trials.

    Inclination for every method, total for the 9-axis ones.
    """
    lines: list[str] = []
    blocks = [("inclination", report.results), ("total", [r for r in report.results if r.method.nine_axis])]
    for metric, results in blocks:
        if not results:
            continue
        names = [r.method.name for r in results]
        width = max(28, max(len(t) for t in report.trials) if report.trials else 0)
        colw = [max(7, len(n)) for n in names]
        head = f"{metric} RMSE (deg)".ljust(width) + " " + " ".join(n.rjust(w) for n, w in zip(names, colw))
        lines += [head, "-" * len(head)]

        def row(label: str, vals: list[float], width: int = width, colw: list[int] = colw) -> str:
            return label.ljust(width) + " " + " ".join(_fmt(v).rjust(w) for v, w in zip(vals, colw))

        for i, t in enumerate(report.trials):
            lines.append(row(t, [getattr(r.trials[i].errors, metric) for r in results]))
        lines.append("-" * len(head))
        for g in report.groups:
            lines.append(row(f"[{g}]", [r.mean(metric, g) for r in results]))
        lines.append(row("average", [r.mean(metric) for r in results]))
        lines.append("")
    return "\n".join(lines)


def format_summary(report: Report) -> str:
    """One line per method: mean total, heading and inclination RMSE and the score metric."""
    out = [f"{'method':<24} {'total':>7} {'heading':>7} {'incl':>7}  judged by"]
    for r in report.results:
        m = r.method
        out.append(
            f"{m.name:<24} {_fmt(r.mean('total'))} {_fmt(r.mean('heading'))} {_fmt(r.mean('inclination'))}"
            f"  {m.score_metric}{'' if m.nine_axis else ' (6-axis)'}"
        )
    return "\n".join(out)


# --- plots --------------------------------------------------------------------------------------------


def _pyplot() -> Any:
    try:
        import matplotlib
    except ImportError:
        raise RuntimeError("plots need matplotlib: pip install '.[eval]' (or use --no-plots)") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _phases(movement: NDArray[np.bool_]) -> list[tuple[int, int]]:
    m = np.concatenate([[False], movement, [False]]).astype(np.int8)
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def plot_trial(report: Report, rec: Recording, path: Path, methods: Sequence[str] | None = None) -> None:
    """Error over time of the given methods on one trial as a small PNG, movement phases shaded.

    9-axis methods show the total error, 6-axis ones the inclination error.
    """
    plt = _pyplot()
    names = [r.method.name for r in report.results if methods is None or r.method.name in methods]
    fig, ax = plt.subplots(figsize=(8, 3), dpi=80)
    t = rec.t
    step = max(1, len(t) // 2000)
    if rec.movement is not None:
        for a, b in _phases(rec.movement):
            ax.axvspan(t[a], t[min(b, len(t) - 1)], color="0.9", lw=0)
    top = 5.0
    colours = plt.get_cmap("tab10").colors
    for i, name in enumerate(names):
        res = report.result(name)
        score, _ = report.curves[(name, rec.name)]
        label = f"{name} ({res.method.score_metric[:5]})"
        ax.plot(t[::step], score[::step], lw=0.8, label=label, color=colours[i % 10])
        finite = score[np.isfinite(score)]
        if finite.size:
            top = max(top, float(np.percentile(finite, 99.5)) * 1.1)
    ax.set_xlabel("time (s); movement phases shaded")
    ax.set_ylabel("error (deg)")
    ax.set_title(rec.name, fontsize=9)
    ax.set_ylim(0, min(top, 180.0))
    ax.legend(fontsize=6, ncol=4, loc="upper left")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_groups(report: Report, path: Path, methods: Sequence[str] | None = None) -> None:
    """Per-group bars of each method's score metric (RMSE, deg), plus the all-trial average."""
    plt = _pyplot()
    results = [r for r in report.results if methods is None or r.method.name in methods]
    labels = [*report.groups, "average"]
    fig, ax = plt.subplots(figsize=(9, 3.6), dpi=80)
    width = 0.8 / max(1, len(results))
    x = np.arange(len(labels))
    colours = plt.get_cmap("tab20").colors
    for i, r in enumerate(results):
        vals = [r.score(g) for g in report.groups] + [r.score()]
        pos = x + (i - (len(results) - 1) / 2) * width
        ax.bar(
            pos,
            vals,
            width,
            label=f"{r.method.name}",
            color=colours[(2 * i) % 20 if i < 10 else 2 * i % 20 + 1],
        )
    ax.set_xticks(x)
    ax.set_xticklabels(labels, rotation=30, ha="right", fontsize=7)
    ax.set_ylabel("RMSE (deg): total (9-axis) / incl. (6-axis)", fontsize=7)
    ax.set_yscale("log")
    ax.legend(fontsize=6, ncol=4)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


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


# --- command line -----------------------------------------------------------------------------------------


def _methods_for(args: argparse.Namespace) -> list[Method]:
    labels: list[str] = []
    for k in implemented_kinds() if args.filter == "all" else args.filter.split(","):
        label = k.label if isinstance(k, FilterKind) else k
        labels.append(label if label in VARIANTS else FilterKind.parse(label).label)
        if args.filter == "all":
            labels += [v for v, (kind, _, _) in VARIANTS.items() if kind.label == label]
    presets = [Preset.DEFAULT, Preset.SEED] if args.preset == "both" else [Preset.parse(args.preset)]
    methods = []
    for p in presets:
        for n in labels:
            variant = n if n in VARIANTS else ""
            kind = VARIANTS[n][0] if variant else FilterKind.parse(n)
            methods.append(attica_method(kind, p, variant=variant))
    if args.peers is not None:
        names = None if args.peers in ("", "all") else args.peers.split(",")
        peers = peer_methods(names)
        if not peers:
            print("attica eval: no peer installed (pip install '.[peers]')", file=sys.stderr)
        methods += peers
    return methods


def _cmd_grid(args: argparse.Namespace, recs: Sequence[Recording], out: Path | None) -> int:
    """``attica eval --grid``: every grid (kinds and variants), best five, in-sample and leave-one-out."""
    from attica.tuning import grid_scores, leave_one_out

    names: list[str] = [k.label for k in implemented_kinds() if k in GRIDS] + list(VARIANT_GRIDS)
    if args.filter != "all":
        names = [n if n in VARIANT_GRIDS else FilterKind.parse(n).label for n in args.filter.split(",")]
    grids: dict[str, Any] = {}
    for name in names:
        variant = name if name in VARIANT_GRIDS else ""
        kind = VARIANTS[name][0] if variant else FilterKind.parse(name)
        grid = VARIANT_GRIDS[name] if variant else GRIDS[kind]
        res = grid_scores(kind, recs, grid, variant=variant, progress=not args.quiet)
        rows = res.ranked()
        print(f"\ngrid {name} ({len(rows)} points, ranked by mean {res.metric} RMSE); best 5:")
        for over, e in rows[:5]:
            print(f"  {e.total:7.2f} {e.heading:7.2f} {e.inclination:7.2f}  {over}")
        entry: dict[str, Any] = {
            "grid": grid,
            "ranked": [{"settings": o, **{k: getattr(e, k) for k in METRICS}} for o, e in rows],
        }
        if len(recs) >= 2:
            loo = leave_one_out(res)
            print(
                f"  {res.metric}: in-sample {loo.in_sample:.3f}, leave-one-trial-out {loo.mean:.3f} "
                f"(the best point on the other {len(recs) - 1} trials, scored on the held-out one)"
            )
            entry["in_sample"] = loo.in_sample
            entry["leave_one_out"] = loo.mean
            entry["held_out"] = {t: float(v) for t, v in zip(res.trials, loo.held_out, strict=True)}
            entry["chosen"] = {t: res.points[i] for t, i in zip(res.trials, loo.chosen, strict=True)}
        grids[name] = entry
    if out is not None:
        (out / "grid.json").write_text(json.dumps(grids, indent=1, default=str))
        print(f"wrote {out / 'grid.json'}")
    return 0


def cmd_eval(args: argparse.Namespace) -> int:
    """``attica eval``."""
    try:
        recs = load_trials(args.data, args.limit)
    except (FileNotFoundError, ValueError, RuntimeError) as exc:
        print(f"attica: error: {exc}", file=sys.stderr)
        return 2
    out = Path(args.out) if args.out else None
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    print(f"{args.data}: {len(recs)} trials, {sum(len(r) for r in recs)} samples")
    if args.grid:
        return _cmd_grid(args, recs, out)
    try:
        methods = _methods_for(args)
    except ValueError as exc:
        print(f"attica: error: {exc}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    report = run_methods(methods, recs, progress=not args.quiet, curves=out is not None and not args.no_plots)
    print(f"{len(methods)} methods x {len(recs)} trials in {time.perf_counter() - t0:.1f} s\n")
    print(format_tables(report))
    print(format_summary(report))
    if out is not None:
        data = {
            "command": " ".join(["attica", *sys.argv[2:]]) if sys.argv[1:2] == ["eval"] else "attica eval"
        }
        data.update(report.as_dict())
        (out / "results.json").write_text(json.dumps(data, indent=1))
        print(f"\nwrote {out / 'results.json'}")
        if not args.no_plots:
            try:
                _write_plots(report, recs, out)
            except RuntimeError as exc:
                print(f"attica: error: {exc}", file=sys.stderr)
                return 2
    return 0


PLOT_PEERS = ("vqf9", "vqf6", "basicvqf9", "fusion9", "madgwick9", "mahony9", "ekf9")
"""Peers drawn in the plots (when they were run; the tables and the JSON have every method)."""


def _write_plots(report: Report, recs: Iterable[Recording], out: Path) -> None:
    """Write the PNGs.

    error_<trial>.png: attica's filters at their defaults (without the gyro-only and accel-only baselines)
    and VQF; groups.png: the same filters and the default-setting peers of :data:`PLOT_PEERS`;
    groups_seed.png: attica's tuned filters against their seed preset.
    """
    baselines = (FilterKind.GYRO.label, FilterKind.TILT.label)
    ran = [r.method for r in report.results]
    mine = [
        m.name for m in ran if m.family == "attica" and m.setting == "default" and m.name not in baselines
    ]
    peers = [m.name for m in ran if m.family != "attica" and m.name in PLOT_PEERS]
    for rec in recs:
        plot_trial(
            report, rec, out / f"error_{rec.name}.png", mine + [n for n in peers if n.startswith("vqf")]
        )
    plot_groups(report, out / "groups.png", mine + peers)
    seeds = {m.name for m in ran if m.setting == "seed"}
    pairs = [n for k in mine for n in (k, f"{k}@seed") if f"{k}@seed" in seeds]
    if pairs:
        plot_groups(report, out / "groups_seed.png", pairs)
    print(f"wrote {out}/error_*.png and {out}/groups*.png")


def add_eval_subcommand(sub: Any) -> None:
    """Register ``attica eval`` on the subparsers object of ``attica``'s parser."""
    choices = ", ".join([k.label for k in FilterKind] + list(VARIANTS))
    sp = sub.add_parser("eval", help="accuracy on recorded trials (BROAD metrics), tables, plots, peers")
    sp.add_argument("--filter", default="all", help=f"'all' or comma-separated kinds ({choices})")
    sp.add_argument("--data", required=True, help="directory of trials (.npz/.csv/.hdf5/.mat) or one file")
    sp.add_argument(
        "--preset", default="default", choices=["default", "seed", "both"], help="settings preset"
    )
    sp.add_argument("--out", help="directory for results.json and the PNG plots")
    sp.add_argument(
        "--peers",
        nargs="?",
        const="all",
        help="also run the installed peers (all, or comma-separated names such as vqf9,fusion9)",
    )
    sp.add_argument("--grid", action="store_true", help="run the grid search of the defaults instead")
    sp.add_argument("--limit", type=int, help="only the first N trials")
    sp.add_argument("--no-plots", action="store_true", help="write no PNGs")
    sp.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    sp.set_defaults(func=cmd_eval)

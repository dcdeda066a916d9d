"""attica eval's output: tables within 110 columns (or --wide), plots readable at a glance.

The plots are checked on the figures themselves: each panel's title against what it draws (the methods
in its legend, the flags in its rows, the bias values, the movement phases the caption says are
shaded), a log scale only where the values span more than two decades (linear elsewhere), every legend
right of its chart's data, 1600 px wide.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from attica import kinds
from attica.cli import main
from attica.data import Recording, broad_groups
from attica.evaluate import VARIANTS, Estimate, Method, run_methods
from attica.metrics import quat_mul
from attica.settings import Flag
from attica.sim import SimConfig, simulate

from helpers import need

TRIALS = ("01_undisturbed_slow_rotation_A", "24_disturbed_tapping_A")


def _qx(deg: float) -> np.ndarray:
    a = np.radians(deg) / 2
    return np.array([np.cos(a), np.sin(a), 0.0, 0.0])


def _recs() -> list[Recording]:
    out = []
    for seed, name in enumerate(TRIALS, start=1):
        r = simulate(SimConfig(duration=12.0, rate=100.0, seed=seed))
        r.name, r.groups = name, broad_groups(name)
        out.append(r)
    return out


def _tilted(name: str, deg: float, nine: bool) -> Method:
    """The truth tilted by ``deg`` about x: inclination and total error ``deg`` at every sample."""

    def run(rec: Any) -> np.ndarray:
        return quat_mul(_qx(deg), np.asarray(rec.quat_true, np.float64))

    return Method(name, "test", nine, "default", run)


def _flagged(name: str) -> Method:
    """2 deg off, at rest over the first 30 % of the samples, initialised at the first, a constant bias."""

    def run(rec: Any) -> Estimate:
        n = len(rec)
        flags = np.zeros(n, np.uint32)
        flags[: int(0.3 * n)] |= np.uint32(Flag.AT_REST)
        flags[0] |= np.uint32(Flag.INITIALISED)
        bias = np.tile(np.radians([0.5, -0.2, 0.0]), (n, 1))
        return Estimate(
            quat_mul(_qx(2.0), np.asarray(rec.quat_true, np.float64)), flags=flags, gyro_bias=bias
        )

    return Method(name, "test", True, "default", run)


@pytest.fixture(scope="module")
def report_and_recs() -> tuple[Any, list[Recording]]:
    # inclination: one method 150x worse than another (log scale); heading (all 0) and 9-axis RMSE: linear
    methods = [
        _tilted("good6", 1.0, False),
        _tilted("bad6", 150.0, False),
        _tilted("a9", 2.0, True),
        _tilted("b9", 3.0, True),
        _flagged("flagged9"),
    ]
    recs = _recs()
    return run_methods(methods, recs, progress=False, curves=True), recs


def _check_figure(fig: Any, titles: list[str], legends: list[list[str]], scales: list[str | None]) -> None:
    fig.canvas.draw()
    assert round(fig.get_size_inches()[0] * fig.dpi) == 1600
    axes = fig.get_axes()
    assert [ax.get_title(loc="left") for ax in axes] == titles
    for ax, names, scale in zip(axes, legends, scales, strict=True):
        leg = ax.get_legend()
        assert [t.get_text() for t in leg.get_texts()] == names, ax.get_title(loc="left")
        if scale is not None:
            assert ax.get_yscale() == scale, (ax.get_title(loc="left"), ax.get_yscale())
        # the legend is right of the data, inside the figure
        box, data = leg.get_window_extent(), ax.get_window_extent()
        assert box.x0 >= data.x1 - 0.5 and box.x1 <= fig.bbox.x1 + 0.5


def test_trial_figure_draws_what_its_titles_say(report_and_recs: Any) -> None:
    need_mpl()
    from attica.evaluate.plots import _pyplot, trial_figure
    from attica.evaluate.trialplot import TITLES

    report, recs = report_and_recs
    plt = _pyplot()
    every, nine = ["good6", "bad6", "a9", "b9", "flagged9"], ["a9", "b9", "flagged9"]
    fig = trial_figure(report, recs[0])
    try:
        _check_figure(
            fig,
            [TITLES[k] for k in ("roll", "pitch", "yaw", "inclination", "heading", "flags", "bias")],
            [["truth", *every], ["truth", *every], ["truth", *nine], every, nine, ["flagged9"], ["flagged9"]],
            [None, None, None, "log", "linear", None, "linear"],
        )
        axes = fig.get_axes()
        # the yaw panel: no 6-axis method's line; the flags panel: a row per flag set, marks in it
        assert [ln.get_label() for ln in axes[2].get_lines()] == ["truth", *nine]
        assert [t.get_text() for t in axes[5].get_yticklabels()] == ["at rest", "initialised"]
        assert len(axes[5].collections) == 2
        # the bias panel: x, y, z of the one method that estimates a bias, in deg/s
        ys = [float(np.nanmean(ln.get_ydata())) for ln in axes[6].get_lines()[:3]]
        assert np.allclose(ys, [0.5, -0.2, 0.0], atol=1e-6)
        # the caption says the movement phases are shaded, and they are: one span per phase in each panel
        rec = recs[0]
        phases = int(np.count_nonzero(np.diff(np.r_[0, rec.movement.astype(int)]) == 1))
        assert axes[-1].get_xlabel() == "time (s); movement phases (the samples scored) shaded"
        assert all(len(ax.patches) == phases for ax in axes) and phases == 3
        assert fig.get_axes()[4].get_ylim()[0] == 0.0  # a linear error axis starts at 0
    finally:
        plt.close(fig)
    # no 9-axis method, no flags: no yaw, heading, flags or bias panel; no movement marked: no shading
    bare = Recording(recs[1].gyr, recs[1].acc, recs[1].mag, recs[1].rate, recs[1].quat_true, None, "bare")
    rep = run_methods([_tilted("good6", 1.0, False)], [bare], progress=False, curves=True)
    fig = trial_figure(rep, bare)
    try:
        axes = fig.get_axes()
        assert [ax.get_title(loc="left") for ax in axes] == [
            TITLES[k] for k in ("roll", "pitch", "inclination")
        ]
        assert all(not ax.patches for ax in axes)
        assert "marks no movement phases" in axes[-1].get_xlabel() and "shaded" not in axes[-1].get_xlabel()
    finally:
        plt.close(fig)


def test_groups_figure_separates_six_and_nine_axis_with_fitting_scales(report_and_recs: Any) -> None:
    need_mpl()
    from attica.evaluate.plots import _pyplot, groups_figure

    report, _ = report_and_recs
    plt = _pyplot()
    fig = groups_figure(report)
    try:
        _check_figure(
            fig,
            ["6-axis: inclination RMSE", "9-axis: total RMSE"],
            [["good6", "bad6"], ["a9", "b9", "flagged9"]],
            ["log", "linear"],
        )
        labels = [t.get_text() for t in fig.get_axes()[0].get_xticklabels()]
        assert labels == [*report.groups, "average"]
    finally:
        plt.close(fig)
    # only one kind of method: one chart
    fig = groups_figure(report, ["a9", "b9"])
    try:
        assert [ax.get_title(loc="left") for ax in fig.get_axes()] == ["9-axis: total RMSE"]
    finally:
        plt.close(fig)
    assert groups_figure(report, []) is None


def need_mpl() -> None:
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        need(False, "matplotlib is not installed (pip install '.[eval]')")


@pytest.fixture(scope="module")
def trial_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    data = tmp_path_factory.mktemp("trials")
    for r in _recs():
        r.save(data / f"{r.name}.npz")
    return data


def test_eval_output_fits_110_columns_unless_wide(
    trial_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Every attica filter (and variant) at both presets: the 6-axis columns in two tables at 110, the
    9-axis ones in one."""
    args = ["eval", "--data", str(trial_dir), "--preset", "both", "-q"]
    assert main(args) == 0
    text = capsys.readouterr().out
    body = text.split("\n", 1)[1]  # the first line names the data directory (a long tmp path here)
    assert max(len(ln) for ln in body.splitlines()) <= 110
    assert "6-axis: inclination RMSE (deg), part 1 of 2" in text and "9-axis: total RMSE (deg)" in text
    for name in [n for label in [*kinds.labels(), *VARIANTS] for n in (label, f"{label}@seed")]:
        assert f" {name} " in f" {text} ".replace("\n", " ")
    assert main([*args, "--wide"]) == 0
    wide = capsys.readouterr().out
    assert "part 1" not in wide and max(len(ln) for ln in wide.splitlines()) > 110


def test_eval_writes_plots_per_trial_and_per_group(trial_dir: Path, tmp_path: Path) -> None:
    need_mpl()
    out = tmp_path / "new" / "out"  # created, parents too
    assert main(["eval", "--data", str(trial_dir), "--filter", "ars,mars", "--out", str(out), "-q"]) == 0
    names = sorted(p.name for p in out.glob("*.png"))
    assert names == [f"error_{t}.png" for t in TRIALS] + ["groups.png"]
    for name in names:
        head = (out / name).read_bytes()[:24]
        assert head[:8] == b"\x89PNG\r\n\x1a\n" and int.from_bytes(head[16:20], "big") == 1600
    assert (out / "results.json").is_file()
    assert main(["eval", "--data", str(trial_dir), "--filter", "ars", "--out", str(out), "--no-plots"]) == 0


def test_eval_refuses_before_any_work(
    trial_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    cases = [
        (["--out", str(blocker / "sub")], "cannot create output directory"),
        (["--out", str(blocker)], "exists and is not a directory"),
        (["--peers", ","], "--peers: empty selection"),
        (["--peers", "vqf9,nosuch"], "unknown peer(s) nosuch"),
        (["--filter", "ars,,"], None),
        (["--filter", " , "], "empty filter selection"),
        (["--filter", "madgwick"], "unknown filter 'madgwick'"),
    ]
    for extra, message in cases:
        code = main(["eval", "--data", str(trial_dir), "-q", "--no-plots", *extra])
        cap = capsys.readouterr()
        if message is None:
            assert code == 0, cap.err
            continue
        assert code == 2 and cap.err.startswith("attica: error: ") and message in cap.err, (extra, cap.err)
        assert "trials" not in cap.out  # nothing was loaded or run


def test_eval_set_changes_attica_settings(trial_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`attica eval --set` (issue 23's settings evaluated from the CLI): the setting goes to the kinds that
    have it, the method's name shows it, and the figure is that of the filter with it; a bad value, an
    unknown name, --grid or --suite with it are refused before anything runs."""
    from attica.evaluate import attica_method, run_methods
    from attica.evaluate.core import load_trials
    from attica.settings import FilterKind

    base = ["eval", "--data", str(trial_dir), "-q", "--no-plots", "--filter", "mars,ars"]
    assert main([*base, "--set", "tau_mag=7", "--set", "recovery_time=3"]) == 0
    cap = capsys.readouterr()
    assert "mars[tau_mag=7.0,recovery_time=3.0]" in cap.out and "ars[recovery_time=3.0]" in cap.out
    assert "applies to mars only" in cap.err  # ars has no tau_mag
    recs = load_trials(str(trial_dir))
    m = attica_method(FilterKind.MARS, overrides={"tau_mag": 7.0, "recovery_time": 3.0})
    total = run_methods([m], recs, progress=False).result(m.name).mean("total")
    line = next(ln for ln in cap.out.splitlines() if ln.startswith("mars[tau_mag=7.0,recovery_time=3.0] "))
    assert line.split()[1] == f"{total:.2f}"
    for extra, message in (
        (["--set", "hard_iron_tau=-1"], "hard_iron_tau = -1.0 is out of range"),
        (["--set", "nosuch=1"], "no setting 'nosuch'"),
        (["--set", "tau_mag=7", "--grid"], "drop one"),
        (["--set", "use_mag=true"], "--filter mekf (9-axis) or mekf6"),  # the axes it is judged by
    ):
        assert main([*base, *extra]) == 2
        cap = capsys.readouterr()
        assert "attica: error: " in cap.err and message in cap.err, (extra, cap.err)
        assert "trials" not in cap.out
    assert main(["eval", "--suite", "--set", "tau_mag=7"]) == 2
    assert "drop --set" in capsys.readouterr().err


def test_eval_plots_with_set_pair_each_method_with_its_seed(trial_dir: Path, tmp_path: Path) -> None:
    """With --set the methods' names carry the change (mars[gyro_range=30.0], mars@seed[gyro_range=30.0]):
    the plots still leave the baselines out and pair each filter with its seed preset (groups_seed.png
    was silently missing and the gyro-only baseline drawn among the filters: a review)."""
    from attica.evaluate.plots import _label, _seed_name

    assert _label("gyro[gyro_range=30.0]") == "gyro" and _label("mars") == "mars"
    assert (
        _seed_name("mars[gyro_range=30.0]") == "mars@seed[gyro_range=30.0]"
        and _seed_name("ars") == "ars@seed"
    )
    out = tmp_path / "out"
    args = ["eval", "--data", str(trial_dir), "--filter", "mars,gyro", "--preset", "both", "-q"]
    assert main([*args, "--set", "gyro_range=30", "--out", str(out)]) == 0
    assert (out / "groups.png").exists() and (out / "groups_seed.png").exists()

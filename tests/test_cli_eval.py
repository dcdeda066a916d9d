"""attica eval's output: tables within 110 columns (or --wide), plots readable at a glance.

The plots are checked on the figures themselves: 6-axis inclination and 9-axis total on separate
charts, a log scale on the chart where one method dominates (linear elsewhere), every legend right of
its chart's data, 1600 px wide.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from attica import kinds
from attica.cli import main
from attica.data import Recording, broad_groups
from attica.evaluate import VARIANTS, Method, run_methods
from attica.metrics import quat_mul
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


@pytest.fixture(scope="module")
def report_and_recs() -> tuple[Any, list[Recording]]:
    # 6-axis: one method 40x worse than the other (log scale); 9-axis: close together (linear)
    methods = [
        _tilted("good6", 1.0, False),
        _tilted("bad6", 40.0, False),
        _tilted("a9", 2.0, True),
        _tilted("b9", 3.0, True),
    ]
    recs = _recs()
    return run_methods(methods, recs, progress=False, curves=True), recs


def _check_figure(fig: Any, titles: list[str], legends: list[list[str]], scales: list[str]) -> None:
    fig.canvas.draw()
    assert round(fig.get_size_inches()[0] * fig.dpi) == 1600
    axes = fig.get_axes()
    assert [ax.get_title(loc="left") for ax in axes] == titles
    for ax, names, scale in zip(axes, legends, scales, strict=True):
        leg = ax.get_legend()
        assert [t.get_text() for t in leg.get_texts()] == names
        assert ax.get_yscale() == scale, (ax.get_title(loc="left"), ax.get_yscale())
        # the legend is right of the data, inside the figure
        box, data = leg.get_window_extent(), ax.get_window_extent()
        assert box.x0 >= data.x1 - 0.5 and box.x1 <= fig.bbox.x1 + 0.5


def test_plots_separate_six_and_nine_axis_with_fitting_scales(report_and_recs: Any) -> None:
    need_mpl()
    from attica.evaluate.plots import _pyplot, groups_figure, trial_figure

    report, recs = report_and_recs
    plt = _pyplot()
    fig = trial_figure(report, recs[0])
    try:
        _check_figure(
            fig,
            ["6-axis: inclination error", "9-axis: total error"],
            [["good6", "bad6"], ["a9", "b9"]],
            ["log", "linear"],
        )
        assert fig.get_axes()[1].get_ylim()[0] == 0.0  # a linear error axis starts at 0
    finally:
        plt.close(fig)
    fig = groups_figure(report)
    try:
        _check_figure(
            fig,
            ["6-axis: inclination RMSE", "9-axis: total RMSE"],
            [["good6", "bad6"], ["a9", "b9"]],
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

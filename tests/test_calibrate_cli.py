"""``attica calibrate mag|gyro|accel``: output, the calibration file, --update merging, plots, errors."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from attica.calibration import Calibration
from attica.cli import main
from attica.sim import SimConfig
from attica.sim.calib_motion import mag_sweep, static_poses
from attica.sim.errors import draw_errors

TRUTH = draw_errors(1)


@pytest.fixture(scope="module")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("rec")
    paths = {
        "mag": d / "sweep.npz",
        "mag_csv": d / "sweep.csv",
        "low": d / "low.npz",
        "static": d / "static.npz",
        "four": d / "four.csv",
    }
    sweep = mag_sweep(SimConfig(duration=40.0, rate=100.0, seed=2), TRUTH)
    sweep.save(paths["mag"])
    sweep.save(paths["mag_csv"])
    mag_sweep(SimConfig(duration=40.0, rate=100.0, seed=2), TRUTH, extent=0.3).save(paths["low"])
    static_poses(SimConfig(rate=100.0, seed=4), TRUTH, poses=12).save(paths["static"])
    static_poses(SimConfig(rate=100.0, seed=4), TRUTH, poses=4).save(paths["four"])
    return paths


def test_fit_each_sensor_into_one_file(
    recordings: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cal = tmp_path / "cal.json"
    assert main(["calibrate", "gyro", str(recordings["static"]), "-o", str(cal)]) == 0
    out = capsys.readouterr().out
    assert "gyro fit: " in out and "offset o" in out and f"wrote {cal} (gyro section)" in out
    assert main(["calibrate", "accel", str(recordings["static"]), "--update", str(cal)]) == 0
    out = capsys.readouterr().out
    assert "12 distinct positions" in out and "misalignment" in out and "kept gyro" in out
    png = tmp_path / "mag.png"
    args = ["calibrate", "mag", str(recordings["mag_csv"]), "--update", str(cal), "--field", "49"]
    assert main([*args, "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert "coverage" in out and "hard iron h" in out and "residual | |m| - B |: before rms" in out
    assert "kept gyro, accel" in out
    assert png.stat().st_size > 20_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    got = Calibration.load(cal)
    assert set(json.loads(cal.read_text())["fit"]) == {"gyro", "accel", "mag"}
    assert np.max(np.abs(np.array(got.gyro.offset) - TRUTH.gyro.offset)) < 5e-4
    assert np.max(np.abs(np.array(got.accel.offset) - TRUTH.accel.offset)) < 0.01
    assert np.max(np.abs(np.array(got.mag.hard_iron) - TRUTH.mag.hard_iron)) < 0.1
    assert np.max(np.abs(np.array(got.mag.soft_iron) - np.array(TRUTH.mag.soft_iron))) < 0.003
    # refitting one section leaves the others as they were
    assert main(["calibrate", "gyro", str(recordings["static"]), "--update", str(cal)]) == 0
    again = Calibration.load(cal)
    assert again.mag == got.mag and again.accel == got.accel and again.gyro == got.gyro


def test_plots_for_gyro_and_accel(recordings: dict[str, Path], tmp_path: Path) -> None:
    for sensor in ("gyro", "accel"):
        png = tmp_path / f"{sensor}.png"
        assert main(["calibrate", sensor, str(recordings["static"]), "--plot", str(png)]) == 0
        assert png.stat().st_size > 20_000


def test_without_output_nothing_is_written(
    recordings: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["calibrate", "mag", str(recordings["mag"])]) == 0
    assert "no calibration file written" in capsys.readouterr().out


@pytest.mark.parametrize(
    "args,message",
    [
        (["mag", "{d}/missing.npz"], "no such recording: "),
        (
            ["mag", "{low}"],
            r"calibrate mag: the recording covers \d+% of the sphere, a magnetometer fit needs 50%",
        ),
        (["accel", "{four}"], "calibrate accel: 4 distinct still position"),
        (["gyro", "{mag}"], "calibrate gyro: 0.0 s of the recording is still"),
        (["mag", "{mag}", "--update", "{d}/none.json"], "--update .*none.json: no such calibration file"),
        (["mag", "{mag}", "-o", "{d}/no/such/dir/cal.json"], "directory .* does not exist"),
        (["mag", "{mag}", "--plot", "{d}/x.jpg"], "the plot is a .png file"),
        (["gyro", "{mag}", "--field", "49"], "--field applies to 'calibrate mag', not gyro"),
        (["mag", "{mag}", "--min-coverage", "50"], "--min-coverage is a fraction"),
        (["mag", "{mag}", "--field", "-3"], "--field must be > 0"),
        (["mag", "{static}", "--update", "{bad}"], "--update: .*bad.json: not JSON"),
    ],
)
def test_errors(
    recordings: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    args: list[str],
    message: str,
) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text("{")
    names = {k: str(v) for k, v in recordings.items()}
    argv = ["calibrate", *(a.format(d=tmp_path, bad=bad, **names) for a in args)]
    assert main(argv) == 2
    captured = capsys.readouterr()
    lines = [ln for ln in captured.err.splitlines() if ln.startswith("attica: error:")]
    assert len(lines) == 1, captured.err
    assert re.search(message, lines[0]), lines[0]
    assert "Traceback" not in captured.err


def test_bad_path_is_refused_before_the_work(
    recordings: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["calibrate", "mag", str(recordings["mag"]), "-o", str(tmp_path / "nodir" / "c.json")]
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert "mag fit" not in captured.out and "samples at" not in captured.out

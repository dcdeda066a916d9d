"""The attica command: sim, run, demo and their error messages."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from attica.cli import main
from attica.data import load_recording


def test_demo_reports_bit_exact(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["demo", "--duration", "10", "-q"]) == 0
    out = capsys.readouterr().out
    assert "steps compared, 0 differ: bit-exact" in out
    assert "RMSE inclination" in out


def test_sim_then_run_every_filter(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "sim.npz"
    assert main(["sim", "--duration", "12", "--seed", "3", "-o", str(path)]) == 0
    rec = load_recording(path)
    assert rec.quat_true is not None and len(rec.gyr) == round(12 * 285.714)
    out_path = tmp_path / "out.npz"
    assert main(["run", "--filter", "all", "--data", str(path), "-q", "--check", "-o", str(out_path)]) == 0
    out = capsys.readouterr().out
    for kind in ("ars", "mars", "kf", "ekf", "gyro", "tilt"):
        assert f"{kind}:" in out
        assert np.load(tmp_path / f"out_{kind}.npz")["q"].shape == (len(rec.gyr), 4)
    assert out.count("0 differ: bit-exact") == 6
    assert "heading" in out  # the 9-axis filter is judged by total and heading too


def test_run_with_settings(capsys: pytest.CaptureFixture[str]) -> None:
    args = ["run", "--filter", "ars", "--duration", "12", "-q", "--set", "tau=0.5"]
    args += ["--set", "bias_mode=frozen"]
    assert main(args) == 0
    assert "ars:" in capsys.readouterr().out


@pytest.mark.parametrize(
    "args,message",
    [
        (["run", "--filter", "ars", "--set", "gian=0.2"], "has no setting 'gian'"),
        (["run", "--filter", "ars", "--set", "tau"], "expects name=value"),
        (["run", "--filter", "ars", "--set", "tau=fast"], "--set tau"),
        (["run", "--filter", "ars", "--set", "bias_init=1,2"], "3 comma-separated numbers"),
        (["run", "--data", "/nonexistent/x.npz"], "no such recording"),
        (["run", "--filter", "ars", "--set", "dt=-1"], "dt is the recording's sample period"),
        (["run", "--filter", "ars", "--set", "tau=0", "--set", "gain=5"], "out of range"),
        (["run", "--filter", "ars", "--set", "gain=0.3", "--set", "tau=0.5"], "gain=0.3 (a per-sample gain)"),
        (
            ["sim", "--duration", "6", "--breaks", "2", "-o", "/tmp/never.npz"],
            "use a longer --duration or fewer",
        ),
    ],
)
def test_errors_are_clear(args: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([*args, "-q"] if args[0] == "run" else args) == 2
    assert message in capsys.readouterr().err

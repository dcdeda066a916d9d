"""The simulation options of the CLI beyond length and rate: ``--condition``, ``--grade``, ``--declination``.

``attica sim / run / demo / view --condition NAME`` simulate a condition of the generalisation suite (the
same recording as the suite's for its seeds); ``--grade`` a sensor grade; ``--declination`` the field's
declination in degrees. A simulated gyro that clips gives its range to the filters, as the suite does.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from attica.cli import main
from attica.commands._common import CONDITION_NAMES, GRADE_NAMES
from attica.data import load_recording
from attica.sim import GRADES, SimConfig, simulate
from attica.sim.conditions import CLIP, CONDITIONS, condition


def _sim(tmp_path: Path, *args: str) -> object:
    path = tmp_path / "s.npz"
    assert main(["sim", *args, "-o", str(path)]) == 0
    return load_recording(path)


def test_the_help_names_every_condition_and_grade() -> None:
    assert CONDITION_NAMES == tuple(c.name for c in CONDITIONS)
    assert GRADE_NAMES == tuple(GRADES)


def test_a_condition_is_the_suites_recording(tmp_path: Path) -> None:
    rec = _sim(tmp_path, "--condition", "clipped", "--seed", "3")
    want = simulate(condition("clipped").config(3))
    assert rec.gyr.tobytes() == want.gyr.astype(np.float32).tobytes()  # type: ignore[attr-defined]
    assert rec.mag.tobytes() == want.mag.astype(np.float32).tobytes()  # type: ignore[attr-defined]
    assert np.abs(rec.gyr).max() == np.float32(CLIP)  # type: ignore[attr-defined]


def test_options_given_replace_the_conditions(tmp_path: Path) -> None:
    """A shorter rate-50 run is the condition's with duration 10: its rate, its noise densities."""
    rec = _sim(tmp_path, "--condition", "rate-50", "--duration", "10", "--seed", "2")
    cond = condition("rate-50")
    want = simulate(dataclasses.replace(cond, sim={**cond.sim, "duration": 10.0}).config(2))
    assert rec.rate == 50.0 and len(rec.gyr) == 500  # type: ignore[attr-defined]
    assert rec.gyr.tobytes() == want.gyr.astype(np.float32).tobytes()  # type: ignore[attr-defined]
    # a rate given to the baseline keeps its noise densities (Condition.config), as rate-50 does
    base = _sim(tmp_path, "--condition", "baseline", "--rate", "50", "--duration", "10", "--seed", "2")
    assert base.gyr.tobytes() == rec.gyr.tobytes()  # type: ignore[attr-defined]


def test_grade_and_declination(tmp_path: Path) -> None:
    rec = _sim(
        tmp_path,
        "--grade",
        "industrial",
        "--declination",
        "-12.5",
        "--duration",
        "8",
        "--seed",
        "4",
        "--breaks",
        "1",
    )
    cfg = SimConfig(duration=8.0, seed=4, taps=3, rest_breaks=1)
    cfg = dataclasses.replace(GRADES["industrial"].config(cfg), mag_declination=math.radians(-12.5))
    want = simulate(cfg)
    assert rec.gyr.tobytes() == want.gyr.astype(np.float32).tobytes()  # type: ignore[attr-defined]
    assert rec.mag.tobytes() == want.mag.astype(np.float32).tobytes()  # type: ignore[attr-defined]
    plain = _sim(tmp_path, "--grade", "industrial", "--duration", "8", "--seed", "4", "--breaks", "1")
    assert plain.mag.tobytes() != rec.mag.tobytes()  # type: ignore[attr-defined]
    # the grade of a condition is replaced by --grade
    ind = _sim(tmp_path, "--condition", "consumer", "--grade", "industrial", "--seed", "1")
    assert ind.gyr.tobytes() == simulate(condition("industrial").config(1)).gyr.astype(np.float32).tobytes()  # type: ignore[attr-defined]


def test_declination_reaches_the_heading(capsys: pytest.CaptureFixture[str]) -> None:
    """The truth's yaw is from true north: a declined field costs the heading unless the setting is given."""
    argv = ["run", "--filter", "mars", "--declination", "20", "--duration", "30", "-q"]
    assert main(argv) == 0
    off = capsys.readouterr().out
    assert main([*argv, "--set", f"declination={math.radians(20.0)}"]) == 0
    on = capsys.readouterr().out
    heading = [float(t.split("heading")[1].split()[0]) for t in (off, on)]
    assert heading[0] > 15.0 and heading[1] < 3.0, heading


def test_a_clipping_sensor_gives_its_range(capsys: pytest.CaptureFixture[str]) -> None:
    base = ["run", "--condition", "clipped", "--seed", "3", "--duration", "30", "--filter", "ars,tilt", "-q"]
    assert main(base) == 0
    cap = capsys.readouterr()
    assert f"gyro_range={CLIP:.6g} for ars, as the suite gives it" in cap.err  # tilt has no gyro_range
    assert main([*base, "--set", f"gyro_range={CLIP!r}"]) == 0
    given = capsys.readouterr()
    assert "as the suite gives it" not in given.err
    line = [x for x in cap.out.splitlines() if "ars:" in x]
    assert line == [x for x in given.out.splitlines() if "ars:" in x]
    assert main([*base, "--set", "gyro_range=34.9"]) == 0  # the user's range stands
    other = capsys.readouterr().out
    assert [x for x in other.splitlines() if "ars:" in x] != line
    assert main(["run", "--condition", "baseline", "--duration", "10", "-q"]) == 0
    assert "clips" not in capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["sim", "--condition", "windy", "-o", "{tmp}/x.npz"],
            "--condition 'windy': unknown; the conditions are: baseline",
        ),
        (["sim", "--declination", "200", "-o", "{tmp}/x.npz"], "--declination must be in [-180, 180] deg"),
        (["sim", "--grade", "military", "-o", "{tmp}/x.npz"], "invalid choice: 'military'"),
        (["run", "--data", "{tmp}/r.npz", "--condition", "clipped"], "--condition describes a simulation"),
    ],
)
def test_refusals(tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str) -> None:
    simulate(SimConfig(duration=2.0)).save(tmp_path / "r.npz")
    with pytest.raises(SystemExit) if "invalid choice" in message else contextlib.nullcontext():
        assert main([a.format(tmp=tmp_path) for a in argv]) == 2
    assert message in capsys.readouterr().err


def test_a_short_condition_keeps_what_fits(capsys: pytest.CaptureFixture[str]) -> None:
    """As without --condition, a short run keeps the still pauses that fit (and --breaks is the user's)."""
    assert main(["run", "--condition", "baseline", "--duration", "8", "-q"]) == 0
    capsys.readouterr()
    assert main(["run", "--condition", "baseline", "--duration", "8", "--breaks", "2", "-q"]) == 2
    assert "do not fit" in capsys.readouterr().err


def test_notes_where_the_simulation_is_not_given_to_the_filter(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--declination", "10", "--duration", "10", "--filter", "mars,ars", "-q"]) == 0
    err = capsys.readouterr().err
    assert "declined by 10 deg, and mars keeps a magnetic heading" in err and "declination=0.174533" in err
    argv = ["run", "--declination", "10", "--duration", "10", "--filter", "mars", "-q"]
    assert main([*argv, "--set", "declination=0.1745"]) == 0
    assert "declined" not in capsys.readouterr().err
    # a node on its init settings (the CAN commands, view --demo): the clipping is the user's to give it
    assert main(["verify", "--with-node", "--condition", "clipped", "--count", "500", "-q"]) == 0
    assert "the node keeps its own gyro_range" in capsys.readouterr().err
    assert (
        main(
            ["verify", "--with-node", "--condition", "clipped", "--count", "500", "-q"]
            + ["--set", "gyro_range=8.7266"]
        )
        == 0
    )
    assert "keeps its own gyro_range" not in capsys.readouterr().err


def test_runs_without_a_moving_sample_and_late_scoring_say_so(capsys: pytest.CaptureFixture[str]) -> None:
    """A simulation that is all rest has nothing to score (not 'RMSE nan'); mag-start's suite score
    starts at 15 s, which run says."""
    assert main(["run", "--condition", "baseline", "--duration", "5", "-q"]) == 0
    out = capsys.readouterr().out
    assert "no moving sample to score" in out and "nan" not in out
    assert main(["run", "--condition", "mag-start", "--duration", "20", "--filter", "mars", "-q"]) == 0
    assert "the suite scores mag-start from 15 s" in capsys.readouterr().err

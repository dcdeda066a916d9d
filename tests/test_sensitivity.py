"""``python -m attica_dev.sensitivity``: its scoring is the suite's, its leave-one-out is right, and
docs/accuracy.md's tables ("What the defaults trade") are what it computes, to the digits printed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from attica.evaluate import load_trials
from attica.evaluate.suite import condition, run_case
from attica.tuning import GridResult, leave_one_out
from attica_dev import sensitivity

from helpers import BROAD, broad_trials

DOC = Path(__file__).resolve().parent.parent / "docs" / "accuracy.md"


def test_the_grids_leave_one_out_by_hand() -> None:
    """attica.tuning.leave_one_out, which the tool's BROAD figure is: rows values, columns trials.
    Without trial 0 the row means are (2, 2.5, 1.5): row 2, which scores 9 on trial 0; without trial 1
    (0.5, 2, 5.5): row 0, scoring 3; without trial 2 (1.5, 1.5, 5): a tie of rows 0 and 1, the first
    taken, scoring 1. A row with a NaN trial is never chosen; one trial is refused."""
    s = np.array([[0.0, 3.0, 1.0], [1.0, 2.0, 3.0], [9.0, 1.0, 2.0]])
    errors = np.repeat(s[:, :, None], 3, axis=2)
    grid = GridResult([{"x": i} for i in range(3)], ["a", "b", "c"], errors, "inclination")
    loo = leave_one_out(grid)
    assert loo.chosen == [2, 0, 0]
    assert loo.mean == pytest.approx((9.0 + 3.0 + 1.0) / 3)
    errors[2, 1] = np.nan
    assert 2 not in leave_one_out(grid).chosen
    with pytest.raises(ValueError, match="at least two trials"):
        leave_one_out(GridResult([{"x": 0}], ["a"], errors[:1, :1], "inclination"))


def test_parse_values() -> None:
    for method, field, text, want in (
        ("mekf6", "tau_acc_lp", "1.25, 1.45", (1.25, 1.45)),
        ("ars", "bias_n_max", "10,20", (10, 20)),
        ("ars", "init_from_accel", "true,0", (True, False)),
    ):
        got = sensitivity.parse_values(method, field, text)
        assert got == want
        assert [type(v) for v in got] == [type(v) for v in want], f"{field}: typed as its default"
    for method, field, text, msg in (
        ("mekf", "tau_mag", "1", "has no setting 'tau_mag'"),
        ("mars", "tau_mag", "10,x", "cannot read 'x' as a float"),
        ("ars", "bias_n_max", "1.5", "cannot read '1.5' as a int"),
        ("ars", "init_from_accel", "yes", "cannot read 'yes' as a bool"),
        ("mars", "tau_mag", "10,10", "distinct"),
        ("mars", "q_init", "1", "not a number or a flag"),
        ("mars", "integration", "1", "not a number or a flag"),
        ("mekf", "use_mag", "true,false", "switches the magnetometer"),
        ("ars", "gyro_range", "5,10", "gyro_range is the sensor's"),
        ("nope", "tau_mag", "1", "unknown filter"),
    ):
        with pytest.raises(ValueError, match=msg):
            sensitivity.parse_values(method, field, text)


def test_cli_errors(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    for argv, msg in (
        (["mars", "gain", "1"], "has no setting 'gain'"),
        (["mars", "tau_mag", "10,10"], "give distinct values, got '10,10'"),
        (["mars", "tau_mag", "10", "--conditions", "nowhere"], "unknown condition 'nowhere'; conditions: "),
        (["mars", "tau_mag", "10", "--seeds", "0"], "--seeds must be at least 1"),
        (["mars", "tau_mag", "10", "-j", "0"], "--jobs must be at least 1"),
        (["mars", "tau_mag", "10", "--data", "/no/such/dir"], "no such file or directory"),
        (["mars", "tau_mag", "10", "--data", str(tmp_path)], "no recordings"),
    ):
        with pytest.raises(SystemExit) as exc:
            sensitivity.main(argv)
        assert exc.value.code == 2
        assert msg in capsys.readouterr().err


@pytest.mark.parametrize(
    ("method", "field", "values", "cond"),
    [
        ("ars", "gain", (1.0, 0.5), "consumer"),
        ("mars", "tau_mag", (20.0, 10.0), "consumer"),
        ("ars", "tau_acc_lp", (1.5, 1.0), "clipped"),
    ],
)
def test_scores_are_the_suites(method: str, field: str, values: tuple[float, float], cond: str) -> None:
    """The default's row and the peer's are ``attica eval --suite``'s figures of that case (on the
    clipped condition with the sensor's gyro range given to both, as the suite does)."""
    c = condition(cond)
    peer = "vqf9" if method == "mars" else "vqf6"
    s = sensitivity.measure(method, field, values, [c], [3])
    case = run_case(c, 3, [method], [peer])
    metric = "total" if method == "mars" else "inclination"
    assert s.suite[cond][0] == getattr(case.errors[method], metric)
    assert s.suite["<peer>" + cond][0] == getattr(case.errors[peer], metric)
    assert s.suite[cond][1] != s.suite[cond][0], "the setting must reach the filter"


def _doc_table(title: str) -> list[list[str]]:
    text = DOC.read_text(encoding="utf-8")
    start = text.index(f"| {title} |")
    return [
        [c.strip().strip("*") for c in r.strip("|").split("|")]
        for r in text[start:].split("\n\n")[0].splitlines()
    ]


TABLES = {
    "mekf6, `tau_acc_lp`": ("mekf6", "tau_acc_lp", "1.25,1.45,1.6"),
    "mekf, `mag_noise`": ("mekf", "mag_noise", "0.2,0.3,0.6,0.9"),
    "mars, `tau_mag`": ("mars", "tau_mag", "10,20"),
    "mekf6, `tau_acc_lp_no_rest`": ("mekf6", "tau_acc_lp_no_rest", "0,1.25"),
    "mekf, `tau_acc_lp_no_rest`": ("mekf", "tau_acc_lp_no_rest", "0,1.25"),
}


@pytest.mark.parametrize("title", list(TABLES))
def test_doc_table(title: str) -> None:
    broad_trials()
    method, field, text = TABLES[title]
    header, _, *rows = _doc_table(title)
    conds = header[1:-2]
    assert header[-2:] == ["BROAD", "BROAD, left out"]
    values = sensitivity.parse_values(method, field, text)
    recs = load_trials(BROAD)
    s = sensitivity.measure(method, field, values, [condition(c) for c in conds], range(1, 11), recs, jobs=2)
    assert s.broad is not None
    assert s.broad.points == [{field: v} for v in values], "the value's grid, in the values' order"
    result = leave_one_out(s.broad)
    loo, picks = result.mean, result.chosen
    assert len(set(picks)) == 1, "the page says every fold chose the same value"
    for i, v in enumerate(values):
        cells = rows[i]
        assert float(cells[0]) == v
        want = [f"{s.suite[c][i]:.3f}" for c in conds] + [f"{s.broad.scores()[i].mean():.4f}"]
        want.append(f"{loo:.4f}" if picks[0] == i else "")
        assert cells[1:] == want, f"{title}, {v}: the page says {cells[1:]}, the tool computes {want}"
    vqf = rows[len(values)]
    assert vqf[0].startswith("VQF")
    assert vqf[1 : 1 + len(conds)] == [f"{s.suite['<peer>' + c][0]:.3f}" for c in conds]


def test_parse_fixed() -> None:
    got = sensitivity.parse_fixed("ars", "gain", " tau_acc_lp=1 , bias_n_max=20,init_from_accel=false")
    assert got == {"tau_acc_lp": 1.0, "bias_n_max": 20, "init_from_accel": False}
    assert [type(v) for v in got.values()] == [float, int, bool], "typed as the defaults"
    assert sensitivity.parse_fixed("mekf6", "tau_acc_lp", "gyro_noise=7e-5,bias_noise=5e-5") == {
        "gyro_noise": 7e-5,
        "bias_noise": 5e-5,
    }
    for text, msg in (
        ("gyro_noise", "is not name=value"),
        ("gyro_noise=", "is not name=value"),
        ("=1", "is not name=value"),
        ("tau_acc_lp=1", "is the setting varied"),
        ("gyro_noise=1e-4,gyro_noise=2e-4", "given twice"),
        ("gyro_noise=x", "cannot read 'x' as a float"),
        ("tau_mag=1", "has no setting 'tau_mag'"),
        ("use_mag=true", "switches the magnetometer"),
        ("gyro_range=5", "gyro_range is the sensor's"),
    ):
        with pytest.raises(ValueError, match=msg):
            sensitivity.parse_fixed("mekf6", "tau_acc_lp", text)


def test_cli_with(capsys: pytest.CaptureFixture[str]) -> None:
    """--with reaches the filter (the row differs from the defaults') and is named in the heading."""
    argv = ["mekf6", "gyro_rate_noise", "0.01", "--conditions", "industrial", "--seeds", "1", "--no-peer"]
    assert sensitivity.main(argv) == 0
    plain = capsys.readouterr().out
    assert sensitivity.main([*argv, "--with", "gyro_noise=7e-5,bias_noise=5e-5"]) == 0
    held = capsys.readouterr().out
    assert "mekf6, with gyro_noise=7e-05, bias_noise=5e-05: mean of 1 seeds" in held
    assert plain.splitlines()[2] != held.splitlines()[2], "the held settings must reach the filter"
    with pytest.raises(SystemExit) as exc:
        sensitivity.main([*argv, "--with", "gyro_rate_noise=0.1"])
    assert exc.value.code == 2
    assert "is the setting varied" in capsys.readouterr().err


HELD = "gyro_noise=7e-5,bias_noise=5e-5,gyro_scale_sd=0.002"
"""The suite's industrial gyro (attica.sim.GRADES) as mekf settings, docs/accuracy.md."""

TABLES_HELD = {
    f"{m}, the industrial gyro's figures, `gyro_rate_noise`": (m, "gyro_rate_noise", "0.01,0.002", HELD)
    for m in ("mekf6", "mekf")
}


def test_held_settings_on_broad() -> None:
    """With trials, the held settings are in every grid point (each value's own, in the values' order)."""
    broad_trials()
    recs = load_trials(BROAD)[:2]
    fixed = {"gyro_noise": 7e-5}
    s = sensitivity.measure("mekf6", "tau_acc_lp", (1.25, 1.45), [], [1], recs, peer=False, fixed=fixed)
    assert s.broad is not None
    assert s.broad.points == [{"tau_acc_lp": v, "gyro_noise": 7e-5} for v in (1.25, 1.45)]
    plain = sensitivity.measure("mekf6", "tau_acc_lp", (1.25,), [], [1], recs, peer=False)
    assert plain.broad is not None
    assert s.broad.scores()[0].tolist() != plain.broad.scores()[0].tolist(), "held settings reach the filter"


@pytest.mark.parametrize("title", list(TABLES_HELD))
def test_doc_table_held(title: str) -> None:
    """docs/accuracy.md, "A gyro's own figures as settings": the tables are the tool's, and the held
    figures are the simulator's industrial grade."""
    from attica.sim import GRADES

    g = GRADES["industrial"]
    method, field, text, held = TABLES_HELD[title]
    fixed = sensitivity.parse_fixed(method, field, held)
    assert fixed == {
        "gyro_noise": g.gyro_noise_density,
        "bias_noise": g.gyro_bias_drift,
        "gyro_scale_sd": g.errors.gyro_scale,
    }
    values = sensitivity.parse_values(method, field, text)
    assert values[1] == g.errors.gyro_scale
    header, _, *rows = _doc_table(title)
    conds = header[1:]
    s = sensitivity.measure(method, field, values, [condition(c) for c in conds], range(1, 11), fixed=fixed)
    assert s.fixed == fixed
    for i, v in enumerate(values):
        assert float(rows[i][0]) == v
        assert rows[i][1:] == [f"{s.suite[c][i]:.3f}" for c in conds], f"{title}, {v}"
    assert rows[len(values)][0].startswith("VQF")
    assert rows[len(values)][1:] == [f"{s.suite['<peer>' + c][0]:.3f}" for c in conds]

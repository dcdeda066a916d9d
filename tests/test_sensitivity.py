"""``python -m attica_dev.sensitivity``: its scoring is the suite's, its leave-one-out is right, and
docs/accuracy.md's tables ("What the defaults trade") are what it computes, to the digits printed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from attica.evaluate.suite import condition, run_case
from attica_dev import sensitivity

from helpers import BROAD, broad_trials

DOC = Path(__file__).resolve().parent.parent / "docs" / "accuracy.md"


def test_leave_one_out_by_hand() -> None:
    # rows: values, columns: trials. Without trial 0 the row means are (2, 3, 1.5) -> row 2 (scores 9);
    # without trial 1: (1, 2, 5) -> row 0 (scores 3); without trial 2: (2, 2.5, 5) -> row 0 (scores 1).
    s = np.array([[0.0, 3.0, 1.0], [1.0, 2.0, 3.0], [9.0, 1.0, 2.0]])
    mean, picks = sensitivity.leave_one_out(s)
    assert picks == [2, 0, 0]
    assert mean == pytest.approx((9.0 + 3.0 + 1.0) / 3)
    with pytest.raises(ValueError, match="2\\+ trials"):
        sensitivity.leave_one_out(np.ones((3, 1)))


def test_parse_values() -> None:
    assert sensitivity.parse_values("mekf6", "tau_acc_lp", "1.25, 1.45") == (1.25, 1.45)
    assert sensitivity.parse_values("ars", "bias_n_max", "10,20") == (10, 20)
    assert sensitivity.parse_values("mekf", "use_mag", "true,0") == (True, False)
    with pytest.raises(ValueError, match="has no setting 'tau_mag'"):
        sensitivity.parse_values("mekf", "tau_mag", "1")
    with pytest.raises(ValueError, match="cannot read 'x'"):
        sensitivity.parse_values("mars", "tau_mag", "10,x")
    with pytest.raises(ValueError, match="distinct"):
        sensitivity.parse_values("mars", "tau_mag", "10,10")
    with pytest.raises(ValueError, match="not a number or a flag"):
        sensitivity.parse_values("mars", "q_init", "1")
    with pytest.raises(ValueError, match="unknown filter"):
        sensitivity.parse_values("nope", "tau_mag", "1")


def test_cli_errors(capsys: pytest.CaptureFixture[str]) -> None:
    for argv, msg in (
        (["mars", "gain", "1"], "has no setting 'gain'"),
        (["mars", "tau_mag", "10", "--conditions", "nowhere"], "unknown condition 'nowhere'"),
        (["mars", "tau_mag", "10", "--seeds", "0"], "--seeds must be at least 1"),
        (["mars", "tau_mag", "10", "--data", "/no/such/dir"], "no such file or directory"),
    ):
        with pytest.raises(SystemExit) as exc:
            sensitivity.main(argv)
        assert exc.value.code == 2
        assert msg in capsys.readouterr().err


@pytest.mark.parametrize(("method", "peer"), [("ars", "vqf6"), ("mars", "vqf9")])
def test_scores_are_the_suites(method: str, peer: str) -> None:
    """The default's row and the peer's are ``attica eval --suite``'s figures of that case."""
    cond = condition("consumer")
    field, values = ("gain", (1.0, 0.5)) if method == "ars" else ("tau_mag", (20.0, 10.0))
    s = sensitivity.measure(method, field, values, [cond], [3])
    case = run_case(cond, 3, [method], [peer])
    metric = "inclination" if method == "ars" else "total"
    assert s.suite["consumer"][0] == getattr(case.errors[method], metric)
    assert s.suite["<peer>consumer"][0] == getattr(case.errors[peer], metric)
    assert s.suite["consumer"][1] != s.suite["consumer"][0], "the setting must reach the filter"


def _doc_table(title: str) -> list[list[str]]:
    text = DOC.read_text(encoding="utf-8")
    start = text.index(f"| {title} |")
    return [
        [c.strip().strip("*") for c in r.strip("|").split("|")]
        for r in text[start:].split("\n\n")[0].splitlines()
    ]


TABLES = {
    "mekf6, `tau_acc_lp`": ("mekf6", "tau_acc_lp", "1.25,1.45,1.6"),
    "mekf, `mag_noise`": ("mekf", "mag_noise", "0.3,0.6"),
    "mars, `tau_mag`": ("mars", "tau_mag", "10,20"),
}


@pytest.mark.parametrize("title", list(TABLES))
def test_doc_table(title: str) -> None:
    broad_trials()
    method, field, text = TABLES[title]
    header, _, *rows = _doc_table(title)
    conds = header[1:-2]
    assert header[-2:] == ["BROAD", "BROAD, left out"]
    values = sensitivity.parse_values(method, field, text)
    s = sensitivity.measure(method, field, values, [condition(c) for c in conds], range(1, 11), BROAD, jobs=2)
    assert s.broad is not None
    loo, picks = sensitivity.leave_one_out(s.broad)
    assert len(set(picks)) == 1, "the page says every fold chose the same value"
    for i, v in enumerate(values):
        cells = rows[i]
        assert float(cells[0]) == v
        want = [f"{s.suite[c][i]:.3f}" for c in conds] + [f"{s.broad[i].mean():.4f}"]
        want.append(f"{loo:.4f}" if picks[0] == i else "")
        assert cells[1:] == want, f"{title}, {v}: the page says {cells[1:]}, the tool computes {want}"
    vqf = rows[len(values)]
    assert vqf[0].startswith("VQF")
    assert vqf[1 : 1 + len(conds)] == [f"{s.suite['<peer>' + c][0]:.3f}" for c in conds]

"""attica eval on several processes and on a Dask cluster: the serial run's figures bit for bit.

Small on purpose (two short simulated trials, a few methods): what is compared is every number of the
report (errors per trial, sample counts, notes, the plot traces) and of results.json / grid.json, which
must not depend on where the trials ran or in which order they finished.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from attica.cli import main
from attica.data import Recording, broad_groups
from attica.evaluate import Method, Report, TrialPool, attica_method, run_methods
from attica.settings import FilterKind
from attica.sim import SimConfig, simulate
from attica.tuning import grid_scores

from helpers import need

TRIALS = ("01_undisturbed_slow_rotation_A", "24_disturbed_tapping_A")


def _recs() -> list[Recording]:
    out = []
    for seed, name in enumerate(TRIALS, start=5):
        r = simulate(SimConfig(duration=14.0, rate=100.0, seed=seed, taps=2))
        r.name, r.groups = name, broad_groups(name)
        out.append(r)
    return out


@pytest.fixture(scope="module")
def recs() -> list[Recording]:
    return _recs()


@pytest.fixture(scope="module")
def trial_dir(tmp_path_factory: pytest.TempPathFactory, recs: list[Recording]) -> Path:
    data = tmp_path_factory.mktemp("trials")
    for r in recs:
        r.save(data / f"{r.name}.npz")
    return data


def _methods() -> list[Method]:
    # covariance: the stated figures too are compared across processes (_numbers)
    methods = [attica_method(k, covariance=True) for k in (FilterKind.ARS, FilterKind.MARS, FilterKind.MEKF)]
    if importlib.util.find_spec("vqf") is not None:
        from attica.evaluate import peer_methods

        methods += peer_methods(["vqf9"])
    return methods


def _numbers(report: Report) -> list[Any]:
    """Every figure of a report but the measured run times, in (method, trial) order."""
    out: list[Any] = []
    for r in report.results:
        for t in r.trials:
            out.append((r.method.name, t.trial, t.errors.total, t.errors.heading, t.errors.inclination))
            out.append((t.errors.n, t.notes, t.stated))
    return out


def _same_traces(a: Report, b: Report) -> None:
    assert list(a.traces) == list(b.traces)  # the same (method, trial) order
    for key, ta in a.traces.items():
        tb = b.traces[key]
        for field in ("index", "euler", "total", "heading", "inclination", "flags", "gyro_bias"):
            va, vb = getattr(ta, field), getattr(tb, field)
            assert (va is None) == (vb is None), (key, field)
            if va is not None:
                assert va.dtype == vb.dtype and np.array_equal(va, vb, equal_nan=True), (key, field)


def _results(out: Path) -> dict[str, Any]:
    data: dict[str, Any] = json.loads((out / "results.json").read_text())
    data.pop("command")
    for m in data["methods"].values():
        m.pop("seconds")
    return data


class _Bar:
    """Stands in for the tqdm bar: counts updates and keeps the postfixes."""

    def __init__(self) -> None:
        self.n, self.postfix = 0, []

    def __enter__(self) -> _Bar:
        return self

    def __exit__(self, *exc: object) -> None:
        pass

    def update(self, k: int) -> None:
        self.n += k

    def set_postfix_str(self, text: str, refresh: bool = True) -> None:
        self.postfix.append(text)


def test_processes_give_the_serial_figures_bit_for_bit(
    recs: list[Recording], monkeypatch: pytest.MonkeyPatch
) -> None:
    from attica.evaluate import core

    methods = _methods()
    serial = run_methods(methods, recs, progress=False, curves=True)
    assert len(serial.traces) == len(methods) * len(recs)
    bars: list[_Bar] = []
    monkeypatch.setattr(core, "_progress", lambda total, desc, enabled: bars.append(_Bar()) or bars[-1])
    with TrialPool(2) as pool:
        parallel = run_methods(methods, recs, progress=True, curves=True, pool=pool)
        assert pool.describe() == "on 2 processes"
        # the bar advanced once per finished trial, naming it
        assert bars[0].n == len(methods) * len(recs) and len(bars[0].postfix) == bars[0].n
        assert sorted(bars[0].postfix) == sorted(f"{m.name} {r.name[:24]}" for m in methods for r in recs)
        # the pool keeps its workers (and their recordings) for the next call, as --grid does
        grid = {"tau_acc_lp": [1.0, 2.0], "gain": [0.1, 1.0]}
        g2 = grid_scores(FilterKind.ARS, recs, grid, progress=False, pool=pool)
    assert _numbers(parallel) == _numbers(serial)
    _same_traces(parallel, serial)
    g1 = grid_scores(FilterKind.ARS, recs, grid, progress=False)
    assert g1.points == g2.points and np.array_equal(g1.errors, g2.errors)


def test_eval_jobs_and_grid_match_the_serial_run(trial_dir: Path, tmp_path: Path) -> None:
    base = ["eval", "--data", str(trial_dir), "--filter", "ars,mekf6", "-q", "--no-plots"]
    for jobs in ("1", "2"):
        assert main([*base, "--jobs", jobs, "--out", str(tmp_path / jobs)]) == 0
    assert _results(tmp_path / "1") == _results(tmp_path / "2")
    grid = ["eval", "--data", str(trial_dir), "--filter", "ars", "--grid", "-q"]
    for jobs in ("1", "2"):
        assert main([*grid, "--jobs", jobs, "--out", str(tmp_path / f"grid{jobs}")]) == 0
    one, two = ((tmp_path / f"grid{j}" / "grid.json").read_text() for j in ("1", "2"))
    assert one == two


def _local_run(rec: Recording) -> np.ndarray:
    return np.asarray(rec.quat_true, np.float64)


def test_refusals(
    trial_dir: Path, recs: list[Recording], monkeypatch: pytest.MonkeyPatch, capsys: Any
) -> None:
    base = ["eval", "--data", str(trial_dir), "-q", "--no-plots"]
    for extra, message in (
        (["--jobs", "0"], "--jobs must be >= 1"),
        (["--jobs", "2", "--scheduler", "tcp://127.0.0.1:8786"], "exclude each other"),
    ):
        assert main([*base, *extra]) == 2
        err = capsys.readouterr().err
        assert message in err, err
    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "distributed" else real(name, *a)
    )
    assert main([*base, "--scheduler", "tcp://127.0.0.1:8786"]) == 2
    cap = capsys.readouterr()
    assert "pip install 'attica[dask]'" in cap.err and "trials" not in cap.out  # before any work
    monkeypatch.undo()

    def local(rec: Recording) -> np.ndarray:  # a closure: does not pickle
        return _local_run(rec)

    method = Method("local", "test", True, "default", local)
    with pytest.raises(ValueError, match="cannot be sent to worker processes"):
        run_methods([method, method], recs, progress=False, jobs=2)
    with pytest.raises(ValueError, match="jobs must be >= 1"):
        TrialPool(0)


def test_dask_cluster_gives_the_serial_figures(
    trial_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    need(
        importlib.util.find_spec("distributed") is not None,
        "dask.distributed missing: pip install 'attica[dask]'",
    )
    from distributed import LocalCluster

    base = ["eval", "--data", str(trial_dir), "--filter", "ars,mars", "-q", "--no-plots"]
    assert main([*base, "--jobs", "1", "--out", str(tmp_path / "serial")]) == 0
    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=40
    ) as cluster:
        out = tmp_path / "dask"
        assert main([*base, "--scheduler", cluster.scheduler_address, "--out", str(out)]) == 0
        assert f"(on the Dask cluster at {cluster.scheduler_address} (2 workers))" in capsys.readouterr().out
        # a closure goes to Dask's workers too (cloudpickle), in the order asked for
        recs = _recs()
        local = Method("truth", "test", True, "default", lambda rec: _local_run(rec))
        rep = run_methods([local], recs, progress=False, scheduler=cluster.scheduler_address)
        assert [t.trial for t in rep.results[0].trials] == list(TRIALS)
        assert all(t.errors.total == 0.0 for t in rep.results[0].trials)
    assert _results(out) == _results(tmp_path / "serial")

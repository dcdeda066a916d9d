"""attica eval --peers on recordings whose magnetometer is missing on some rows (phone logs).

Before the fix the ahrs EKF raised from inside its batch loop (its first quaternion came from a zero
field) and Madgwick/Mahony returned NaN throughout. Now the 9-axis ahrs filters start at the first mag
sample (earlier rows unscored), VQF and Fusion get a zero field (their "no sample"), the EKF holds the
last sample on later gaps, and the notes under the tables say so (attica.peers.MISSING_MAG).
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from attica.cli import main
from attica.data import Recording
from attica.evaluate import peer_methods, run_methods
from attica.sim import SimConfig, simulate

from helpers import need

PEERS = ("ekf9", "madgwick9", "mahony9", "vqf9", "fusion9")


def _need_peers() -> None:
    for lib in ("ahrs", "vqf", "imufusion"):
        need(
            importlib.util.find_spec(lib) is not None,
            f"peer library {lib} not installed (pip install '.[peers]')",
        )


def _phone_log() -> Recording:
    rec = simulate(SimConfig(duration=12.0, rate=100.0, seed=4, taps=1))
    rec.name = "phone_log"
    rec.mag[:50] = np.nan  # the magnetometer's first sample comes half a second after the gyro's
    rec.mag[51::2] = np.nan  # and then at half the gyro's rate
    return rec


def test_peers_run_from_the_first_mag_sample_and_say_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _need_peers()
    rec = _phone_log()
    rec.save(tmp_path / "phone_log.npz")
    out = tmp_path / "out"
    args = ["eval", "--data", str(tmp_path / "phone_log.npz"), "--filter", "mars", "--peers", ",".join(PEERS)]
    assert main([*args, "-q", "--jobs", "1", "--no-plots", "--out", str(out)]) == 0
    text = " ".join(capsys.readouterr().out.split())  # the notes are wrapped at 110 columns
    assert "notes (the input the methods got, and what was scored):" in text
    assert (
        "ekf9, ekf9@tuned on phone_log: rows 0-49 (0.50 s) before the first mag sample: no estimate, not "
        "scored (ahrs EKF starts from the first row's field)"
    ) in text
    later = int(np.count_nonzero(~np.isfinite(rec.mag[50:, 0])))
    assert (
        f"ekf9, ekf9@tuned on phone_log: {later} later rows without a mag sample: the last sample held"
        in text
    )
    assert (
        f"madgwick9, madgwick9@tuned on phone_log: {later} later rows without a mag sample: a 6-axis" in text
    )
    missing = int(np.count_nonzero(~np.isfinite(rec.mag[:, 0])))
    assert f"vqf9, vqf9@tuned on phone_log: {missing} of 1200 rows without a mag sample: given to VQF" in text
    res = json.loads((out / "results.json").read_text())["methods"]
    assert set(res) >= {p for name in PEERS for p in (name, f"{name}@tuned")}
    assert rec.movement is not None
    for name, m in res.items():
        trial = m["trials"]["phone_log"]
        assert trial["total"] is not None and trial["total"] < 20.0, (name, trial)
        if name.startswith(("ekf9", "madgwick9", "mahony9")):  # the first 50 rows are not scored
            assert trial["n"] == int(np.count_nonzero(rec.movement[50:])) and trial["notes"]
        else:
            assert trial["n"] == int(np.count_nonzero(rec.movement))
    assert "notes" not in res["mars"]["trials"]["phone_log"]


def test_no_mag_at_all_is_a_note_not_a_traceback() -> None:
    _need_peers()
    rec = _phone_log()
    rec.mag[:] = np.nan
    rep = run_methods(peer_methods(["ekf9", "vqf9"]), [rec], progress=False)
    ekf, vqf = rep.result("ekf9").trials[0], rep.result("vqf9").trials[0]
    assert np.isnan(ekf.errors.total) and "not run" in ekf.notes[0]
    assert np.isfinite(vqf.errors.inclination) and "ran without mag updates" in vqf.notes[0]


@pytest.mark.parametrize("seed", [1, 2])
def test_vqf_is_told_a_slower_magnetometers_period(seed: int) -> None:
    """A magnetometer on every 10th row: VQF gets its mean period (magTs), so its mag time constants stay
    seconds and its heading matches the one with a field on every row (within 0.02 deg RMSE; without magTs
    they were 0.05 and 0.12 deg apart on these seeds)."""
    need(importlib.util.find_spec("vqf") is not None, "peer library vqf missing (pip install '.[peers]')")
    from attica.metrics import evaluate
    from attica.peers import peer_by_name

    cfg = SimConfig(duration=60.0, rate=100.0, seed=seed)
    full = simulate(cfg)
    slow = simulate(cfg)
    slow.mag[np.arange(len(slow.mag)) % 10 != 0] = np.nan
    scored = full.t >= 10.0
    vqf9 = peer_by_name("vqf9")
    h_full = evaluate(vqf9.estimate(full).q, full.quat_true, scored).heading
    h_slow = evaluate(vqf9.estimate(slow).q, slow.quat_true, scored).heading
    assert abs(h_slow - h_full) < 0.02, (h_full, h_slow)


def test_vqf_magts_is_the_typical_spacing_not_the_mean(monkeypatch: pytest.MonkeyPatch) -> None:
    """A full-rate magnetometer that starts 20 s late is not a slower one: magTs = the gyro's period.
    Every 4th row: 4 periods. (A mean over all rows would give 1.5 and 4.5 periods.)"""
    need(importlib.util.find_spec("vqf") is not None, "peer library vqf missing (pip install '.[peers]')")
    import vqf

    from attica.peers import peer_by_name

    seen: list[tuple[float, ...]] = []
    real = vqf.VQF

    def spy(*args: float, **kw: object) -> object:
        seen.append(args)
        return real(*args, **kw)

    monkeypatch.setattr(vqf, "VQF", spy)
    rec = simulate(SimConfig(duration=60.0, rate=100.0, seed=1))
    late = rec.mag.copy()
    late[:2000] = np.nan
    every4 = rec.mag.copy()
    every4[np.arange(len(every4)) % 4 != 0] = np.nan
    for mag, periods in ((late, 1.0), (every4, 4.0)):
        rec.mag = mag
        peer_by_name("vqf9").estimate(rec)
        assert seen[-1][2] == pytest.approx(periods / 100.0), seen[-1]

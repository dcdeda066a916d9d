"""--calibration FILE on run, eval, replay, node and verify; sending a calibration to a node over CAN."""

from __future__ import annotations

import json
import threading
import time
import uuid
from pathlib import Path

import numpy as np
import pytest

from attica import native
from attica.calibration import Calibration, InertialModel, MagModel, Mounting
from attica.calibration.stages import StageSettings, fields, from_calibration
from attica.can.bus import open_bus
from attica.can.calibration import CalibrationRefusedError, send_calibration
from attica.can.logs import read_log
from attica.can.node import Node
from attica.can.replay import ImuStream
from attica.can.runner import NodeRunner
from attica.can.verify import frames_of, verify_frames, verify_live
from attica.cli import main
from attica.data import load_recording
from attica.native import ffi, lib
from attica.settings import FilterKind
from attica.sim import SimConfig, simulate

from helpers import assert_same_bits

RATE = 285.714
CAL = Calibration(
    gyro=InertialModel(offset=(0.01, -0.02, 0.005), sensitivity=(1.01, 0.99, 1.0)),
    accel=InertialModel(offset=(0.1, -0.05, 0.08)),
    mag=MagModel(soft_iron=((0.95, 0.02, 0.0), (0.02, 1.04, 0.01), (0.0, 0.01, 0.98)), hard_iron=(5, -3, 2)),
    mounting=Mounting(remap="+x-z+y"),
    convention="ned",
)


@pytest.fixture
def files(tmp_path: Path) -> dict[str, Path]:
    cal = tmp_path / "cal.json"
    CAL.save(cal)
    rec = tmp_path / "sim.npz"
    assert main(["sim", "--duration", "4", "--seed", "5", "-o", str(rec)]) == 0
    bad = tmp_path / "bad.json"
    d = CAL.to_dict()
    d["mag"]["soft_iron"] = [[1, 0, 0], [0, 0, 0], [0, 0, 1]]
    bad.write_text(json.dumps(d))
    return {"cal": cal, "rec": rec, "bad": bad, "dir": tmp_path}


def _channel() -> str:
    return "t" + uuid.uuid4().hex[:12]


def _node_fields(node: Node) -> list[float]:
    v = ffi.new("float *")
    out = []
    for i in range(lib.ATT_CALIB_FIELDS):
        assert lib.att_calib_field_get(node.state.cal.ptr, i, v)
        out.append(float(v[0]))
    return out


def test_run_applies_the_calibration(files: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    rec = load_recording(files["rec"])
    out, plain = files["dir"] / "cal_out.npz", files["dir"] / "plain.npz"
    args = ["run", "--filter", "mars", "--data", str(files["rec"]), "-q", "--check"]
    assert main([*args, "--calibration", str(files["cal"]), "-o", str(out)]) == 0
    text = capsys.readouterr()
    assert (
        f"calibration {files['cal']} applied: gyro, accel, mag, mounting +x-z+y, convention ned" in text.out
    )
    assert "0 differ: bit-exact" in text.out
    assert "ground truth is the sensor's attitude in ENU" in text.err
    assert main([*args, "-o", str(plain)]) == 0
    got, base = np.load(out)["q"], np.load(plain)["q"]
    want = native.Filter("mars", dt=1.0 / rec.rate, calibration=CAL).run(rec.gyr, rec.acc, rec.mag)["q"]
    assert_same_bits(got, want)
    assert not np.array_equal(got.view(np.uint32), base.view(np.uint32))


def test_eval_applies_the_calibration(files: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    from attica.evaluate import attica_method

    mag_only = Calibration(mag=CAL.mag)
    path = files["dir"] / "mag.json"
    mag_only.save(path)
    runs = []
    for extra in ([], ["--calibration", str(path)]):
        out = files["dir"] / ("e" + str(len(extra)))
        assert main(["eval", "--filter", "mars", "--data", str(files["rec"]), "--out", str(out), "--no-plots",
                     "-q", *extra]) == 0  # fmt: skip
        runs.append(json.loads((out / "results.json").read_text())["methods"]["mars"])
    assert "calibration" in capsys.readouterr().out
    assert runs[0]["mean"] != runs[1]["mean"] and runs[1]["note"].endswith("calibrated")
    rec = load_recording(files["rec"])
    q = attica_method(FilterKind.MARS, calibration=mag_only)
    want = native.Filter("mars", dt=1.0 / rec.rate, calibration=mag_only).run(rec.gyr, rec.acc, rec.mag)["q"]
    assert_same_bits(q.run(rec).astype(np.float32), want)


@pytest.mark.parametrize(
    "argv",
    [
        ["run", "--duration", "2"],
        ["eval", "--data", "{rec}"],
        ["replay", "-c", "{ch}", "--duration", "1"],
        ["node", "-c", "{ch}", "--count", "1"],
        ["verify", "-c", "{ch}", "--duration", "1"],
        ["calibrate", "send", "{bad}", "-c", "{ch}"],
    ],
)
def test_bad_calibration_file_is_an_error_before_any_work(
    files: dict[str, Path], argv: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    subs = {"rec": str(files["rec"]), "ch": _channel(), "bad": str(files["bad"])}
    argv = [a.format(**subs) for a in argv]
    extra = [] if argv[0] == "calibrate" else ["--calibration", str(files["bad"])]
    assert main([*argv, *extra]) == 2
    err = capsys.readouterr().err
    assert err.startswith("attica: error: ") and "soft_iron" in err and err.count("\n") == 1
    if argv[0] != "calibrate":
        assert main([*argv, "--calibration", str(files["dir"] / "none.json")]) == 2
        assert "no such calibration file" in capsys.readouterr().err


def test_node_and_verify_apply_the_calibration(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    """attica node --calibration serves a calibrated node: verify --calibration proves it bit-exact, and
    verify without the calibration sees every set differ."""
    ch = _channel()
    codes: list[int] = []
    steps = 2 * round(2 * RATE)  # two verify runs; --idle-timeout only ends the node if one fails
    argv = ["node", "-c", ch, "--filter", "mars", "--calibration", str(files["cal"]), "--count", str(steps)]
    argv += ["--idle-timeout", "30"]
    node = threading.Thread(target=lambda: codes.append(main(argv)))
    node.start()
    try:
        time.sleep(1.0)  # the node's start-up
        v = ["verify", "-c", ch, "--filter", "mars", "--duration", "2", "-q"]
        assert main([*v, "--calibration", str(files["cal"])]) == 0
        out = capsys.readouterr().out
        assert "verdict: BIT-EXACT" in out and "calibration" in out and "applied" in out
        assert main(v) == 1
        assert "verdict: BIT-EXACT" not in capsys.readouterr().out
    finally:
        node.join(40)
    assert codes == [0]


def test_replay_sends_the_calibration_first(files: dict[str, Path]) -> None:
    ch = _channel()
    bus = open_bus("virtual", ch)
    n = Node("mars", sample_rate=RATE)
    stop = threading.Event()
    thread = NodeRunner(bus, n).start(stop)
    log = files["dir"] / "replay.log"
    try:
        code = main(
            ["replay", "-c", ch, "--duration", "2", "-q", "-w", str(log), "--calibration", str(files["cal"])]
        )
    finally:
        stop.set()
        thread.join(5)
        bus.shutdown()
    assert code == 0
    assert _node_fields(n)[:48] == fields(from_calibration(CAL))[:48]
    frames = frames_of(read_log(log))
    assert verify_frames(frames, FilterKind.MARS, RATE, calibration=CAL).ok
    assert not verify_frames(frames, FilterKind.MARS, RATE).ok


@pytest.mark.parametrize("fd", [False, True])
def test_send_commit_refusal_and_bit_exact_outputs(fd: bool) -> None:
    ch = _channel()
    node_bus, bus = open_bus("virtual", ch, fd=fd), open_bus("virtual", ch, fd=fd)
    n = Node("mars", sample_rate=RATE, fd=fd, data_bitrate=2_000_000 if fd else 0)
    service = NodeRunner(node_bus, n).service
    try:
        before = _node_fields(n)
        rep = send_calibration(bus, CAL, service=service)
        assert rep.fields == 48 and rep.commands == 50 and rep.persisted == 0
        applied = _node_fields(n)
        assert applied[:48] == fields(from_calibration(CAL))[:48] and applied[48:] == before[48:]
        # a singular soft iron: refused with the reason, nothing changes, the session is closed
        s = from_calibration(CAL)
        bad = StageSettings(**{**s.__dict__, "soft_iron": (1, 0, 0, 0, 0, 0, 0, 0, 1)})
        with pytest.raises(CalibrationRefusedError, match="mag_matrix") as info:
            send_calibration(bus, bad, service=service)
        assert info.value.reason == "mag_matrix"
        assert _node_fields(n) == applied and not n.state.shadow_open
        rec = ImuStream.from_recording(simulate(SimConfig(duration=2, rate=RATE, seed=2)))
        r = verify_live(bus, rec, FilterKind.MARS, fd=fd, calibration=CAL, service=service)
        assert r.ok, r.lines()
        r = verify_live(bus, rec, FilterKind.MARS, fd=fd, service=service)
        assert not r.ok
    finally:
        node_bus.shutdown()
        bus.shutdown()


def test_calibrate_send_cli(files: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    ch = _channel()
    argv = [
        "calibrate",
        "send",
        str(files["cal"]),
        "-c",
        ch,
        "--with-node",
        "--verify",
        "--duration",
        "2",
        "-q",
    ]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "CAL_COMMIT: acknowledged" in out and "verdict: BIT-EXACT" in out
    assert main(["calibrate", "send", str(files["cal"]), "-c", _channel(), "--timeout", "0.2"]) == 2
    assert "no ATT_CAL_ACK" in capsys.readouterr().err
    assert main(["calibrate", "send", str(files["cal"]), "-o", "x.json"]) == 2
    assert main(["calibrate", "mag", str(files["rec"]), "--verify"]) == 2

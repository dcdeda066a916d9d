"""Tests of the recording container and loaders (attica.data)."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest

from attica.data import Recording, load_recording
from attica.sim import SimConfig, quat_rotate, simulate

BROAD_DIR = Path(
    os.environ.get("ATTICA_BROAD_DIR", Path(__file__).resolve().parents[2] / "shared/data/broad")
)
BROAD_TRIAL = "24_disturbed_tapping_A.npz"
BROAD_KEYS = {"gyr", "acc", "mag", "opt_quat", "movement", "sampling_rate", "name", "groups"}


@pytest.fixture(scope="module")
def rec() -> Recording:
    r = simulate(SimConfig(duration=10.0, seed=7))
    r.quat_true[100:110] = np.nan  # tracking lost, as in BROAD
    r.mag[50:53] = np.nan  # absent magnetometer samples
    return r


def assert_same(a: Recording, b: Recording) -> None:
    for name in ("gyr", "acc", "mag"):
        x, y = getattr(a, name), getattr(b, name)
        assert y.dtype == np.float32 and np.array_equal(x, y, equal_nan=True), name
    assert b.quat_true is not None and b.quat_true.dtype == np.float64
    assert np.array_equal(a.quat_true, b.quat_true, equal_nan=True)
    assert b.movement is not None and np.array_equal(a.movement, b.movement)
    assert b.rate == a.rate and b.name == a.name and b.groups == a.groups


def test_npz_round_trip_broad_layout(tmp_path, rec):
    path = tmp_path / "trial.npz"
    rec.save(path)
    assert path.exists() and not (tmp_path / "trial.npz.npz").exists()
    with np.load(path, allow_pickle=False) as d:
        assert set(d.files) == BROAD_KEYS
        for k in ("gyr", "acc", "mag", "opt_quat"):
            assert d[k].dtype == np.float64, k
        assert d["movement"].dtype == np.bool_ and d["sampling_rate"].shape == ()
        assert str(d["name"]) == rec.name
    assert_same(rec, load_recording(path))
    assert_same(rec, load_recording(str(path)))


def test_csv_round_trip(tmp_path, rec):
    path = tmp_path / "trial.csv"
    rec.save(path)
    text = path.read_text()
    assert text.startswith(f"# rate={rec.rate!r}\n")
    assert (
        "t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,mag_x,mag_y,mag_z,quat_w,quat_x,quat_y,quat_z,movement" in text
    )
    assert_same(rec, load_recording(path))


def test_npz_optional_keys(tmp_path):
    n = 5
    path = tmp_path / "minimal.npz"
    np.savez(path, gyr=np.zeros((n, 3)), acc=np.ones((n, 3)), sampling_rate=100.0)
    r = load_recording(path)
    assert r.n == n and r.rate == 100.0 and r.name == "minimal" and r.groups == ()
    assert r.quat_true is None and r.movement is None
    assert r.mag.shape == (n, 3) and np.isnan(r.mag).all() and not r.has_mag
    r.save(tmp_path / "again.npz")
    back = load_recording(tmp_path / "again.npz")
    assert back.quat_true is None and back.movement is None and back.name == "minimal"


def test_csv_hand_written(tmp_path):
    path = tmp_path / "log.csv"
    path.write_text(
        "# attica test log\n"
        "# rate=200\n"
        "# name=hand\n"
        "# groups=a; b\n"
        "ACC_X,acc_y,acc_z,gyr_x,gyr_y,gyr_z,mag_x,mag_y,mag_z,movement,comment\n"
        "0,0,9.81,0.1,0.2,0.3,1,20,-40,false,x\n"
        "0,0.5,9.8,0.1,0.2,0.3,,,,true,y\n"
        "\n"
        "0,0,9.81,-0.1,0,0,nan,nan,nan,1,z\n"
    )
    r = load_recording(path)
    assert r.rate == 200.0 and r.dt == 0.005 and r.name == "hand" and r.groups == ("a", "b")
    assert r.n == 3 and np.allclose(r.t, [0.0, 0.005, 0.01])
    assert r.acc.dtype == np.float32 and np.allclose(r.acc[1], [0, 0.5, 9.8])
    assert np.allclose(r.gyr[:, 0], [0.1, 0.1, -0.1])
    assert np.allclose(r.mag[0], [1, 20, -40]) and np.isnan(r.mag[1:]).all()
    assert r.movement.tolist() == [False, True, True]
    assert r.quat_true is None


def test_csv_rate_from_t_column(tmp_path):
    rows = "\n".join(f"{k / 285.714:.9f},0,0,0,0,0,9.81,1,0,0,0" for k in range(50))
    path = tmp_path / "t.csv"
    path.write_text("t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,quat_w,quat_x,quat_y,quat_z\n" + rows + "\n")
    r = load_recording(path)
    assert r.rate == pytest.approx(285.714, rel=1e-6)
    assert r.quat_true is not None and np.array_equal(r.quat_true[0], [1, 0, 0, 0])
    assert np.isnan(r.mag).all()


CSV_HEAD = "gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n"


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("# rate=100\n", "no header"),
        ("# rate=100\ngyr_x,gyr_y,gyr_z,acc_x,acc_y\n1,2,3,4,5\n", "missing column"),
        ("# rate=100\n" + CSV_HEAD + "1,2,3,4,5\n", "fields"),
        ("# rate=100\n" + CSV_HEAD + "1,2,3,4,5,abc\n", "cannot parse"),
        ("# rate=100\n" + CSV_HEAD + "1,2,3,4,5,\n", "non-finite"),
        ("# rate=100\n" + CSV_HEAD + "1,2,3,4" + "4" * 50 + ",5,6\n", "float32 range"),  # host fuzz find
        (
            "# rate=100\ngyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,mag_x,mag_y,mag_z\n1,2,3,4,5,6,7,-1e39,\n",
            "float32 range",
        ),
        (CSV_HEAD + "1,2,3,4,5,6\n", "no sampling rate"),
        ("# rate=-5\n" + CSV_HEAD + "1,2,3,4,5,6\n", "rate"),
        ("# rate=fast\n" + CSV_HEAD + "1,2,3,4,5,6\n", "rate"),
        ("# rate=100\ngyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,mag_x\n1,2,3,4,5,6,7\n", "all together"),
        ("# rate=100\ngyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,movement\n1,2,3,4,5,6,2\n", "movement"),
        ("# rate=100\nt," + CSV_HEAD + "0,1,2,3,4,5,6\n0.02,1,2,3,4,5,6\n", "disagrees"),
        ("# rate=100\nt," + CSV_HEAD + "0,1,2,3,4,5,6\n0,1,2,3,4,5,6\n", "increasing"),
        ("# rate=100\ngyr_x,gyr_x,gyr_z,acc_x,acc_y,acc_z\n1,2,3,4,5,6\n", "duplicate"),
    ],
)
def test_csv_errors(tmp_path, text, match):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=match):
        load_recording(path)


def good_arrays(n: int = 4) -> dict[str, np.ndarray]:
    return {
        "gyr": np.zeros((n, 3)),
        "acc": np.ones((n, 3)),
        "mag": np.ones((n, 3)),
        "opt_quat": np.tile([1.0, 0, 0, 0], (n, 1)),
        "movement": np.ones(n, dtype=bool),
        "sampling_rate": np.float64(100.0),
    }


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"acc": None}, "missing key.*acc"),
        ({"sampling_rate": None}, "missing key.*sampling_rate"),
        ({"gyr": np.zeros((4, 2))}, r"gyr.*\(N, 3\)"),
        ({"mag": np.zeros((3, 3))}, "mag: 3 samples"),
        ({"opt_quat": np.zeros((4, 3))}, r"quat_true.*\(N, 4\)"),
        ({"movement": np.ones(5, dtype=bool)}, "movement: 5 samples"),
        ({"movement": np.full(4, 2.0)}, "movement"),
        ({"sampling_rate": np.float64(0.0)}, "rate"),
        ({"sampling_rate": np.float64(np.inf)}, "rate"),
        ({"sampling_rate": np.array([100.0, 200.0])}, "sampling_rate"),
        ({"gyr": np.array(["a", "b"])}, "gyr"),
    ],
)
def test_npz_errors(tmp_path, change, match):
    arrays = good_arrays()
    for k, v in change.items():
        if v is None:
            del arrays[k]
        else:
            arrays[k] = v
    path = tmp_path / "bad.npz"
    np.savez(path, **arrays)
    with pytest.raises(ValueError, match=match):
        load_recording(path)


def test_not_an_npz(tmp_path):
    path = tmp_path / "junk.npz"
    path.write_text("hello")
    with pytest.raises(ValueError, match="not a readable"):
        load_recording(path)
    with pytest.raises(FileNotFoundError):
        load_recording(tmp_path / "missing.npz")


def test_unknown_suffix(tmp_path, rec):
    with pytest.raises(ValueError, match="suffix"):
        load_recording(tmp_path / "x.xyz")  # .mat is a BROAD original now
    with pytest.raises(ValueError, match="suffix"):
        rec.save(tmp_path / "x.txt")


def test_recording_validation_and_properties():
    r = Recording(gyr=np.zeros((10, 3)), acc=np.zeros((10, 3)), mag=None, rate=50)  # type: ignore[arg-type]
    assert r.gyr.dtype == np.float32 and r.rate == 50.0 and isinstance(r.rate, float)
    assert r.n == len(r) == 10 and r.dt == 0.02 and r.t[-1] == pytest.approx(0.18)
    assert np.isnan(r.mag).all()
    src = np.zeros((10, 3), np.float32)
    r2 = Recording(gyr=src, acc=src, mag=src, rate=1.0, movement=np.arange(10) % 2)
    assert r2.movement.dtype == np.bool_
    src[0, 0] = 1.0
    assert r2.gyr[0, 0] == 0.0  # the recording owns its arrays
    with pytest.raises(ValueError, match="rate"):
        Recording(gyr=src, acc=src, mag=src, rate=math.nan)
    with pytest.raises(ValueError, match="rate"):
        Recording(gyr=src, acc=src, mag=src, rate="x")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="acc: 9 samples"):
        Recording(gyr=src, acc=src[:9], mag=src, rate=1.0)
    with pytest.raises(ValueError, match="gyr"):
        Recording(gyr=np.zeros(3), acc=src, mag=src, rate=1.0)  # type: ignore[arg-type]


def test_broad_trial():
    path = BROAD_DIR / BROAD_TRIAL
    if not path.exists():
        reason = f"BROAD data not found at {path} (set ATTICA_BROAD_DIR)"
        print(reason)
        if os.environ.get("CI") == "true":
            pytest.fail(reason)
        pytest.skip(reason)
    r = load_recording(path)
    assert r.name == "24_disturbed_tapping_A"
    assert "tapping" in r.groups and "all_trials" in r.groups
    assert r.rate == pytest.approx(285.714, abs=1e-3)
    n = r.n
    assert n > 10_000
    assert r.gyr.shape == r.acc.shape == r.mag.shape == (n, 3) and r.gyr.dtype == np.float32
    assert r.quat_true is not None and r.quat_true.shape == (n, 4) and r.quat_true.dtype == np.float64
    assert r.movement is not None and r.movement.dtype == np.bool_ and 0 < r.movement.mean() < 1
    known = np.isfinite(r.quat_true).all(axis=1)
    assert 0.5 < known.mean() < 1.0  # some tracking loss in this trial
    assert np.allclose(np.linalg.norm(r.quat_true[known], axis=1), 1.0, atol=1e-6)
    # conventions hold on real data: at rest, R acc ~ (0, 0, +g) and R mag points north and down (Berlin)
    still = np.flatnonzero(known & ~r.movement)[:2000]
    acc_e = quat_rotate(r.quat_true[still], r.acc[still]).mean(axis=0)
    mag_e = quat_rotate(r.quat_true[still], r.mag[still]).mean(axis=0)
    assert acc_e == pytest.approx([0.0, 0.0, 9.81], abs=0.2)
    assert abs(mag_e[0]) < 3.0 and mag_e[1] > 10.0 and mag_e[2] < -30.0
    # float32 conversion is the only change
    with np.load(path, allow_pickle=False) as d:
        assert np.array_equal(r.gyr, d["gyr"].astype(np.float32))
        assert np.array_equal(r.quat_true, d["opt_quat"], equal_nan=True)

"""EuRoC / ASL folders (attica.data.euroc): text files written from a known motion, read back."""

from __future__ import annotations

import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from recordings_support import motion
from recordings_text import write_euroc

from attica.data import Recording, detect, load_recording, read_recording
from attica.data.euroc import read_euroc
from attica.data.timing import TimingWarning


@pytest.fixture(scope="module")
def rec() -> Recording:
    return motion()


def test_values_time_and_truth(tmp_path: Path, rec: Recording) -> None:
    root = write_euroc(tmp_path / "MH_01_easy", rec)
    assert detect(root) == "euroc"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = load_recording(root)
    assert got.name == "MH_01_easy" and got.n == rec.n and got.rate == 100.0
    np.testing.assert_array_equal(got.gyr, rec.gyr)
    np.testing.assert_array_equal(got.acc, rec.acc)
    assert not got.has_mag
    np.testing.assert_allclose(got.time, np.arange(rec.n) / rec.rate, atol=1e-9)
    assert got.timing is not None and got.timing.unit == "ns" and not got.timing.unit_guessed
    q = got.quat_true
    assert q is not None
    known = np.isfinite(q).all(axis=1)
    # truth 1 ms after row i is held on row i + 1 (9 ms later); none 19 ms after the last (> 1.5 intervals)
    np.testing.assert_array_equal(np.flatnonzero(known), np.arange(21, 271))
    np.testing.assert_allclose(q[21:271], rec.quat_true[20:270], atol=1e-12)


def test_any_folder_level_or_the_csv_or_a_zip(tmp_path: Path, rec: Recording) -> None:
    root = write_euroc(tmp_path / "V1_01", rec)
    for path in (root / "mav0", root / "mav0" / "imu0", root / "mav0" / "imu0" / "data.csv"):
        got, contents = read_euroc(path)
        assert got.n == rec.n and got.quat_true is not None, path
        assert got.name == "V1_01"
    archive = Path(shutil.make_archive(str(tmp_path / "V1_01"), "zip", root))
    assert detect(archive) == "euroc"
    got, contents = read_recording(archive)
    assert got.n == rec.n and contents.format == "EuRoC/ASL"
    assert [s.role for s in contents.streams] == ["gyr, acc", "quat_true"]


def test_truth_only_when_asked_and_stated(tmp_path: Path, rec: Recording) -> None:
    root = write_euroc(tmp_path / "s", rec)
    got, contents = read_euroc(root, truth=False)
    assert got.quat_true is None and any("truth=False" in n for n in contents.notes)
    _, contents = read_euroc(root)
    assert any("heading arbitrary" in n for n in contents.notes)
    got, contents = read_euroc(write_euroc(tmp_path / "t", rec, truth=False))
    assert got.quat_true is None and any("no ground truth" in n for n in contents.notes)


def test_gaps_are_reported_and_integrated(tmp_path: Path, rec: Recording) -> None:
    root = write_euroc(tmp_path / "s", rec, skip=range(150, 160))
    with pytest.warns(TimingWarning, match="10 sample"):
        got = load_recording(root)
    assert got.n == rec.n - 10 and got.lost == 10 and int(got.steps[150]) == 11


def test_bad_input(tmp_path: Path, rec: Recording) -> None:
    root = write_euroc(tmp_path / "s", rec)
    data = root / "mav0" / "imu0" / "data.csv"
    lines = data.read_text().splitlines()
    lines[5] = lines[5].replace(",", ",oops", 1)
    data.write_text("\n".join(lines) + "\n")
    with pytest.raises(
        ValueError, match=r"imu0/data.csv: row 6, column 'w_RS_S_x \[rad s\^-1\]': 'oops.*not a number"
    ):
        load_recording(root)
    data.write_text("#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1]\n1,2,3\n")
    with pytest.raises(ValueError, match="no column w_RS_S_z"):
        read_euroc(root)
    other = tmp_path / "other"
    (other / "mav0" / "cam0").mkdir(parents=True)
    (other / "mav0" / "cam0" / "data.csv").write_text("#timestamp [ns],filename\n1,a.png\n")
    with pytest.raises(ValueError, match="no imu0/data.csv"):
        read_euroc(other)

"""phyphox exports (attica.data.phyphox): every CSV variant of phyphox's export menu, written and read."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest
from recordings_support import motion
from recordings_text import VARIANTS, phyphox_sensor, phyphox_sets, phyphox_table, write_phyphox_zip

from attica.data import Recording, detect, load_recording, read_recording
from attica.data.phyphox import read_phyphox
from attica.data.timing import TimingWarning


@pytest.fixture(scope="module")
def rec() -> Recording:
    return motion()


def _check(got: Recording, rec: Recording) -> None:
    # accel 2 ms after each gyro sample: the first gyro row is dropped, then each accel is held one row
    assert got.n == rec.n - 1
    np.testing.assert_allclose(got.gyr, rec.gyr[1:], rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(got.acc, rec.acc[:-1], rtol=1e-6, atol=1e-9)
    placed = np.flatnonzero(np.isfinite(got.mag).all(axis=1))
    np.testing.assert_array_equal(placed, np.arange(0, rec.n - 1, 2))  # 1 ms after gyro row 2k: on row 2k + 1
    np.testing.assert_allclose(got.mag[placed], rec.mag[::2][: placed.size], rtol=1e-6)
    assert got.rate == pytest.approx(100.0) and got.lost == 0


@pytest.mark.parametrize(("sep", "decimal"), VARIANTS)
def test_every_export_variant(tmp_path: Path, rec: Recording, sep: str, decimal: str) -> None:
    path = write_phyphox_zip(tmp_path / "walk.zip", rec, sep, decimal)
    assert detect(path) == "phyphox"
    got, contents = read_phyphox(path)
    _check(got, rec)
    assert contents.format == "phyphox"
    assert any("linear acceleration" in n for n in contents.notes)
    assert [s.role for s in contents.streams] == ["gyr", "acc", "mag"]


def test_folder_and_one_table_with_several_time_columns(tmp_path: Path, rec: Recording) -> None:
    folder = tmp_path / "walk"
    folder.mkdir()
    for name, cols in phyphox_sets(rec).items():
        (folder / name).write_text(phyphox_table(cols, ";", ","), encoding="utf-8")
    with pytest.warns(
        TimingWarning, match=r"walk/Gyroscope.csv \(gyr\): 1 gyro row\(s\) before the first accel"
    ):
        _check(load_recording(folder), rec)
    sets = phyphox_sets(rec)
    combined = sets["Gyroscope.csv"] + sets["Accelerometer.csv"] + sets["Magnetometer.csv"]
    one = tmp_path / "Raw Data.csv"
    one.write_text(phyphox_table(combined, ",", "."), encoding="utf-8")
    assert detect(one) == "phyphox"
    got, _ = read_recording(one)
    _check(got, rec)


def test_columns_found_by_unit_in_any_language(tmp_path: Path, rec: Recording) -> None:
    t = np.arange(rec.n) / rec.rate
    cols = phyphox_sensor("Gyroskop", "rad/s", t, rec.gyr, "Zeit (s)") + phyphox_sensor(
        "Beschleunigung", "m/s²", t, rec.acc, "Zeit (s)"
    )
    path = tmp_path / "Rohdaten.csv"
    path.write_text(phyphox_table(cols, "\t", ","), encoding="utf-8")
    got, _ = read_phyphox(path)
    np.testing.assert_allclose(got.gyr, rec.gyr, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(got.acc, rec.acc, rtol=1e-6, atol=1e-9)


def test_refusals(tmp_path: Path, rec: Recording) -> None:
    sets = phyphox_sets(rec)
    path = tmp_path / "lin.zip"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("Gyroscope.csv", phyphox_table(sets["Gyroscope.csv"], ",", "."))
        z.writestr("Linear Acceleration.csv", phyphox_table(sets["Linear Acceleration.csv"], ",", "."))
    with pytest.raises(ValueError, match=r"lin.zip: no accelerometer \(with g\) \(only linear acceleration"):
        load_recording(path)
    bad = tmp_path / "bad.csv"
    text = phyphox_table(sets["Gyroscope.csv"] + sets["Accelerometer.csv"], ",", ".").splitlines()
    text[3] = text[3].replace("E", "X", 1)
    bad.write_text("\n".join(text) + "\n")
    with pytest.raises(ValueError, match=r"bad.csv: row 4, column 'Time \(s\)': .* is not a number"):
        load_recording(bad)

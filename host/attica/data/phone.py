"""Phone recordings of one CSV file per sensor: Sensor Logger exports and Android-style folders.

Give the folder or the ``.zip`` export. Plain text, no extra package. Phones report in the device's
frame (Android's, for both readers below): x to the right of the screen, y up along it, z out of the
screen. Gyro rad/s, acceleration m/s^2, field uT: attica's units; nothing is rotated.

**Sensor Logger** (the app by Kelvin Choi; recognised by ``Metadata.csv`` or a ``seconds_elapsed``
column). Files ``Gyroscope.csv``, ``TotalAcceleration.csv`` / ``Accelerometer.csv`` + ``Gravity.csv``,
``Magnetometer.csv`` with columns ``time`` (ns since the epoch, used exactly), ``seconds_elapsed``,
``z``, ``y``, ``x``. Its ``Accelerometer.csv`` is acceleration *without* gravity (both platforms), so
the specific force attica needs is taken from:

- ``TotalAcceleration.csv`` (Android: the raw accelerometer, gravity included), as it is;
- else ``Accelerometer.csv + Gravity.csv`` (iOS: gravity held on the accelerometer's times). iOS reports
  both with the opposite sign of Android's (CoreMotion's inertial-force convention: flat on a table,
  gravity reads -z), so the sum is negated, unless ``Metadata.csv`` says the export was made with
  "Standardise Units & Frames" (then it is already in Android's convention). Without ``Metadata.csv``
  the platform is taken as iOS (Android exports always have TotalAcceleration.csv), stated in the notes.

The uncalibrated variants (``*Uncalibrated.csv``) are not used.

**Android-style folders** (any other folder or zip of per-sensor CSVs): a file per sensor whose name
says which (``gyro``/``gyroscope``, ``accel``/``accelerometer``/``acc``, ``mag``/``magnetometer``/
``magnetic``; files named ``linear``, ``gravity``, ``uncalibrated``, ``rotation`` are not sensors
attica reads), each with a time column (``time``, ``timestamp``, ``t``, with an optional unit such as
``timestamp_ns`` or ``time [ms]``; else the first column) and three axis columns (names ending in x, y,
z; else the three after the time). The accelerometer must include gravity (Android's
``TYPE_ACCELEROMETER``). A time column without a unit is read by its intervals (and reported as guessed).

Every stream keeps its own times: the gyro's are the clock, accel held, magnetometer placed
(:mod:`attica.data.streams`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np

from attica.data import timing
from attica.data.recording import PathLike, Recording
from attica.data.streams import Contents, RecordingError, Series, Stream, assemble, median_rate, report
from attica.data.tables import Bundle, Table

__all__ = ["is_sensor_logger", "load_phone", "read_phone"]

_TIME = re.compile(r"^(t|time|timestamp|stamp|ts|sensor_?time(stamp)?)([ _\[(].*)?$", re.IGNORECASE)
_AXIS = re.compile(r"([xyz])(\s*[\[(].*)?$", re.IGNORECASE)
_SKIP = re.compile(
    r"linear|gravity|uncalibrated|uncal|rotation|orientation|game|geomagnetic|user", re.IGNORECASE
)
_KINDS = {
    "gyr": re.compile(r"gyro|angular", re.IGNORECASE),
    "acc": re.compile(r"accel|(^|[_\-\s.])acc([_\-\s.]|$)", re.IGNORECASE),
    "mag": re.compile(r"magnet|(^|[_\-\s.])mag([_\-\s.]|$)", re.IGNORECASE),
}


@dataclass
class _Sensor:
    """A sensor file read: its stream, time column and rows."""

    series: Series
    time_name: str
    rows: int


def is_sensor_logger(bundle: Bundle) -> bool:
    """Whether the files are a Sensor Logger export (``Metadata.csv``, or ``seconds_elapsed`` columns)."""
    if bundle.find("Metadata.csv"):
        return True
    gyro = bundle.find("Gyroscope.csv")
    return bool(gyro) and "seconds_elapsed" in bundle.text(gyro[0]).split("\n", 1)[0]


def _axes(table: Table, skip: int) -> list[int]:
    named: dict[str, int] = {}
    for j, h in enumerate(table.header):
        m = _AXIS.search(h.strip().strip('"'))
        if j != skip and m and m.group(1).lower() not in named and not _TIME.match(h):
            named[m.group(1).lower()] = j
    if len(named) == 3:
        return [named["x"], named["y"], named["z"]]
    rest = [j for j in range(len(table.header)) if j != skip]
    if len(rest) < 3:
        raise RecordingError(f"{table.source}: need three axis columns, the header is {table.header}")
    return rest[:3]


def _read(bundle: Bundle, name: str, time_col: str | None, scale: float = 1.0) -> _Sensor:
    table = bundle.table(name)
    if len(table) == 0:
        raise RecordingError(f"{table.source}: no rows")
    tj = next((j for j, h in enumerate(table.header) if h == time_col), None) if time_col else None
    if tj is None:
        tj = next((j for j, h in enumerate(table.header) if _TIME.match(h)), 0)
    if _AXIS.fullmatch(table.header[tj].strip()):
        raise RecordingError(
            f"{table.source}: no time column (time, timestamp, t ...); the header is {table.header}"
        )
    values = np.column_stack([table.floats(j) for j in _axes(table, tj)]) * scale
    return _Sensor(Series(table.times(tj), values, name), table.header[tj], len(table))


def _metadata(bundle: Bundle) -> dict[str, str]:
    name = bundle.one("Metadata.csv")
    if name is None:
        return {}
    table = bundle.table(name)
    row = table.rows[0] if table.rows else []
    return {h.strip().lower(): (row[j].strip() if j < len(row) else "") for j, h in enumerate(table.header)}


def _sensor_logger(
    bundle: Bundle, notes: list[str]
) -> tuple[_Sensor, _Sensor, _Sensor | None, str, str | None]:
    meta = _metadata(bundle)
    gyro = bundle.one("Gyroscope.csv")
    if gyro is None:
        raise RecordingError(f"{bundle.path}: a Sensor Logger export without Gyroscope.csv")
    g = _read(bundle, gyro, "time")
    platform = meta.get("platform", "").lower()
    standard = meta.get("standardisation", meta.get("standardization", "")).lower() in (
        "true",
        "1",
        "yes",
        "on",
    )
    ios = platform == "ios" or (not platform and not bundle.one("TotalAcceleration.csv"))
    flip = -1.0 if ios and not standard else 1.0
    convention = "Android's convention" if flip > 0 else "iOS sign, negated to Android's"
    total = bundle.one("TotalAcceleration.csv")
    if total is not None:
        a = _read(bundle, total, "time", flip)
        notes.append(f"acc: {total} (gravity included; {convention})")
    else:
        acc_name, grav_name = bundle.one("Accelerometer.csv"), bundle.one("Gravity.csv")
        if acc_name is None or grav_name is None:
            raise RecordingError(
                f"{bundle.path}: Sensor Logger's Accelerometer.csv is acceleration without gravity; "
                "the export needs TotalAcceleration.csv (Android) or Accelerometer.csv with Gravity.csv (iOS)"
            )
        user, grav = _read(bundle, acc_name, "time"), _read(bundle, grav_name, "time")
        order = np.argsort(grav.series.time, kind="stable")
        held, _ = timing.hold_on(user.series.time, grav.series.time[order], grav.series.values[order])
        ok = np.isfinite(held).all(axis=1)
        total_v = (user.series.values[ok] + held[ok]) * flip
        a = _Sensor(
            Series(user.series.time[ok], total_v, f"{acc_name} + {grav_name}"), user.time_name, user.rows
        )
        guess = "" if platform else " (no Metadata.csv: taken as iOS)"
        notes.append(f"acc: {acc_name} + {grav_name} (user acceleration + gravity; {convention}){guess}")
    mag_name = bundle.one("Magnetometer.csv")
    m = _read(bundle, mag_name, "time") if mag_name is not None else None
    unused = [n for n in bundle.names if "uncalibrated" in n.lower()]
    if unused:
        notes.append(f"not used: {', '.join(unused)}")
    fmt = "Sensor Logger" + (f" ({meta.get('platform')}, app {meta.get('appversion', '?')})" if meta else "")
    if g.time_name != "time":
        notes.append(f"time: {g.time_name} (no time column), its unit from its name or intervals")
        return g, a, m, fmt, None
    notes.append("time: the time column, ns since the epoch (Sensor Logger's unit)")
    return g, a, m, fmt, "ns"


def _android(bundle: Bundle, notes: list[str]) -> tuple[_Sensor, _Sensor, _Sensor | None, str, str | None]:
    found: dict[str, list[str]] = {k: [] for k in _KINDS}
    for n in bundle.names:
        stem = PurePosixPath(n).stem
        if not n.lower().endswith((".csv", ".txt")) or _SKIP.search(stem):
            continue
        for kind, pattern in _KINDS.items():
            if pattern.search(stem):
                found[kind].append(n)
                break
    for kind in ("gyr", "acc", "mag"):
        if len(found[kind]) > 1:
            raise RecordingError(f"{bundle.path}: several {kind} files: {', '.join(found[kind])}")
    if not found["gyr"] or not found["acc"]:
        skipped = [n for n in bundle.names if _SKIP.search(PurePosixPath(n).stem)]
        raise RecordingError(
            f"{bundle.path}: need a gyroscope and an accelerometer file (with gravity); found "
            f"{', '.join(bundle.names[:8]) or 'no files'}"
            + (f" (not used: {', '.join(skipped)})" if skipped else "")
        )
    g = _read(bundle, found["gyr"][0], None)
    a = _read(bundle, found["acc"][0], None)
    m = _read(bundle, found["mag"][0], None) if found["mag"] else None
    notes.append(f"Android-style files: {', '.join(s.series.source for s in (g, a, m) if s is not None)}")
    return g, a, m, "Android-style CSV files", None


def read_phone(path: PathLike) -> tuple[Recording, Contents]:
    """Read a Sensor Logger export or an Android-style folder (the module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        The folder or ``.zip``.

    Returns
    -------
    recording : Recording
    contents : Contents

    Raises
    ------
    ValueError
        Missing sensor files, columns or rows, text that is not a number, bad times.

    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file or folder")
    notes: list[str] = []
    with Bundle(p) as bundle:
        reader = _sensor_logger if is_sensor_logger(bundle) else _android
        g, a, m, fmt, unit = reader(bundle, notes)
    named = (timing.unit_from_name(s.time_name) for s in (g, a, m) if s is not None)
    stated = {u for u in named if u is not None}
    if len(stated) > 1:
        raise RecordingError(
            f"{p}: the sensor files' times are in different units ({', '.join(sorted(stated))})"
        )
    notes.append("frame: the device's (Android: x right, y up, z out of the screen), nothing rotated")
    rec, n2, w2 = assemble(
        g.series,
        a.series,
        mag=m.series if m is not None else None,
        unit=unit,
        time_name=g.time_name,
        name=p.stem if p.is_file() else p.name,
        where=p,
    )
    streams = []
    for s, role in ((g, "gyr"), (a, "acc"), (m, "mag")):
        if s is None:
            continue
        scale = timing.UNITS[rec.timing.unit] if rec.timing is not None else 1.0
        rate = median_rate(np.asarray(s.series.time, np.float64) * scale)
        streams.append(Stream(s.series.source, role, s.rows, rate, role))
    return rec, Contents(p, fmt, tuple(streams), tuple(notes + n2), tuple(w2))


def load_phone(path: PathLike, **options: Any) -> Recording:
    """:func:`read_phone`'s recording, its timing problems emitted as TimingWarnings."""
    rec, contents = read_phone(path, **options)
    report(rec, contents)
    return rec

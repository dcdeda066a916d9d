"""phyphox exports: one CSV per sensor (or one table), as a ``.zip``, a folder or a single ``.csv``.

phyphox (RWTH Aachen) exports each data set of an experiment as a table: a time column
``"Time (s)"`` (s since the start of the measurement) followed by that sensor's columns, e.g.
``"Gyroscope x (rad/s)"``, ``"Acceleration x (m/s^2)"``, ``"Linear Acceleration x (m/s^2)"``,
``"Magnetic field x (µT)"``. Every export variant reads: comma separated with a decimal point, or
semicolon / tab separated with a decimal point or a decimal comma; the ``meta/`` files are not used.

**Columns** are recognised by their unit and axis, not their language: ``(rad/s)`` with an axis x/y/z is
the gyro, ``(m/s^2)`` the accelerometer, ``(µT)`` the magnetometer, ``(s)`` without an axis a time
column; each sensor column belongs to the time column before it. Acceleration must include gravity
(phyphox's "Acceleration with g", the raw accelerometer); "Linear Acceleration" (without g, its name
contains "lin") is not used, and a file with only that is refused.

**Frames and units**: the device frame in Android's convention on both platforms (x right, y up, z out
of the screen; phyphox converts iOS's acceleration to it, so at rest the up axis reads +g), rad/s, m/s^2,
uT: nothing is converted. Gyro times are the clock, accel held, magnetometer placed
(:mod:`attica.data.streams`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np

from attica.data.recording import PathLike, Recording
from attica.data.streams import Contents, RecordingError, Series, Stream, assemble, median_rate, report
from attica.data.tables import Bundle, Table

__all__ = ["is_phyphox_header", "load_phyphox", "read_phyphox"]

_UNIT = re.compile(r"\(([^)]*)\)\s*$")
_UNITS = {"rad/s": "gyr", "m/s^2": "acc", "m/s²": "acc", "m/s2": "acc", "µt": "mag", "μt": "mag", "ut": "mag"}
_NAMES = {
    "gyr": "gyroscope",
    "acc": "accelerometer (with g)",
    "lin": "linear acceleration",
    "mag": "magnetometer",
}


def _column(header: str) -> tuple[str, str] | None:
    """``(kind, axis)`` of a phyphox column: kind gyr/acc/lin/mag with axis x/y/z, or ("time", "")."""
    h = header.strip().strip('"').strip()
    m = _UNIT.search(h)
    if m is None:
        return None
    unit = m.group(1).replace(" ", "").lower()
    words = h[: m.start()].split()
    axis = words[-1].lower() if words and words[-1].lower() in ("x", "y", "z") else ""
    if unit == "s" and not axis:
        return "time", ""
    kind = _UNITS.get(unit)
    if kind is None or not axis:
        return None
    if kind == "acc" and re.search(r"lin", h, re.IGNORECASE):
        kind = "lin"
    return kind, axis


def is_phyphox_header(line: str) -> bool:
    """Whether a CSV header line has phyphox's columns (a time in s and a sensor axis with its unit)."""
    cells = re.split(r"[,;\t]", line)
    kinds = [_column(c) for c in cells]
    return any(k is not None and k[0] == "time" for k in kinds) and any(
        k is not None and k[0] != "time" for k in kinds
    )


@dataclass
class _Set:
    """One sensor's columns in one table: its time column and axes."""

    table: Table
    time: int
    axes: dict[str, int] = field(default_factory=dict)

    def series(self, what: str) -> Series:
        t = self.table.floats(self.time)
        v = np.column_stack([self.table.floats(self.axes[a]) for a in "xyz"])
        ok = np.isfinite(t) & np.isfinite(v).any(axis=1)
        return Series(t[ok], v[ok], f"{self.table.source} ({what})")


def _sets(bundle: Bundle) -> dict[str, list[_Set]]:
    out: dict[str, list[_Set]] = {}
    for name in bundle.names:
        if not name.lower().endswith(".csv") or PurePosixPath(name).parts[0].lower() == "meta":
            continue
        table = bundle.table(name)
        current: dict[tuple[str, int], _Set] = {}
        time_j = -1
        for j, h in enumerate(table.header):
            col = _column(h)
            if col is None:
                continue
            kind, axis = col
            if kind == "time":
                time_j = j
            elif time_j >= 0:
                current.setdefault((kind, time_j), _Set(table, time_j)).axes[axis] = j
        for (kind, _), s in current.items():
            if set(s.axes) == {"x", "y", "z"}:
                out.setdefault(kind, []).append(s)
    return out


def read_phyphox(path: PathLike) -> tuple[Recording, Contents]:
    """Read a phyphox export (the module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        The ``.zip``, the folder of its files, or one ``.csv``.

    Returns
    -------
    recording : Recording
    contents : Contents

    Raises
    ------
    ValueError
        No gyroscope or no accelerometer with g, several tables of one sensor, text that is not a
        number, bad times.

    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file or folder")
    with Bundle(p) as bundle:
        sets = _sets(bundle)
    for kind in ("gyr", "acc", "mag"):
        if len(sets.get(kind, [])) > 1:
            where = ", ".join(s.table.source for s in sets[kind])
            raise RecordingError(f"{p}: {_NAMES[kind]} columns in several tables ({where}); give one export")
    missing = [k for k in ("gyr", "acc") if not sets.get(k)]
    if missing:
        extra = " (only linear acceleration, without g)" if "acc" in missing and sets.get("lin") else ""
        found = ", ".join(_NAMES[k] for k in sets) or "no sensor columns"
        raise RecordingError(
            f"{p}: no {' and no '.join(_NAMES[k] for k in missing)}{extra} in the export ({found})"
        )
    g = sets["gyr"][0].series("gyr")
    a = sets["acc"][0].series("acc")
    m = sets["mag"][0].series("mag") if sets.get("mag") else None
    notes = [
        "phyphox: device frame in Android's convention, rad/s, m/s^2 (with g), uT: nothing converted",
        "time: s since the start of the measurement",
    ]
    if sets.get("lin"):
        notes.append("not used: linear acceleration (without g)")
    gyr_table = sets["gyr"][0]
    rec, n2, w2 = assemble(
        g,
        a,
        mag=m,
        unit="s",
        time_name=gyr_table.table.header[gyr_table.time],
        name=p.stem if p.is_file() else p.name,
        where=p,
    )
    streams = [
        Stream(s.source, kind, len(s), median_rate(np.asarray(s.time, np.float64)), kind)
        for s, kind in ((g, "gyr"), (a, "acc"), (m, "mag"))
        if s is not None
    ]
    return rec, Contents(p, "phyphox", tuple(streams), tuple(notes + n2), tuple(w2))


def load_phyphox(path: PathLike, **options: Any) -> Recording:
    """:func:`read_phyphox`'s recording, its timing problems emitted as TimingWarnings."""
    rec, contents = read_phyphox(path, **options)
    report(rec, contents)
    return rec

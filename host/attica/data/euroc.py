"""EuRoC MAV / ASL dataset format: ``mav0/imu0/data.csv`` and the ground truth beside it.

Give the sequence folder (the one holding ``mav0/``), ``mav0`` itself, the ``imu0`` folder or its
``data.csv``; zipped sequences read too. Plain text, no extra package.

**IMU** (``imu0/data.csv``): ``#timestamp [ns], w_RS_S_x [rad s^-1], w_RS_S_y, w_RS_S_z,
a_RS_S_x [m s^-2], a_RS_S_y, a_RS_S_z``: angular rate and specific force of the sensor frame S (the
IMU's axes), as attica wants them; nothing is converted. Gyro and accel share the row (and clock); the
nominal rate is ``rate_hz`` of ``imu0/sensor.yaml`` when present, else the median interval. There is no
magnetometer.

**Ground truth** (``state_groundtruth_estimate0/data.csv``, with ``truth=True``, the default):
``q_RS_w, q_RS_x, q_RS_y, q_RS_z`` is the attitude of S in the world frame R. EuRoC's R is gravity
aligned (z up) but its heading is that of the motion-capture system, not north or east: the
inclination of a filter's estimate is comparable with it, the heading only up to a constant offset
(6-axis heading errors and the heading panel of ``attica eval`` are meaningless on it). It is held on
the IMU clock for at most 1.5 of its intervals (:mod:`attica.data.streams`), NaN elsewhere. Other ASL
datasets (TUM-VI's ``mocap0``) give poses in a frame that need not be gravity aligned; they are not read.
"""

from __future__ import annotations

import re
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np

from attica.data.recording import PathLike, Recording
from attica.data.streams import Contents, RecordingError, Series, Stream, assemble, median_rate, report
from attica.data.tables import Bundle, Table

__all__ = ["load_euroc", "read_euroc"]

_IMU = ("w_RS_S_x", "w_RS_S_y", "w_RS_S_z", "a_RS_S_x", "a_RS_S_y", "a_RS_S_z")
_TRUTH = ("q_RS_w", "q_RS_x", "q_RS_y", "q_RS_z")


def _cols(table: Table, names: tuple[str, ...]) -> list[int]:
    """Indices of the columns whose name starts with each of ``names`` (units follow a space)."""
    base = [h.split("[")[0].strip() for h in table.header]
    missing = [n for n in names if n not in base]
    if missing:
        raise RecordingError(f"{table.source}: no column {missing[0]} (columns: {', '.join(table.header)})")
    return [base.index(n) for n in names]


def is_euroc_header(first_line: str) -> bool:
    """Whether a CSV header is an ASL IMU file's (``#timestamp [ns], w_RS_S_x ...``)."""
    return "w_RS_S_x" in first_line and "timestamp" in first_line


def _locate(bundle: Bundle) -> str:
    found = bundle.find("data.csv", under="")
    imu = [n for n in found if PurePosixPath(n).parent.name == "imu0"]
    if not imu and bundle.path.is_file() and bundle.zip is None:
        return bundle.names[0]
    if not imu:
        raise RecordingError(
            f"{bundle.path}: no imu0/data.csv (an EuRoC/ASL folder holds mav0/imu0/data.csv)"
        )
    if len(imu) > 1:
        raise RecordingError(
            f"{bundle.path}: {len(imu)} imu0/data.csv files ({', '.join(imu[:4])}); give one sequence"
        )
    return imu[0]


def read_euroc(path: PathLike, *, truth: bool = True) -> tuple[Recording, Contents]:
    """Read an EuRoC/ASL sequence (the module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        Sequence folder, ``mav0``, ``imu0``, its ``data.csv``, or a zip of one of these.
    truth : bool
        Load ``state_groundtruth_estimate0`` as ``quat_true`` when present.

    Returns
    -------
    recording : Recording
    contents : Contents

    Raises
    ------
    ValueError
        No ``imu0/data.csv``, missing columns, text that is not a number, bad times.

    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file or folder")
    notes: list[str] = []
    streams: list[Stream] = []
    root = p
    if p.is_file() and p.parent.name == "imu0":
        root = p.parent.parent  # the data.csv of imu0: read its mav0 folder, for the ground truth
    elif p.is_dir() and p.name == "imu0":
        root = p.parent
    with Bundle(root) as bundle:
        imu_name = _locate(bundle)
        imu = bundle.table(imu_name)
        if len(imu) == 0:
            raise RecordingError(f"{imu.source}: no rows")
        j = _cols(imu, _IMU)
        t_imu = imu.times(0)
        values = np.column_stack([imu.floats(k) for k in j])
        rate = None
        folder = str(PurePosixPath(imu_name).parent)
        yaml = bundle.find("sensor.yaml", under="" if folder == "." else folder)
        if yaml:
            m = re.search(r"^rate_hz:\s*([0-9.eE+-]+)", bundle.text(yaml[0]), re.M)
            rate = float(m.group(1)) if m else None
            notes.append(f"nominal rate {rate:g} Hz from {yaml[0]}" if rate else f"no rate_hz in {yaml[0]}")
        notes.append(f"IMU: {imu_name} (sensor frame S, nothing converted)")
        quat = None
        above = str(PurePosixPath(folder).parent)
        gt = [
            n
            for n in bundle.find("data.csv", under="" if above == "." else above)
            if PurePosixPath(n).parent.name == "state_groundtruth_estimate0"
        ]
        if truth and gt:
            table = bundle.table(gt[0])
            q = np.column_stack([table.floats(k) for k in _cols(table, _TRUTH)])
            t_gt = table.times(0)
            quat = Series(t_gt, q / np.linalg.norm(q, axis=1, keepdims=True), gt[0])
            notes.append(
                f"quat_true: {gt[0]} (world frame gravity aligned, heading arbitrary: "
                "compare the inclination only)"
            )
            streams.append(
                Stream(gt[0], "ground truth", len(table), median_rate(_seconds(t_gt)), "quat_true")
            )
        elif gt:
            notes.append(f"ground truth {gt[0]} not loaded (truth=False)")
        else:
            notes.append("no ground truth (state_groundtruth_estimate0)")
    name = next(
        (q.stem for q in (p, *p.resolve().parents) if q.stem.lower() not in ("mav0", "imu0", "data")), p.stem
    )
    rec, n2, w2 = assemble(
        Series(t_imu, values[:, :3], imu_name),
        values[:, 3:],
        quat=quat,
        unit="ns",
        time_name="timestamp [ns]",
        rate=rate,
        name=name,
        where=p,
    )
    streams.insert(0, Stream(imu_name, "IMU (gyr, acc)", len(imu), median_rate(_seconds(t_imu)), "gyr, acc"))
    return rec, Contents(p, "EuRoC/ASL", tuple(streams), tuple(notes + n2), tuple(w2))


def _seconds(t: Any) -> Any:
    return np.asarray(t, np.float64) * 1e-9


def load_euroc(path: PathLike, **options: Any) -> Recording:
    """:func:`read_euroc`'s recording, its timing problems emitted as TimingWarnings."""
    rec, contents = read_euroc(path, **options)
    report(rec, contents)
    return rec

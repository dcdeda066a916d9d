"""PX4 ULog files (``.ulg``): the IMU, magnetometer and optionally PX4's attitude estimate.

Read with ``pyulog`` (``pip install 'attica[recordings]'``).

**Messages.**

- ``sensor_combined`` (required): ``gyro_rad`` (rad/s) and ``accelerometer_m_s2`` (m/s^2, specific
  force) in one message; its ``timestamp`` (us since boot) is the gyro's sample time and the
  recording's clock. The accel sample of a message is paired with its gyro sample (its own time,
  ``timestamp + accelerometer_timestamp_relative``, is within a period; the median offset is stated in
  the notes).
- Magnetometer (``mag="auto"``): ``vehicle_magnetometer`` (calibrated, ``magnetometer_ga``), else
  ``sensor_mag`` (a driver's raw ``x, y, z``, uncalibrated); ``mag_instance`` picks the instance (0);
  gauss times 100 to uT; time ``timestamp_sample`` when logged, else ``timestamp``; placed on the gyro
  clock. ``mag="vehicle_magnetometer"``, ``"sensor_mag"`` or ``"none"`` choose.
- ``vehicle_attitude`` (``attitude=True``): PX4's own estimate (EKF2), not ground truth; ``q`` becomes
  ``quat_true``, held on the gyro clock.

**Frames.** PX4 reports body-frame data in FRD (x forward, y right, z down) and attitudes as FRD-to-NED.
attica's convention is the sensor's axes with an ENU earth (a level sensor at rest reads +g on z), so
the reader turns every vector by ``(x, -y, -z)`` (FRD to FLU) and the attitude by
:func:`attica.data.frames.ned_frd_to_enu_flu`. The result is the same motion seen by a sensor with FLU
axes: a level vehicle at rest reads ``(0, 0, +g)``, and a filter's ENU attitude from it is comparable
with the converted ``vehicle_attitude`` (heading measured from east instead of north, as in all of
attica).

Logger dropouts (ULog ``O`` messages) and corrupt parts (skipped by pyulog) are reported as warnings.
"""

from __future__ import annotations

import io
from contextlib import redirect_stdout
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.data.frames import frd_to_flu, ned_frd_to_enu_flu
from attica.data.recording import PathLike, Recording
from attica.data.streams import (
    Contents,
    RecordingError,
    Series,
    Stream,
    assemble,
    median_rate,
    reading,
    report,
    require,
)

__all__ = ["load_ulog", "read_ulog"]

_MAGS = ("auto", "vehicle_magnetometer", "sensor_mag", "none")
_READ = ("sensor_combined", "vehicle_magnetometer", "sensor_mag", "vehicle_attitude")
_INVALID_RELATIVE = 2147483647  # sensor_combined.RELATIVE_TIMESTAMP_INVALID


def _columns(data: dict[str, NDArray[Any]], prefix: str, n: int, where: str) -> NDArray[np.float64]:
    names = [f"{prefix}[{i}]" for i in range(n)] if prefix else ["x", "y", "z"]
    missing = [k for k in names if k not in data]
    if missing:
        raise RecordingError(f"{where}: no field {missing[0]} (fields: {', '.join(sorted(data))})")
    return np.column_stack([np.asarray(data[k], np.float64) for k in names])


def _time(data: dict[str, NDArray[Any]]) -> NDArray[np.int64]:
    key = "timestamp_sample" if "timestamp_sample" in data else "timestamp"
    return np.asarray(data[key]).astype(np.int64)


def read_ulog(
    path: PathLike,
    *,
    mag: str = "auto",
    mag_instance: int = 0,
    attitude: bool = False,
    everything: bool = False,
) -> tuple[Recording, Contents]:
    """Read a PX4 ULog file (the module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        The ``.ulg`` file.
    mag : {"auto", "vehicle_magnetometer", "sensor_mag", "none"}
        The magnetometer message.
    mag_instance : int
        Its instance (``multi_id``).
    attitude : bool
        ``vehicle_attitude`` (converted to FLU-to-ENU) as ``quat_true``.
    everything : bool
        Parse every message, so that the contents list all of them (``attica info``); otherwise only the
        four messages above are parsed.

    Returns
    -------
    recording : Recording
    contents : Contents

    Raises
    ------
    ImportError
        Without ``pyulog``.
    ValueError
        Not a ULog file, no ``sensor_combined``, a missing magnetometer that was asked for, bad times.

    """
    if mag not in _MAGS:
        raise ValueError(f"mag must be one of {', '.join(_MAGS)}, got {mag!r}")
    p = Path(path)
    pyulog = require("pyulog", "PX4 ULog files")
    if not p.is_file():
        raise FileNotFoundError(f"{p}: no such file")
    chatter = io.StringIO()
    with reading(p, "PX4 ULog file", (pyulog.ULogException,)), redirect_stdout(chatter):
        log = pyulog.ULog(str(p), None if everything else list(_READ))
    found: dict[tuple[str, int], Any] = {(d.name, int(d.multi_id)): d for d in log.data_list}
    notes: list[str] = []
    warns: list[str] = []
    said = [ln.strip() for ln in chatter.getvalue().splitlines() if ln.strip()]
    if log.file_corruption or said:
        warns.append(
            f"{p.name}: corrupt in places, the damaged messages skipped ({'; '.join(said[:3]) or 'pyulog'})"
        )
    if log.dropouts:
        lost_ms = sum(int(d.duration) for d in log.dropouts)
        warns.append(f"{p.name}: {len(log.dropouts)} logger dropout(s), {lost_ms} ms of data not logged")
    sc = found.get(("sensor_combined", 0))
    if sc is None:
        names = sorted({n for n, _ in found}) if everything else []
        raise RecordingError(
            f"{p}: no sensor_combined message" + (f" (messages: {', '.join(names)})" if names else "")
        )
    d = sc.data
    t_g = _time({"timestamp": d["timestamp"]})
    gyr = frd_to_flu(_columns(d, "gyro_rad", 3, f"{p}: sensor_combined"))
    acc = frd_to_flu(_columns(d, "accelerometer_m_s2", 3, f"{p}: sensor_combined"))
    rel = np.asarray(d.get("accelerometer_timestamp_relative", np.zeros(0)), np.int64)
    rel = rel[rel != _INVALID_RELATIVE]
    offset = f", accel time offset median {float(np.median(rel)):g} us" if rel.size else ""
    notes.append(f"IMU: sensor_combined (gyro time = timestamp{offset}; accel paired with its message)")
    roles = {("sensor_combined", 0): "gyr, acc"}
    mag_series = None
    choices = ("vehicle_magnetometer", "sensor_mag") if mag == "auto" else (() if mag == "none" else (mag,))
    for name in choices:
        m = found.get((name, mag_instance))
        if m is None:
            continue
        field = _columns(
            m.data, "magnetometer_ga" if name == "vehicle_magnetometer" else "", 3, f"{p}: {name}"
        )
        mag_series = Series(_time(m.data), frd_to_flu(field) * 100.0, f"{name}[{mag_instance}]")
        roles[(name, mag_instance)] = "mag"
        calibrated = "calibrated" if name == "vehicle_magnetometer" else "raw, uncalibrated"
        notes.append(f"magnetometer: {name} instance {mag_instance} ({calibrated}; gauss -> uT)")
        break
    else:
        if mag not in ("auto", "none"):
            raise RecordingError(f"{p}: no {mag} instance {mag_instance}")
        notes.append("magnetometer: none" + (" in the log" if mag == "auto" else ", as asked"))
    quat = None
    if attitude:
        va = found.get(("vehicle_attitude", 0))
        if va is None:
            raise RecordingError(f"{p}: attitude=True, but the log has no vehicle_attitude")
        q = _columns(va.data, "q", 4, f"{p}: vehicle_attitude")
        quat = Series(_time(va.data), ned_frd_to_enu_flu(q), "vehicle_attitude")
        roles[("vehicle_attitude", 0)] = "quat_true"
        notes.append("quat_true: vehicle_attitude (PX4's estimate, FRD-to-NED converted to FLU-to-ENU)")
    notes.append("frames: PX4 FRD/NED converted to FLU/ENU: vectors (x, -y, -z)")
    rec, n2, w2 = assemble(
        Series(t_g, gyr, "sensor_combined"),
        acc,
        mag=mag_series,
        quat=quat,
        unit="us",
        name=p.stem,
        where=p,
    )
    streams = []
    for (name, inst), data in sorted(found.items()):
        t = np.asarray(data.data["timestamp"], np.float64) * 1e-6
        label = f"{name}[{inst}]" if inst or (name, 1) in found else name
        streams.append(
            Stream(label, "ULog message", int(t.size), median_rate(t), roles.get((name, inst), ""))
        )
    version = log.msg_info_dict.get("ver_sw_release_str") or log.msg_info_dict.get("ver_sw", "")
    if version:
        notes.insert(0, f"PX4 software {version}")
    return rec, Contents(p, "PX4 ULog", tuple(streams), tuple(notes + n2), tuple(warns + w2))


def load_ulog(path: PathLike, **options: Any) -> Recording:
    """:func:`read_ulog`'s recording, its timing problems emitted as TimingWarnings."""
    rec, contents = read_ulog(path, **options)
    report(rec, contents)
    return rec

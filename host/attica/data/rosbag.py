"""ROS 1 bags and ROS 2 bags (sqlite3 or MCAP storage) with ``sensor_msgs/Imu`` and ``MagneticField``.

Read with the ``rosbags`` package (``pip install 'attica[recordings]'``): a ROS 1 ``.bag`` file, a
ROS 2 bag folder (``metadata.yaml`` beside its ``.db3`` or ``.mcap`` files, compressed or not), or a
bare ROS 2 ``.db3`` file. Bare ``.mcap`` files are read by :mod:`attica.data.mcapfile` with the same
rules.

**Topics.** The IMU topic is the one ``sensor_msgs/msg/Imu`` topic of the bag (``topic=`` names one
when there are several), the magnetometer the one ``sensor_msgs/msg/MagneticField`` topic
(``mag_topic=``; ``mag_topic=""`` reads none; a bag without one gives a recording without
magnetometer). An ambiguous or missing choice is a ValueError listing the candidates. A file that
``attica run -o`` wrote has a second ``MagneticField`` topic, ``/attica/mag_offset`` (the filter's
hard-iron estimate, not a sensor): it is not a candidate unless named.

**Units.** ``angular_velocity`` rad/s and ``linear_acceleration`` m/s^2 as they are (REP-145: specific
force, +g up at rest, as attica's); ``magnetic_field`` in tesla, times 1e6 to uT.

**Time.** ``header.stamp`` of each message (the sensor's time), in ns; when a stream's stamps are all
zero (a driver that does not set them), or with ``stamp="log"``, every stream uses the log (receive)
time instead, stated in the notes. The IMU topic's clock is the recording's: accel comes in the same
message, the magnetometer is placed on it (:mod:`attica.data.streams`).

**Frames.** ROS uses REP-103: body FLU (x forward, y left, z up), earth ENU, the same as attica's, so
nothing is converted. Data in NED/FRD axes (PX4 through a bridge, a ``*_ned`` frame_id, many INS
drivers) must be converted: ``frd=True`` turns rate, acceleration and field by ``(x, -y, -z)`` and the
orientation by :func:`attica.data.frames.ned_frd_to_enu_flu`. A frame_id ending in ``_ned`` or ``_frd``
without ``frd=True`` gives a warning.

**Orientation.** An Imu message's ``orientation`` (sensor-to-ENU, ``x, y, z, w``) is the driver's own
estimate or, in a file ``attica run -o`` wrote, attica's; it becomes ``quat_true`` (``w, x, y, z``) only
with ``orientation=True``. Messages whose ``orientation_covariance[0]`` is -1 (REP: "no estimate") or
whose quaternion is zero give NaN rows.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
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

IMU = "sensor_msgs/msg/Imu"
MAG = "sensor_msgs/msg/MagneticField"
ESTIMATE_TOPIC = "/attica/mag_offset"
"""attica's hard-iron estimate in its own outputs (``attica.data.export.MAG_OFFSET_TOPIC``): no sensor."""
STAMPS = ("header", "log")

__all__ = ["IMU", "MAG", "load_rosbag", "read_rosbag"]


def msgtype(name: str) -> str:
    """``pkg/Type`` (ROS 1) as ``pkg/msg/Type`` (ROS 2); other names unchanged."""
    parts = name.split("/")
    return f"{parts[0]}/msg/{parts[1]}" if len(parts) == 2 else name


@dataclass(frozen=True)
class Topic:
    """A topic (channel) of a bag or MCAP file.

    ``usable`` is False for channels attica cannot decode (not ROS CDR/ROS 1, no schema); ``encoding``
    then says what they are.
    """

    name: str
    type: str
    count: int
    encoding: str = ""
    usable: bool = True


def _listing(topics: list[Topic]) -> str:
    return ", ".join(f"{t.name} ({t.type}, {t.count} msgs)" for t in topics) or "none"


def choose(
    topics: list[Topic], wanted: str | None, kind: str, arg: str, path: Path, required: bool
) -> Topic | None:
    """The topic of type ``kind``: ``wanted`` by name, else the only one (see the module docstring)."""
    if wanted == "" and not required:
        return None
    cands = [t for t in topics if t.usable and t.type == kind and t.name != ESTIMATE_TOPIC]
    if wanted is not None:
        named = [t for t in topics if t.name == wanted]
        if not named:
            raise RecordingError(
                f"{path}: no topic {wanted!r}; {kind} topics: {_listing(cands)}; all: {_listing(topics)}"
            )
        t = named[0]
        if t.type != kind or not t.usable:
            what = f"{t.type} ({t.encoding})" if t.encoding else t.type
            raise RecordingError(f"{path}: topic {wanted!r} is {what}, not {kind}")
        return t
    if len(cands) == 1:
        return cands[0]
    if not cands:
        if required:
            raise RecordingError(f"{path}: no {kind} topic; the topics are: {_listing(topics)}")
        return None
    raise RecordingError(
        f"{path}: {len(cands)} {kind} topics: {_listing(cands)}; choose one with {arg}='<name>'"
    )


@dataclass
class Rows:
    """Messages of one topic as they are read: stamps, log times, values, frame ids."""

    topic: Topic
    stamp: list[int] = field(default_factory=list)
    log: list[int] = field(default_factory=list)
    vec: list[tuple[float, ...]] = field(default_factory=list)
    quat: list[tuple[float, ...]] = field(default_factory=list)
    frames: set[str] = field(default_factory=set)

    def add(self, msg: Any, log_ns: int) -> None:
        """Append one deserialized Imu or MagneticField message."""
        st = msg.header.stamp
        self.stamp.append(int(st.sec) * 1_000_000_000 + int(st.nanosec))
        self.log.append(int(log_ns))
        if len(self.frames) < 8:
            self.frames.add(str(msg.header.frame_id))
        if self.topic.type == IMU:
            w, a, o = msg.angular_velocity, msg.linear_acceleration, msg.orientation
            self.vec.append((w.x, w.y, w.z, a.x, a.y, a.z))
            self.quat.append((o.w, o.x, o.y, o.z, float(msg.orientation_covariance[0])))
        else:
            f = msg.magnetic_field
            self.vec.append((f.x, f.y, f.z))


def _orientation(rows: Rows) -> NDArray[np.float64]:
    q = np.array(rows.quat, np.float64).reshape(-1, 5)
    cov0, q = q[:, 4], q[:, :4]
    norm = np.linalg.norm(q, axis=1)
    bad = (cov0 == -1.0) | ~(norm > 0.5) | ~np.isfinite(norm)
    out = np.full_like(q, np.nan)
    out[~bad] = q[~bad] / norm[~bad, None]
    return out


_FRD_NAME = re.compile(r"(ned|frd)$", re.IGNORECASE)


def build(
    path: Path,
    fmt: str,
    topics: list[Topic],
    imu: Rows,
    mag: Rows | None,
    *,
    span: float,
    stamp: str,
    orientation: bool,
    frd: bool,
    notes: list[str],
    warns: list[str],
) -> tuple[Recording, Contents]:
    """The recording and contents of the messages read (shared with :mod:`attica.data.mcapfile`)."""
    if not imu.stamp:
        raise RecordingError(f"{path}: topic {imu.topic.name} has no messages")
    notes = [*notes, f"IMU: {imu.topic.name} ({IMU})"]
    notes.append(f"magnetometer: {mag.topic.name} (tesla -> uT)" if mag is not None else "magnetometer: none")
    use_log = stamp == "log"
    if use_log:
        notes.append("time: the log (receive) time of each message, as asked (stamp='log')")
    else:
        zero = [r.topic.name for r in (imu, mag) if r is not None and r.stamp and not any(r.stamp)]
        if zero:
            use_log = True
            notes.append(f"time: header.stamp is 0 in every message of {', '.join(zero)}, so the log time")
        else:
            notes.append("time: header.stamp of each message")

    def times(r: Rows) -> NDArray[np.int64]:
        return np.array(r.log if use_log else r.stamp, np.int64)

    v = np.array(imu.vec, np.float64).reshape(-1, 6)
    gyr, acc = v[:, :3], v[:, 3:]
    field_ut = np.array(mag.vec, np.float64).reshape(-1, 3) * 1e6 if mag is not None else None
    quat = _orientation(imu) if orientation else None
    if quat is not None:
        known = int(np.count_nonzero(np.isfinite(quat[:, 0])))
        notes.append(f"quat_true: the Imu orientation ({known} of {len(quat)} messages with one)")
    frames = sorted(imu.frames | (mag.frames if mag is not None else set()))
    notes.append(f"frame_id: {', '.join(repr(f) for f in frames)}")
    if frd:
        gyr, acc = frd_to_flu(gyr), frd_to_flu(acc)
        field_ut = frd_to_flu(field_ut) if field_ut is not None else None
        quat = ned_frd_to_enu_flu(quat) if quat is not None else None
        notes.append("frames: FRD/NED converted to FLU/ENU (x, -y, -z), as asked (frd=True)")
    else:
        notes.append("frames: REP-103 FLU/ENU, as attica's (nothing converted)")
        odd = [f for f in frames if _FRD_NAME.search(f.strip("/"))]
        if odd:
            warns = [*warns, f"frame_id {', '.join(odd)} looks NED/FRD: pass frd=True to convert the axes"]
    rec, n2, w2 = assemble(
        Series(times(imu), gyr, imu.topic.name),
        acc,
        mag=Series(times(mag), field_ut, mag.topic.name)
        if mag is not None and field_ut is not None
        else None,
        quat=quat,
        unit="ns",
        name=path.stem if path.is_file() else path.name,
        where=path,
    )
    streams = []
    for t in topics:
        used = {imu.topic.name: "gyr, acc" + (", quat_true" if orientation else "")}
        if mag is not None:
            used[mag.topic.name] = "mag"
        if t.name in used:
            r = imu if t.name == imu.topic.name else mag
            assert r is not None
            rate = median_rate(times(r).astype(np.float64) * 1e-9)
        else:
            rate = (t.count - 1) / span if t.count > 1 and span > 0 else None
        kind = f"{t.type} ({t.encoding}, skipped)" if not t.usable else t.type
        streams.append(Stream(t.name, kind, t.count, rate, used.get(t.name, "")))
    return rec, Contents(path, fmt, tuple(streams), tuple(notes + n2), tuple(warns + w2))


def _format(p: Path) -> str:
    if p.is_dir():
        meta = p / "metadata.yaml"
        if not meta.is_file():
            raise RecordingError(f"{p}: a folder without metadata.yaml is not a ROS 2 bag")
        m = re.search(r"storage_identifier:\s*(\S+)", meta.read_text(errors="replace"))
        return f"ROS 2 bag ({m.group(1) if m else 'unknown storage'})"
    if p.suffix.lower() == ".bag":
        return "ROS 1 bag"
    return "ROS 2 bag file (sqlite3)"


def read_rosbag(
    path: PathLike,
    *,
    topic: str | None = None,
    mag_topic: str | None = None,
    stamp: str = "header",
    orientation: bool = False,
    frd: bool = False,
) -> tuple[Recording, Contents]:
    """Read a ROS 1 ``.bag``, a ROS 2 bag folder or a ROS 2 ``.db3`` file (the module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        The bag.
    topic, mag_topic : str, optional
        The Imu and MagneticField topics (default: the only one of each type; ``mag_topic=""``: none).
    stamp : {"header", "log"}
        Time from ``header.stamp`` (the log time when those are all zero) or from the log time.
    orientation : bool
        Take the Imu orientation as ``quat_true``.
    frd : bool
        The data is in FRD/NED axes: convert it to FLU/ENU.

    Returns
    -------
    recording : Recording
    contents : Contents
        Every topic with type, count and rate; the choices made; problems. Timing warnings are not
        emitted (:func:`load_rosbag` does).

    Raises
    ------
    ImportError
        Without the ``rosbags`` package.
    ValueError
        A file that is not a readable bag, a topic choice that is missing or ambiguous, bad times.

    """
    if stamp not in STAMPS:
        raise ValueError(f"stamp must be one of {', '.join(STAMPS)}, got {stamp!r}")
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file or folder")
    highlevel = require("rosbags.highlevel", "ROS bags")
    typesys = require("rosbags.typesys", "ROS bags")
    rb1 = require("rosbags.rosbag1", "ROS bags")
    rb2 = require("rosbags.rosbag2", "ROS bags")
    serde = require("rosbags.serde", "ROS bags")
    import sqlite3

    errors = (
        highlevel.AnyReaderError,
        rb1.ReaderError,
        rb2.ReaderError,
        typesys.TypesysError,
        serde.SerdeError,
        sqlite3.Error,
    )
    fmt = _format(p)
    with reading(p, fmt, errors):
        reader = highlevel.AnyReader([p], default_typestore=typesys.get_typestore(typesys.Stores.ROS2_HUMBLE))
        reader.open()
    try:
        with reading(p, fmt, errors):
            topics = [
                Topic(name, msgtype(info.msgtype or "?"), int(info.msgcount))
                for name, info in sorted(reader.topics.items())
            ]
            span = (reader.end_time - reader.start_time) * 1e-9 if reader.message_count else 0.0
        imu_t = choose(topics, topic, IMU, "topic", p, required=True)
        mag_t = choose(topics, mag_topic, MAG, "mag_topic", p, required=False)
        assert imu_t is not None
        rows = {imu_t.name: Rows(imu_t)}
        if mag_t is not None:
            rows[mag_t.name] = Rows(mag_t)
        conns = [c for c in reader.connections if c.topic in rows]
        with reading(p, fmt, errors):
            for conn, log_ns, raw in reader.messages(connections=conns):
                rows[conn.topic].add(reader.deserialize(raw, conn.msgtype), log_ns)
    finally:
        reader.close()
    mag_rows = rows.get(mag_t.name) if mag_t is not None else None
    return build(
        p,
        fmt,
        topics,
        rows[imu_t.name],
        mag_rows,
        span=span,
        stamp=stamp,
        orientation=orientation,
        frd=frd,
        notes=[],
        warns=[],
    )


def load_rosbag(path: PathLike, **options: Any) -> Recording:
    """:func:`read_rosbag`'s recording, its timing problems emitted as TimingWarnings."""
    rec, contents = read_rosbag(path, **options)
    report(rec, contents)
    return rec

"""Bare MCAP files (``.mcap`` without a bag's ``metadata.yaml``) with ROS 2 Imu and MagneticField.

Read with the ``mcap`` package, the messages decoded with the ``rosbags`` type system
(``pip install 'attica[recordings]'``). The rules are those of :mod:`attica.data.rosbag` (topics by
type or name, units, header stamps, frames, ``orientation=True`` for ``quat_true``); only what differs:

- **Channels**: a channel is read when its messages are ROS 2 CDR (``message_encoding`` ``cdr``) with a
  ``ros2msg`` or ``ros2idl`` schema. Channels of other encodings (JSON, protobuf, flatbuffers: Foxglove
  schemas such as ``foxglove.FrameTransform``) and schemaless ones are listed and skipped, never decoded.
  A file written by ``attica run -o out.mcap`` reads back: gyro and accel from its Imu channel, its
  orientation with ``orientation=True``.
- **Types**: from each channel's schema, so any ROS 2 distribution's files read; when a schema cannot be
  parsed, ROS 2 Humble's definition of the type is used (stated in the notes).
- **Profile**: any (``ros2``, ``""`` ...).
- **Unfinished files** (no summary section, e.g. a recorder that was killed): read from start to end,
  stated in the notes.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from attica.data.recording import PathLike, Recording
from attica.data.rosbag import IMU, MAG, STAMPS, Rows, Topic, build, choose, msgtype
from attica.data.streams import Contents, reading, report, require

__all__ = ["load_mcap", "read_mcap"]

_ROS_SCHEMAS = ("ros2msg", "ros2idl")


@dataclass
class _Channel:
    topic: str
    schema: Any | None
    encoding: str
    count: int = 0

    @property
    def type(self) -> str:
        return msgtype(self.schema.name) if self.schema is not None and self.schema.name else "?"

    @property
    def usable(self) -> bool:
        return self.encoding == "cdr" and self.schema is not None and self.schema.encoding in _ROS_SCHEMAS

    def label(self) -> str:
        schema = self.schema.encoding if self.schema is not None else "no schema"
        return f"{self.encoding or 'no encoding'}, {schema or 'no schema'}"


class _Decoder:
    """CDR messages to objects, one rosbags typestore per schema."""

    def __init__(self) -> None:
        self.typesys = require("rosbags.typesys", "MCAP files")
        self.stores: dict[int, Any] = {}
        self.fallback: list[str] = []

    def store(self, schema: Any) -> Any:
        if schema.id in self.stores:
            return self.stores[schema.id]
        ts = self.typesys
        name = msgtype(schema.name)
        try:
            text = bytes(schema.data).decode()
            types = (
                ts.get_types_from_msg(text, name)
                if schema.encoding == "ros2msg"
                else ts.get_types_from_idl(text)
            )
            store = ts.get_typestore(ts.Stores.EMPTY)
            store.register(types)
            if name not in store.fielddefs:
                raise KeyError(name)
        except (ts.TypesysError, UnicodeDecodeError, KeyError, ValueError):
            store = ts.get_typestore(ts.Stores.ROS2_HUMBLE)
            self.fallback.append(name)
        self.stores[schema.id] = store
        return store

    def decode(self, schema: Any, data: bytes) -> Any:
        return self.store(schema).deserialize_cdr(data, msgtype(schema.name))


def read_mcap(
    path: PathLike,
    *,
    topic: str | None = None,
    mag_topic: str | None = None,
    stamp: str = "header",
    orientation: bool = False,
    frd: bool = False,
) -> tuple[Recording, Contents]:
    """Read a bare ``.mcap`` file (the module docstring; options as :func:`attica.data.rosbag.read_rosbag`).

    Returns
    -------
    recording : Recording
    contents : Contents
        Every channel with type (and encoding when skipped), count and rate; the choices made; problems.

    Raises
    ------
    ImportError
        Without the ``mcap`` or ``rosbags`` package.
    ValueError
        Not a readable MCAP file, a topic choice that is missing or ambiguous, bad times.

    """
    if stamp not in STAMPS:
        raise ValueError(f"stamp must be one of {', '.join(STAMPS)}, got {stamp!r}")
    p = Path(path)
    mreader = require("mcap.reader", "MCAP files")
    mexc = require("mcap.exceptions", "MCAP files")
    decoder = _Decoder()
    serde = require("rosbags.serde", "MCAP files")
    errors = (mexc.McapError, decoder.typesys.TypesysError, serde.SerdeError)
    notes: list[str] = []
    with open(p, "rb") as f, reading(p, "MCAP file", errors):
        reader = mreader.make_reader(f)
        header = reader.get_header()
        notes.append(f"MCAP profile {header.profile!r}, written by {header.library!r}")
        try:
            summary = reader.get_summary()
        except mexc.McapError:
            summary = None
        chans: dict[int, _Channel] = {}
        kept: dict[int, list[tuple[int, Any, bytes]]] | None = None
        if summary is not None and summary.statistics is not None and summary.channels:
            counts = summary.statistics.channel_message_counts
            for cid, ch in summary.channels.items():
                schema = summary.schemas.get(ch.schema_id)
                chans[cid] = _Channel(ch.topic, schema, ch.message_encoding, int(counts.get(cid, 0)))
            stats = summary.statistics
            span = (stats.message_end_time - stats.message_start_time) * 1e-9 if stats.message_count else 0.0
        else:
            notes.append("no summary section (an unfinished file?): read from start to end")
            kept = {}
            first = last = None
            f.seek(0)
            try:
                for schema, ch, msg in mreader.NonSeekingReader(f).iter_messages(log_time_order=False):
                    c = chans.setdefault(ch.id, _Channel(ch.topic, schema, ch.message_encoding))
                    c.count += 1
                    first = msg.log_time if first is None else min(first, msg.log_time)
                    last = msg.log_time if last is None else max(last, msg.log_time)
                    if c.usable and c.type in (IMU, MAG):
                        kept.setdefault(ch.id, []).append((msg.log_time, schema, msg.data))
            except mexc.EndOfFile:
                notes.append("the file ends inside a record (cut off): the messages before it are read")
            span = (last - first) * 1e-9 if first is not None and last is not None else 0.0
        topics = [Topic(c.topic, c.type, c.count, c.label(), c.usable) for c in chans.values()]
        topics.sort(key=lambda t: t.name)
        imu_t = choose(topics, topic, IMU, "topic", p, required=True)
        mag_t = choose(topics, mag_topic, MAG, "mag_topic", p, required=False)
        assert imu_t is not None
        rows = {imu_t.name: Rows(imu_t)}
        if mag_t is not None:
            rows[mag_t.name] = Rows(mag_t)
        wanted = {cid for cid, c in chans.items() if c.topic in rows and c.usable}
        if kept is not None:
            items = sorted(
                ((t, cid, s, d) for cid in wanted for t, s, d in kept.get(cid, [])), key=lambda x: x[0]
            )
            for log_ns, cid, schema, data in items:
                rows[chans[cid].topic].add(decoder.decode(schema, data), log_ns)
        else:
            for schema, ch, msg in reader.iter_messages(topics=list(rows)):
                if ch.id in wanted:
                    rows[ch.topic].add(decoder.decode(schema, msg.data), msg.log_time)
    skipped = [t for t in topics if not t.usable]
    if skipped:
        notes.append(
            "skipped (not ROS 2 CDR): " + ", ".join(f"{t.name} ({t.type}, {t.encoding})" for t in skipped)
        )
    if decoder.fallback:
        notes.append(
            f"schema not readable, ROS 2 Humble's definition used: {', '.join(sorted(set(decoder.fallback)))}"
        )
    return build(
        p,
        "MCAP",
        topics,
        rows[imu_t.name],
        rows.get(mag_t.name) if mag_t is not None else None,
        span=span,
        stamp=stamp,
        orientation=orientation,
        frd=frd,
        notes=notes,
        warns=[],
    )


def load_mcap(path: PathLike, **options: Any) -> Recording:
    """:func:`read_mcap`'s recording, its timing problems emitted as TimingWarnings."""
    rec, contents = read_mcap(path, **options)
    report(rec, contents)
    return rec

"""Test helpers for the recording readers: a known motion, and a minimal PX4 ULog writer.

The ULog writer follows the format specification (docs.px4.io, "ULog File Format"): a 16-byte header
(magic ``ULog`` 0x01 0x12 0x35, version, start time in us), then messages of ``uint16 size, uint8 type,
payload``: ``B`` flag bits, ``I`` information, ``F`` formats (``name:type field;...``), then ``A``
subscriptions and ``D`` data (``uint16 msg_id`` + the packed struct, little-endian, no implicit padding),
and ``O`` dropouts (``uint16`` duration in ms). Padding fields at the end of a message are declared in
its format but not written in its data messages.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from attica.data import Recording
from attica.sim import SimConfig, simulate

G = 9.80665

_CODES = {
    "uint8_t": "B",
    "int8_t": "b",
    "uint16_t": "H",
    "int16_t": "h",
    "uint32_t": "I",
    "int32_t": "i",
    "uint64_t": "Q",
    "int64_t": "q",
    "float": "f",
    "double": "d",
    "bool": "?",
    "char": "c",
}


def motion(seconds: float = 3.0, rate: float = 100.0, seed: int = 1) -> Recording:
    """A short simulated recording (gyr, acc, mag in the sensor frame, quat_true sensor-to-ENU)."""
    cfg = SimConfig(duration=seconds, rate=rate, seed=seed, rest_start=0.5, rest_end=0.5, rest_breaks=0)
    return simulate(cfg)


@dataclass
class UlogTopic:
    """One logged message: name, fields ``(type, name)`` (``float[3]`` arrays allowed) and rows."""

    name: str
    fields: list[tuple[str, str]]
    rows: list[tuple[object, ...]] = field(default_factory=list)
    multi_id: int = 0

    def written(self) -> list[tuple[str, str]]:
        """The fields of a data message: the logger leaves out the padding at the end."""
        out = list(self.fields)
        while out and out[-1][1].startswith("_padding"):
            out.pop()
        return out

    def packing(self) -> str:
        codes = ""
        for typ, _ in self.written():
            base, _, count = typ.partition("[")
            codes += _CODES[base] * (int(count.rstrip("]")) if count else 1)
        return "<" + codes

    def format_text(self) -> str:
        return f"{self.name}:" + "".join(f"{typ} {name};" for typ, name in self.fields)


def _msg(kind: str, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), ord(kind)) + payload


def _info(key: str, value: str) -> bytes:
    k = f"char[{len(value)}] {key}".encode()
    return _msg("I", bytes([len(k)]) + k + value.encode())


def ulog_bytes(topics: list[UlogTopic], start_us: int = 1_000_000, dropouts: tuple[int, ...] = ()) -> bytes:
    """A ULog file of the topics, their data messages interleaved in timestamp order.

    Each row's first value is its timestamp (the first field must be ``uint64_t timestamp``).
    ``dropouts`` are durations in ms, written after the first data message.
    """
    out = bytearray(b"ULog\x01\x12\x35" + bytes([1]) + struct.pack("<Q", start_us))
    out += _msg("B", bytes(16) + bytes(24))
    out += _info("sys_name", "PX4")
    out += _info("ver_sw_release_str", "v1.14.0-test")
    for t in {t.name: t for t in topics}.values():
        out += _msg("F", t.format_text().encode())
    data: list[tuple[int, int, bytes]] = []
    for msg_id, t in enumerate(topics):
        out += _msg("A", struct.pack("<BH", t.multi_id, msg_id) + t.name.encode())
        fmt = t.packing()
        width = len(t.written())
        for row in t.rows:
            flat: list[object] = []
            for v in row[:width]:
                flat.extend(v if isinstance(v, (list, tuple, np.ndarray)) else [v])
            data.append((int(row[0]), msg_id, struct.pack("<H", msg_id) + struct.pack(fmt, *flat)))
    data.sort(key=lambda x: (x[0], x[1]))
    for i, (_, _, payload) in enumerate(data):
        out += _msg("D", payload)
        if i == 0:
            for ms in dropouts:
                out += _msg("O", struct.pack("<H", ms))
    return bytes(out)


def write_ulog(path: Path, topics: list[UlogTopic], **kwargs: object) -> Path:
    """Write :func:`ulog_bytes` to ``path``."""
    path.write_bytes(ulog_bytes(topics, **kwargs))  # type: ignore[arg-type]
    return path


SENSOR_COMBINED = [
    ("uint64_t", "timestamp"),
    ("float[3]", "gyro_rad"),
    ("uint32_t", "gyro_integral_dt"),
    ("int32_t", "accelerometer_timestamp_relative"),
    ("float[3]", "accelerometer_m_s2"),
    ("uint32_t", "accelerometer_integral_dt"),
    ("uint8_t", "accelerometer_clipping"),
    ("uint8_t", "gyro_clipping"),
    ("uint8_t[2]", "_padding0"),
]
VEHICLE_MAGNETOMETER = [
    ("uint64_t", "timestamp"),
    ("uint64_t", "timestamp_sample"),
    ("uint32_t", "device_id"),
    ("float[3]", "magnetometer_ga"),
    ("uint8_t", "calibration_count"),
    ("uint8_t[3]", "_padding0"),
]
SENSOR_MAG = [
    ("uint64_t", "timestamp"),
    ("uint64_t", "timestamp_sample"),
    ("uint32_t", "device_id"),
    ("float", "x"),
    ("float", "y"),
    ("float", "z"),
    ("float", "temperature"),
    ("uint32_t", "error_count"),
    ("bool", "is_external"),
    ("uint8_t[7]", "_padding0"),
]
VEHICLE_ATTITUDE = [
    ("uint64_t", "timestamp"),
    ("uint64_t", "timestamp_sample"),
    ("float[4]", "q"),
    ("float[4]", "delta_q_reset"),
    ("uint8_t", "quat_reset_counter"),
    ("uint8_t[7]", "_padding0"),
]


# --- ROS messages -------------------------------------------------------------------------------------

IMU = "sensor_msgs/msg/Imu"
MAG = "sensor_msgs/msg/MagneticField"


def need_package(name: str) -> None:
    """Skip (fail under CI) when an optional package of attica[recordings] is missing."""
    import importlib.util

    from helpers import need

    need(
        importlib.util.find_spec(name) is not None,
        f"{name} is not installed (pip install 'attica[recordings]')",
    )


def typestore(ros1: bool = False) -> Any:
    """rosbags' typestore of ROS 1 Noetic or ROS 2 Humble."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)


def _header(ts: Any, ns: int, frame: str, seq: int) -> Any:
    t = ts.types
    stamp = t["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
    header = t["std_msgs/msg/Header"]
    extra = {"seq": seq} if "seq" in header.__dataclass_fields__ else {}
    return header(**extra, stamp=stamp, frame_id=frame)


def imu_message(
    ts: Any, ns: int, gyr: Any, acc: Any, quat: Any = None, frame: str = "imu_link", seq: int = 0
) -> Any:
    """A sensor_msgs/Imu (quat w, x, y, z; None: unknown, covariance[0] = -1)."""
    t = ts.types
    v3 = t["geometry_msgs/msg/Vector3"]
    cov = np.zeros(9)
    if quat is None:
        quat, cov = (1.0, 0.0, 0.0, 0.0), np.array([-1.0] + [0.0] * 8)
    w, x, y, z = (float(c) for c in quat)
    return t[IMU](
        header=_header(ts, ns, frame, seq),
        orientation=t["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w),
        orientation_covariance=cov,
        angular_velocity=v3(x=float(gyr[0]), y=float(gyr[1]), z=float(gyr[2])),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=v3(x=float(acc[0]), y=float(acc[1]), z=float(acc[2])),
        linear_acceleration_covariance=np.zeros(9),
    )


def mag_message(ts: Any, ns: int, field_t: Any, frame: str = "imu_link", seq: int = 0) -> Any:
    """A sensor_msgs/MagneticField, field in tesla."""
    t = ts.types
    v3 = t["geometry_msgs/msg/Vector3"]
    return t[MAG](
        header=_header(ts, ns, frame, seq),
        magnetic_field=v3(x=float(field_t[0]), y=float(field_t[1]), z=float(field_t[2])),
        magnetic_field_covariance=np.zeros(9),
    )


T0_NS = 1_700_000_000_123_456_789


def ros_samples(
    rec: Recording,
    ros1: bool = False,
    mag_every: int = 4,
    zero_stamps: bool = False,
    quat: bool = True,
    topics: tuple[str, str] = ("/imu", "/mag"),
) -> list[tuple[str, int, Any]]:
    """``(topic, log time ns, message)`` of a recording: Imu every sample, MagneticField every
    ``mag_every``-th, on ``topics``; log times 2 ms after the stamps."""
    ts = typestore(ros1)
    period = round(1e9 / rec.rate)
    out: list[tuple[str, int, Any]] = []
    for i in range(rec.n):
        ns = T0_NS + i * period
        stamp = 0 if zero_stamps else ns
        q = rec.quat_true[i] if quat and rec.quat_true is not None else None
        out.append((topics[0], ns + 2_000_000, imu_message(ts, stamp, rec.gyr[i], rec.acc[i], q, seq=i)))
        if mag_every and i % mag_every == 0:
            out.append((topics[1], ns + 2_000_000, mag_message(ts, stamp, rec.mag[i] * 1e-6, seq=i)))
    return out


def write_ros2_bag(path: Path, samples: list[tuple[str, int, Any]], storage: str = "sqlite3") -> Path:
    """A ROS 2 bag folder written by rosbags (``storage``: sqlite3 or mcap)."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    ts = typestore()
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conns: dict[str, Any] = {}
        for topic, ns, msg in samples:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msg.__msgtype__, typestore=ts)
            w.write(conns[topic], ns, bytes(ts.serialize_cdr(msg, msg.__msgtype__)))
    return path


def write_ros1_bag(path: Path, samples: list[tuple[str, int, Any]]) -> Path:
    """A ROS 1 bag written by rosbags (messages made with :func:`typestore` ``(ros1=True)``)."""
    from rosbags.rosbag1 import Writer

    ts = typestore(ros1=True)
    with Writer(path) as w:
        conns: dict[str, Any] = {}
        for topic, ns, msg in samples:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msg.__msgtype__, typestore=ts)
            w.write(conns[topic], ns, bytes(ts.serialize_ros1(msg, msg.__msgtype__)))
    return path


def write_bare_mcap(
    path: Path, samples: list[tuple[str, int, Any]], others: bool = True, finish: bool = True
) -> Path:
    """A bare MCAP written with the mcap package: profile "", ROS 2 CDR channels with ros2msg schemas,
    and (``others``) a JSON foxglove.FrameTransform and a protobuf channel that the reader must skip."""
    import json

    from mcap.writer import CompressionType, Writer

    ts = typestore()
    with open(path, "wb") as f:
        w = Writer(f, compression=CompressionType.NONE, use_chunking=finish)
        w.start(profile="", library="attica tests")
        chans: dict[str, int] = {}
        schemas: dict[str, int] = {}
        if others:
            js = w.register_schema("foxglove.FrameTransform", "jsonschema", b'{"type": "object"}')
            chans["/tf_json"] = w.register_channel("/tf_json", "json", js)
            pb = w.register_schema("foxglove.Imu", "protobuf", b"\x0a\x03not a descriptor")
            chans["/imu_pb"] = w.register_channel("/imu_pb", "protobuf", pb)
        for topic, ns, msg in samples:
            kind = msg.__msgtype__
            if kind not in schemas:
                schemas[kind] = w.register_schema(
                    kind, "ros2msg", ts.generate_msgdef(kind, ros_version=2)[0].encode()
                )
            if topic not in chans:
                chans[topic] = w.register_channel(topic, "cdr", schemas[kind])
            w.add_message(chans[topic], log_time=ns, data=bytes(ts.serialize_cdr(msg, kind)), publish_time=ns)
            if others and kind == IMU:
                tf = {"parent_frame_id": "enu", "child_frame_id": "imu", "rotation": {"w": 1.0}}
                w.add_message(chans["/tf_json"], log_time=ns, data=json.dumps(tf).encode(), publish_time=ns)
                w.add_message(chans["/imu_pb"], log_time=ns, data=b"\x08\x01", publish_time=ns)
        if finish:
            w.finish()
    return path


def quat_from_matrix(m: Any) -> Any:
    """``w, x, y, z`` of rotation matrices (N, 3, 3), w >= 0 (Shepperd's method, a test-side reference)."""
    m = np.asarray(m, np.float64)
    out = np.empty((m.shape[0], 4))
    for i, r in enumerate(m):
        tr = np.trace(r)
        if tr > 0:
            s = 2.0 * np.sqrt(1.0 + tr)
            q = [0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
        else:
            k = int(np.argmax(np.diag(r)))
            j, h = (k + 1) % 3, (k + 2) % 3
            s = 2.0 * np.sqrt(1.0 + r[k, k] - r[j, j] - r[h, h])
            q = [0.0] * 4
            q[0] = (r[h, j] - r[j, h]) / s
            q[1 + k] = 0.25 * s
            q[1 + j] = (r[j, k] + r[k, j]) / s
            q[1 + h] = (r[h, k] + r[k, h]) / s
        q = np.array(q)
        out[i] = q if q[0] >= 0 else -q
    return out


def matrix_from_quat(q: Any) -> Any:
    """Rotation matrices (N, 3, 3) of ``w, x, y, z`` quaternions."""
    w, x, y, z = np.asarray(q, np.float64).T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


# --- PX4 -----------------------------------------------------------------------------------------------

T0_US = 20_000_000
FLIP = np.array([1.0, -1.0, -1.0])  # FLU <-> FRD, its own inverse
ENU_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # ENU <-> NED, its own inverse


def ned_frd(q_enu_flu: np.ndarray) -> np.ndarray:
    """PX4's attitude of an ENU/FLU one, by matrices: R_NED<-FRD = P R_ENU<-FLU F (test-side reference)."""
    r = ENU_NED @ matrix_from_quat(q_enu_flu) @ np.diag(FLIP)
    return quat_from_matrix(r)


def px4_topics(
    rec: Recording, skip: range = range(0), mag_name: str = "vehicle_magnetometer"
) -> list[UlogTopic]:
    """sensor_combined at the recording's rate, the magnetometer every 4th sample (sampled 300 us after the
    gyro), vehicle_attitude every 2nd: PX4's FRD/NED conventions and gauss."""
    period = round(1e6 / rec.rate)
    sc, mag, att = [], [], []
    q_px4 = ned_frd(rec.quat_true)
    for i in range(rec.n):
        t = T0_US + i * period
        if i not in skip:
            sc.append((t, rec.gyr[i] * FLIP, period, 0, rec.acc[i] * FLIP, period, 0, 0, [0, 0]))
        if i % 4 == 0:
            gauss = rec.mag[i] * FLIP / 100.0
            if mag_name == "vehicle_magnetometer":
                mag.append((t + 500, t + 300, 7, gauss, 1, [0, 0, 0]))
            else:
                mag.append((t + 500, t + 300, 7, *gauss, 35.0, 0, True, [0] * 7))
        if i % 2 == 0:
            att.append((t, t, q_px4[i], [1.0, 0.0, 0.0, 0.0], 0, [0] * 7))
    fields = VEHICLE_MAGNETOMETER if mag_name == "vehicle_magnetometer" else SENSOR_MAG
    return [
        UlogTopic("sensor_combined", SENSOR_COMBINED, sc),
        UlogTopic(mag_name, fields, mag),
        UlogTopic("vehicle_attitude", VEHICLE_ATTITUDE, att),
    ]

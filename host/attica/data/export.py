"""Filter outputs written where other tools look: ``.npz``, ``.csv`` and ``.mcap`` (``attica run -o``).

One file holds one filter's outputs over one recording, one row (or message) per sample:

- ``.npz``: the fields of :data:`attica.outputs.OUTPUT_DTYPE` as arrays (``q``, ``euler``, ...).
- ``.csv``: ``#`` comment lines that state every unit, frame and flag bit, one header row, then one
  row per sample (:func:`write_csv`; pandas reads it with ``comment="#"``).
- ``.mcap``: ROS 2 messages in CDR for Foxglove, ``ros2 bag``, rosbags and other MCAP tools
  (:func:`write_mcap`; the optional packages of ``pip install 'attica[recordings]'``).

Time: a recording with a time of its own (:attr:`attica.data.Recording.time`, e.g. the time column of
a log) is written on that clock; one without gets the time from its first sample, ``index / rate``.

Covariance: ``att_output_t.cov`` holds a diagonal whose meaning depends on the kind; :data:`COVARIANCE`
(:mod:`attica.data.covariance`) names its columns and says how it becomes the 3x3 orientation covariance
of a ROS ``sensor_msgs/msg/Imu``.

Hard-iron offset: a mars or mekf whose on-device estimate runs (``hard_iron_tau`` > 0) gives each
sample's estimate (:data:`attica.outputs.MAG_OFFSET_DTYPE`, ``Filter.run(mag_offset=...)``) to every
format: the CSV's ``mag_offset_*`` columns, the ``.npz``'s ``mag_offset`` arrays, the ``.mcap``'s
:data:`MAG_OFFSET_TOPIC`.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.data.covariance import COVARIANCE, UNKNOWN_YAW, Covariance, orientation_covariance
from attica.data.rosbag import ESTIMATE_TOPIC
from attica.kinds import info
from attica.outputs import MAG_OFFSET_DTYPE
from attica.settings import OUTPUT_INVALID, FilterKind, Flag

__all__ = [
    "COVARIANCE",
    "IMU_TOPIC",
    "FLAGS_TOPIC",
    "MAG_OFFSET_COLUMNS",
    "MAG_OFFSET_TOPIC",
    "MAG_TOPIC",
    "TF_TOPIC",
    "OUTPUT_INVALID",
    "OUTPUT_SUFFIXES",
    "Covariance",
    "UNKNOWN_YAW",
    "check_output",
    "csv_columns",
    "orientation_covariance",
    "output_format",
    "ros_stamps",
    "sample_times",
    "stamp_problem",
    "write_csv",
    "write_mcap",
    "write_npz",
    "write_outputs",
]

F64 = NDArray[np.float64]
PathLike = str | os.PathLike[str]

OUTPUT_SUFFIXES = (".npz", ".csv", ".mcap")
"""The output formats, by file suffix (any case)."""


RECORDINGS_EXTRA = "pip install 'attica[recordings]'"
"""How to install the packages that .mcap needs (mcap, rosbags)."""


def output_format(path: PathLike) -> str:
    """The format of an output file by its suffix: ``".npz"``, ``".csv"`` or ``".mcap"``.

    Raises
    ------
    ValueError
        For any other suffix (the message lists the choices).

    """
    suffix = Path(path).suffix.lower()
    if suffix not in OUTPUT_SUFFIXES:
        got = f"unknown suffix {Path(path).suffix!r}" if suffix else "no suffix"
        raise ValueError(f"{path}: {got}; use {', '.join(OUTPUT_SUFFIXES[:-1])} or {OUTPUT_SUFFIXES[-1]}")
    return suffix


def sample_times(rec: Any) -> tuple[F64, bool]:
    """Time of each sample in s and whether it is the recording's own clock.

    ``(rec.time, True)`` for a recording with a time of its own (any origin, e.g. Unix time);
    ``(rec.t, False)`` otherwise: from 0 at the first sample, ``index / rate``.
    """
    time = getattr(rec, "time", None)
    if time is not None:
        return np.asarray(time, np.float64), True
    return np.asarray(rec.t, np.float64), False


def _kind_text(kind: FilterKind, settings: Any) -> str:
    k = info(kind)
    return f"{k.label} ({k.axes(settings)}-axis: {', '.join(k.inputs(settings))})"


MAG_OFFSET_COLUMNS = ("mag_offset_x", "mag_offset_y", "mag_offset_z", "mag_offset_estimated")
"""The CSV columns of the hard-iron estimate (after ``steps``; only with a ``mag_offset``)."""


def csv_columns(kind: FilterKind | str, mag_offset: bool = False) -> list[str]:
    """The columns of :func:`write_csv` for ``kind``, in order (``mag_offset``: the hard-iron ones too)."""
    k = info(kind)
    cov = COVARIANCE[k.kind].columns if k.kind in COVARIANCE else ()
    return [
        "time",
        "q_w",
        "q_x",
        "q_y",
        "q_z",
        "roll",
        "pitch",
        "yaw",
        "gyro_bias_x",
        "gyro_bias_y",
        "gyro_bias_z",
        *cov,
        "flags",
        "steps",
        *(MAG_OFFSET_COLUMNS if mag_offset else ()),
    ]


CONVENTION_AXES = {
    "enu": "ENU: x east, y north, z up",
    "ned": "NED: x north, y east, z down",
    "nwu": "NWU: x north, y west, z up",
}
"""The earth frames of the output conventions (att_calib.h), as the CSV header names them."""


MCAP_ENU_ONLY = (
    "an .mcap output holds sensor_msgs/Imu in the ENU world frame (REP-145), but the calibration's output "
    "convention is {convention}: leave it at enu for .mcap (or write .csv / .npz)"
)
"""The error of an .mcap output with a non-ENU output convention."""


def _csv_header(
    kind: FilterKind, rec: Any, absolute: bool, settings: Any, convention: str, mag_offset: bool
) -> list[str]:
    k = info(kind)
    clock = (
        "s on the recording's own clock (its time as recorded, any origin, e.g. Unix time)"
        if absolute
        else "s from the first sample (the recording has no time of its own: index / rate)"
    )
    lines = [
        f"attica run outputs: {_kind_text(k.kind, settings)} over {rec.name or 'a recording'}, "
        f"{len(rec.gyr)} samples at {rec.rate:g} Hz",
        f"time: {clock}",
        f"q_w, q_x, q_y, q_z: attitude, unit quaternion sensor-to-earth ({CONVENTION_AXES[convention]})",
        "roll, pitch, yaw: ZYX Euler angles of the attitude, rad",
        "gyro_bias_x, gyro_bias_y, gyro_bias_z: gyro bias estimate, rad/s, sensor frame"
        + ("" if k.gyro_bias else f" (0: {k.label} does not estimate one)"),
    ]
    if k.kind in COVARIANCE:
        lines.append(f"{', '.join(COVARIANCE[k.kind].columns)}: {COVARIANCE[k.kind].meaning}")
        if convention != "enu":
            lines.append("the covariance columns are about the ENU axes whatever the output convention")
    else:
        lines.append(f"no covariance columns: {k.label} does not estimate a covariance")
    bits = ", ".join(f"0x{f.value:04X} {f.name}" for f in Flag)
    lines += [
        f"flags: ATT_FLAG_* bits of the step (an integer, the sum of: {bits}); with NOT_READY or BAD_ARG "
        "the row is not an attitude estimate; INITIALISED marks a (re)initialisation and every step of a "
        "start's or a clipping gyro's recovery (recovery_time), not a new start each time",
        "steps: filter steps since the start (uint32, wraps)",
    ]
    if mag_offset:
        lines.append(
            "mag_offset_x, mag_offset_y, mag_offset_z: the hard-iron offset the filter estimates and "
            "subtracts from its mag samples after this step, uT, the frame of the samples it sees (after a "
            "calibration's input stage); mag_offset_estimated: 1 once the rotations made it observable "
            "(0: the offset is 0, not applied yet)"
        )
    return [f"# {line}" for line in lines]


def write_csv(
    path: PathLike,
    out: NDArray[np.void],
    rec: Any,
    kind: FilterKind | str,
    settings: Any = None,
    convention: str = "enu",
    mag_offset: NDArray[np.void] | None = None,
) -> None:
    """Write one filter's outputs as CSV: comment lines, a header row, one row per sample.

    The columns are :func:`csv_columns`; the ``#`` lines before them state the units, the frames, the
    clock of ``time`` (:func:`sample_times`), what the covariance columns hold for the kind and the
    name of every flag bit. Floats are written with 9 significant digits, which give back the float32
    outputs exactly; ``time`` with 9 decimals (ns).

    Parameters
    ----------
    path : str or os.PathLike
        Destination (its directory must exist).
    out : ndarray of :data:`attica.outputs.OUTPUT_DTYPE`, shape (N,)
        The outputs (``Filter.run``), one per sample of ``rec``.
    rec : attica.data.Recording
        The recording the filter ran over (its time, name and rate).
    kind : FilterKind or str
        The filter kind (its covariance columns).
    settings : optional
        The kind's settings of the run (None: its defaults), for the header's axes.
    convention : str
        The earth frame of ``q`` and the Euler angles (the calibration's output convention: ``enu``,
        ``ned`` or ``nwu``), for the header; the covariance stays about the ENU axes.
    mag_offset : ndarray of :data:`attica.outputs.MAG_OFFSET_DTYPE`, shape (N,), optional
        The hard-iron estimate after each step (``Filter.run(mag_offset=...)``): the columns
        :data:`MAG_OFFSET_COLUMNS` after ``steps``.

    """
    k = info(kind)
    if convention not in CONVENTION_AXES:
        raise ValueError(f"unknown output convention {convention!r} (enu, ned, nwu)")
    times, absolute = sample_times(rec)
    if len(times) != len(out):
        raise ValueError(f"{len(out)} outputs for a recording of {len(times)} samples")
    _check_mag_offset(mag_offset, len(out))
    ncov = len(COVARIANCE[k.kind].columns) if k.kind in COVARIANCE else 0
    cols = [
        times[:, None],
        out["q"],
        out["euler"],
        out["gyro_bias"],
        out["cov"][:, :ncov],
        out["flags"][:, None],
        out["steps"][:, None],
    ]
    fmt = ["%.9f"] + ["%.9g"] * (10 + ncov) + ["%d", "%d"]
    if mag_offset is not None:
        cols += [mag_offset["offset"], mag_offset["estimated"][:, None]]
        fmt += ["%.9g"] * 3 + ["%d"]
    table = np.hstack([np.asarray(c, np.float64) for c in cols])
    header = _csv_header(k.kind, rec, absolute, settings, convention, mag_offset is not None)
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write("\n".join(header) + "\n")
        f.write(",".join(csv_columns(k.kind, mag_offset is not None)) + "\n")
        np.savetxt(f, table, fmt=fmt, delimiter=",")


def _check_mag_offset(mag_offset: NDArray[np.void] | None, n: int) -> None:
    """ValueError unless ``mag_offset`` is None or (n,) records of :data:`attica.outputs.MAG_OFFSET_DTYPE`."""
    if mag_offset is None:
        return
    if mag_offset.dtype != MAG_OFFSET_DTYPE or mag_offset.shape != (n,):
        raise ValueError(
            f"mag_offset must be ({n},) records of attica.outputs.MAG_OFFSET_DTYPE (one per output), "
            f"not {mag_offset.shape} {mag_offset.dtype}"
        )


def write_npz(path: PathLike, out: NDArray[np.void], mag_offset: NDArray[np.void] | None = None) -> None:
    """Write the output fields as arrays of a compressed ``.npz`` (``q``, ``euler``, ``flags`` ...).

    With ``mag_offset`` (the hard-iron estimate after each step, :data:`attica.outputs.MAG_OFFSET_DTYPE`)
    also ``mag_offset`` ((N, 3) float32, uT) and ``mag_offset_estimated`` ((N,) bool).
    """
    _check_mag_offset(mag_offset, len(out))
    arrays: dict[str, Any] = {name: out[name] for name in out.dtype.names or ()}
    if mag_offset is not None:
        arrays["mag_offset"] = np.ascontiguousarray(mag_offset["offset"])
        arrays["mag_offset_estimated"] = np.ascontiguousarray(mag_offset["estimated"])
    with open(path, "wb") as f:  # a file object: numpy appends no second ".npz" (e.g. to "out.NPZ")
        np.savez_compressed(f, **arrays)


def ros_stamps(times: F64) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """(sec, nanosec) of ``builtin_interfaces/msg/Time`` nearest to each time in s (nanosec < 1e9)."""
    t = np.asarray(times, np.float64)
    sec = np.floor(t)
    nsec = np.rint((t - sec) * 1e9).astype(np.int64)  # t - floor(t) is exact in float64
    carry = nsec >= 1_000_000_000
    return sec.astype(np.int64) + carry, np.where(carry, nsec - 1_000_000_000, nsec)


STAMP_LIMIT = 2.0**31
"""Stamps hold 0 <= t < 2^31 s: ``builtin_interfaces/msg/Time.sec`` is an int32, MCAP log times unsigned."""


def stamp_problem(times: F64) -> str | None:
    """Why ``times`` (s) cannot be ROS stamps and MCAP log times, or None when they can."""
    if len(times) and not (times[0] >= 0.0 and times[-1] < STAMP_LIMIT):
        return (
            f"the recording's time runs from {times[0]:g} to {times[-1]:g} s, but ROS stamps and MCAP log "
            "times need 0 <= t < 2^31 s"
        )
    return None


def _recordings_packages() -> tuple[Any, Any]:
    """(mcap.writer.Writer, a ROS 2 typestore of rosbags); ImportError naming the extra when missing."""
    try:
        from mcap.writer import Writer
        from rosbags.typesys import Stores, get_typestore
    except ImportError as exc:
        raise ImportError(
            f"writing .mcap needs the packages mcap and rosbags ({exc.name or exc} is missing): "
            f"{RECORDINGS_EXTRA}"
        ) from None
    return Writer, get_typestore(Stores.ROS2_HUMBLE)


def check_output(path: PathLike, rec: Any = None) -> str:
    """Refuse before the work what :func:`write_outputs` would refuse after it; returns the format.

    The suffix (:func:`output_format`); for ``.mcap`` its packages and, given the recording ``rec``,
    whether its times can be stamps (:func:`stamp_problem`).

    Raises
    ------
    ValueError
        Unknown suffix, or times that cannot be stamps.
    ImportError
        ``.mcap`` without the packages mcap and rosbags (``pip install 'attica[recordings]'``).

    """
    fmt = output_format(path)
    if fmt == ".mcap":
        _recordings_packages()
        problem = stamp_problem(sample_times(rec)[0]) if rec is not None else None
        if problem:
            raise ValueError(f"{path}: {problem}")
    return fmt


IMU_TYPE = "sensor_msgs/msg/Imu"
TF_TYPE = "tf2_msgs/msg/TFMessage"
MAG_TYPE = "sensor_msgs/msg/MagneticField"

IMU_TOPIC = "/attica/imu"
"""Topic of the ``sensor_msgs/msg/Imu`` messages."""
TF_TOPIC = "/tf"
"""Topic of the ``tf2_msgs/msg/TFMessage`` messages (where ROS tools and Foxglove look for transforms)."""
MAG_TOPIC = "/attica/mag"
"""Topic of the ``sensor_msgs/msg/MagneticField`` messages (the input's magnetometer samples)."""
FLAGS_TYPE = "std_msgs/msg/UInt32"
FLAGS_TOPIC = "/attica/flags"
"""Topic of the ``std_msgs/msg/UInt32`` messages: each step's ATT_FLAG_* bits (the metadata names them)."""
MAG_OFFSET_TOPIC = ESTIMATE_TOPIC
"""Topic of the hard-iron estimate, ``sensor_msgs/msg/MagneticField`` (only with a ``mag_offset``; the
readers of :mod:`attica.data.rosbag` do not take it for the magnetometer unless it is named)."""


def write_mcap(
    path: PathLike,
    out: NDArray[np.void],
    rec: Any,
    kind: FilterKind | str,
    *,
    frame_id: str = "imu",
    world_frame: str = "enu",
    settings: Any = None,
    mag_offset: NDArray[np.void] | None = None,
) -> None:
    """Write one filter's outputs as an MCAP file of ROS 2 messages (CDR, ``ros2msg`` schemas).

    Per sample, all stamped with the sample's time (:func:`sample_times`, as header.stamp and as the
    MCAP log and publish times):

    - :data:`IMU_TOPIC`, ``sensor_msgs/msg/Imu`` in ``frame_id``: ``orientation`` = q (the sensor
      frame's attitude in the ENU world frame, as REP-145 asks of an IMU with an orientation estimate),
      ``orientation_covariance`` from :func:`orientation_covariance`; ``angular_velocity`` and
      ``linear_acceleration`` the input sample as recorded (rad/s, m/s^2 specific force, sensor frame),
      their covariances all zeros (unknown), or element 0 = -1 for a sample that is not finite.
    - :data:`TF_TOPIC`, ``tf2_msgs/msg/TFMessage``: one transform ``world_frame`` -> ``frame_id``, rotation q,
      translation 0, for Foxglove's 3D panel. It takes its transforms from ``tf2_msgs/msg/TFMessage`` as
      from its own ``foxglove.FrameTransform``; the ROS message keeps the whole file in one encoding
      (CDR with ``ros2msg`` schemas), which rosbags' ``AnyReader``, ``ros2 bag play`` (RViz) and
      PlotJuggler read as any ROS 2 bag. A ``foxglove.FrameTransform`` in JSON would be the one channel
      that ROS tools cannot decode: rosbags refuses the whole file for its ``jsonschema`` schema.
    - :data:`MAG_TOPIC`, ``sensor_msgs/msg/MagneticField`` in ``frame_id``, in T, for the samples that
      have one (a recording without a magnetometer has none): with the Imu topic the file is again
      a complete recording.
    - :data:`FLAGS_TOPIC`, ``std_msgs/msg/UInt32``: the step's ATT_FLAG_* bits (a recovery, a rejected
      field, a clipped sample: what the live view's ``/attica/status`` shows); the metadata names the bits.
    - :data:`MAG_OFFSET_TOPIC`, with ``mag_offset`` (the hard-iron estimate after each step,
      :data:`attica.outputs.MAG_OFFSET_DTYPE`): ``sensor_msgs/msg/MagneticField`` in ``frame_id``, in T,
      covariance all zeros, or element 0 = -1 while the offset is not observable yet (0, not applied).

    The MCAP metadata record ``attica`` names the kind, the clock of the stamps and the covariance's
    meaning. The stamps need 0 <= time < 2^31 s (``builtin_interfaces/msg/Time`` and MCAP log times);
    a recording's own clock outside that is refused (a ValueError). ``settings``: the kind's settings of
    the run (None: its defaults), for the metadata's ``filter`` entry (its axes and inputs: a mekf with
    ``use_mag`` off is 6-axis).

    Raises
    ------
    ImportError
        Without the packages mcap and rosbags (``pip install 'attica[recordings]'``).
    ValueError
        Outputs and recording of different lengths, or times the stamps cannot hold.

    """
    writer_class, ts = _recordings_packages()
    k = info(kind)
    times, absolute = sample_times(rec)
    if len(times) != len(out):
        raise ValueError(f"{len(out)} outputs for a recording of {len(times)} samples")
    _check_mag_offset(mag_offset, len(out))
    problem = stamp_problem(times)
    if problem:
        raise ValueError(problem)
    sec, nsec = ros_stamps(times)
    log_ns = sec * 1_000_000_000 + nsec
    q = np.asarray(out["q"], np.float64)
    ocov = orientation_covariance(k.kind, out)
    gyr = np.asarray(rec.gyr, np.float64)
    acc = np.asarray(rec.acc, np.float64)
    mag = np.asarray(rec.mag, np.float64)
    has_mag = np.isfinite(mag).all(axis=1) & (mag != 0.0).any(axis=1)
    meta = {
        "kind": k.label,
        "filter": _kind_text(k.kind, settings),
        "clock": "the recording's own clock" if absolute else "from the first sample (index / rate)",
        "orientation": "q sensor-to-earth, ENU world frame",
        "orientation_covariance": COVARIANCE[k.kind].orientation
        if k.kind in COVARIANCE
        else f"all zeros (unknown): {k.label} does not estimate a covariance",
        "no_estimate": "orientation_covariance[0] = -1 where the filter had no attitude estimate yet",
        "frames": f"{world_frame} (ENU) -> {frame_id} (sensor)",
        "flags": f"{FLAGS_TOPIC}: ATT_FLAG_* bits of each step, the sum of: "
        + ", ".join(f"0x{f.value:04X} {f.name}" for f in Flag),
    }
    if mag_offset is not None:
        meta["mag_offset"] = (
            f"{MAG_OFFSET_TOPIC}: the hard-iron offset the filter estimates and subtracts from its mag "
            "samples after each step, T, in the frame of the samples the filter sees (the sensor frame, or "
            "after a calibration's input stage); covariance[0] = -1 while it is not observable yet "
            "(0, not applied)"
        )
    types = ts.types
    imu_t, tf_t, field_t, flags_t = types[IMU_TYPE], types[TF_TYPE], types[MAG_TYPE], types[FLAGS_TYPE]
    header_t, time_t, quat_t, vec_t = (
        types["std_msgs/msg/Header"],
        types["builtin_interfaces/msg/Time"],
        types["geometry_msgs/msg/Quaternion"],
        types["geometry_msgs/msg/Vector3"],
    )
    stamped_t, transform_t = types["geometry_msgs/msg/TransformStamped"], types["geometry_msgs/msg/Transform"]
    zero = vec_t(x=0.0, y=0.0, z=0.0)
    unknown = np.zeros(9, np.float64)
    not_yet = np.zeros(9, np.float64)
    not_yet[0] = -1.0
    flags = np.asarray(out["flags"], np.uint32)
    with open(path, "wb") as stream:
        w = writer_class(stream)
        w.start(profile="ros2", library=f"attica {_version()}")
        topics = [(IMU_TOPIC, IMU_TYPE), (TF_TOPIC, TF_TYPE), (FLAGS_TOPIC, FLAGS_TYPE)]
        topics += [(MAG_TOPIC, MAG_TYPE)] if has_mag.any() else []
        topics += [(MAG_OFFSET_TOPIC, MAG_TYPE)] if mag_offset is not None else []
        chan = {}
        for topic, name in topics:
            schema = w.register_schema(name, "ros2msg", ts.generate_msgdef(name, ros_version=2)[0].encode())
            chan[topic] = w.register_channel(topic, "cdr", schema)
        w.add_metadata("attica", meta)
        for i in range(len(out)):
            stamp = time_t(sec=int(sec[i]), nanosec=int(nsec[i]))
            header = header_t(stamp=stamp, frame_id=frame_id)
            rot = quat_t(x=q[i, 1], y=q[i, 2], z=q[i, 3], w=q[i, 0])
            imu = imu_t(
                header=header,
                orientation=rot,
                orientation_covariance=ocov[i],
                angular_velocity=vec_t(x=gyr[i, 0], y=gyr[i, 1], z=gyr[i, 2]),
                angular_velocity_covariance=_sensor_covariance(gyr[i]),
                linear_acceleration=vec_t(x=acc[i, 0], y=acc[i, 1], z=acc[i, 2]),
                linear_acceleration_covariance=_sensor_covariance(acc[i]),
            )
            transform = stamped_t(
                header=header_t(stamp=stamp, frame_id=world_frame),
                child_frame_id=frame_id,
                transform=transform_t(translation=zero, rotation=rot),
            )
            ns = int(log_ns[i])
            w.add_message(chan[IMU_TOPIC], ns, bytes(ts.serialize_cdr(imu, IMU_TYPE)), ns, sequence=i)
            tf = tf_t(transforms=[transform])
            w.add_message(chan[TF_TOPIC], ns, bytes(ts.serialize_cdr(tf, TF_TYPE)), ns, sequence=i)
            if has_mag[i]:
                m = mag[i] * 1e-6  # uT to T
                field = field_t(
                    header=header,
                    magnetic_field=vec_t(x=m[0], y=m[1], z=m[2]),
                    magnetic_field_covariance=unknown,
                )
                w.add_message(chan[MAG_TOPIC], ns, bytes(ts.serialize_cdr(field, MAG_TYPE)), ns, sequence=i)
            fl = flags_t(data=int(flags[i]))
            w.add_message(chan[FLAGS_TOPIC], ns, bytes(ts.serialize_cdr(fl, FLAGS_TYPE)), ns, sequence=i)
            if mag_offset is not None:
                h = np.asarray(mag_offset["offset"][i], np.float64) * 1e-6  # uT to T
                field = field_t(
                    header=header,
                    magnetic_field=vec_t(x=h[0], y=h[1], z=h[2]),
                    magnetic_field_covariance=unknown if mag_offset["estimated"][i] else not_yet,
                )
                data = bytes(ts.serialize_cdr(field, MAG_TYPE))
                w.add_message(chan[MAG_OFFSET_TOPIC], ns, data, ns, sequence=i)
        w.finish()


def _sensor_covariance(v: F64) -> F64:
    """All zeros (unknown) for a finite sample; element 0 = -1 (no value) for one that is not."""
    c = np.zeros(9, np.float64)
    if not np.isfinite(v).all():
        c[0] = -1.0
    return c


def _version() -> str:
    import attica

    return str(attica.__version__)


def write_outputs(
    path: PathLike,
    out: NDArray[np.void],
    rec: Any,
    kind: FilterKind | str,
    settings: Any = None,
    convention: str = "enu",
    mag_offset: NDArray[np.void] | None = None,
) -> None:
    """Write one filter's outputs in the format of ``path``'s suffix (:data:`OUTPUT_SUFFIXES`).

    ``convention`` is the earth frame of the outputs' ``q`` (the calibration's output convention): the
    CSV's header says it; ``.mcap`` takes ENU only (REP-145's world frame of ``sensor_msgs/Imu``).
    ``mag_offset``: the hard-iron estimate after each step (:data:`attica.outputs.MAG_OFFSET_DTYPE`),
    written in every format.

    Raises
    ------
    ValueError
        For an unknown suffix (:func:`output_format`), outputs that do not match the recording, or
        ``.mcap`` with a convention other than ENU.
    ImportError
        For ``.mcap`` without its packages (``pip install 'attica[recordings]'``).
    OSError
        When the file cannot be written.

    """
    fmt = output_format(path)
    if fmt == ".mcap" and convention != "enu":
        raise ValueError(MCAP_ENU_ONLY.format(convention=convention))
    if fmt == ".npz":
        write_npz(path, out, mag_offset)
    elif fmt == ".csv":
        write_csv(path, out, rec, kind, settings, convention, mag_offset)
    else:
        write_mcap(path, out, rec, kind, settings=settings, mag_offset=mag_offset)

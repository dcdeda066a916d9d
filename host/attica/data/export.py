"""Filter outputs written where other tools look: ``.npz``, ``.csv`` and ``.mcap`` (``attica run -o``).

One file holds one filter's outputs over one recording, one row (or message) per sample:

- ``.npz``: the fields of :data:`attica.outputs.OUTPUT_DTYPE` as arrays (``q``, ``euler``, ...).
- ``.csv``: ``#`` comment lines that state every unit, frame and flag bit, one header row, then one
  row per sample (:func:`write_csv`; pandas reads it with ``comment="#"``).
- ``.mcap``: ROS 2 messages in CDR for Foxglove, ``ros2 bag``, rosbags and other MCAP tools
  (:func:`write_mcap`; the optional packages of ``pip install 'attica[recordings]'``).

Time: a recording with a time of its own (:attr:`attica.data.Recording.time`, e.g. the time column of
a log) is written on that clock; one without gets the time from its first sample, ``index / rate``.

Covariance: ``att_output_t.cov`` holds a diagonal whose meaning depends on the kind
(``firmware/include/attica/att_filter.h``); :data:`COVARIANCE` names its columns and says how it becomes
the 3x3 orientation covariance of a ROS ``sensor_msgs/msg/Imu``.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.kinds import KINDS, info
from attica.settings import OUTPUT_INVALID, FilterKind, Flag

__all__ = [
    "COVARIANCE",
    "IMU_TOPIC",
    "MAG_TOPIC",
    "TF_TOPIC",
    "OUTPUT_INVALID",
    "OUTPUT_SUFFIXES",
    "Covariance",
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


@dataclass(frozen=True)
class Covariance:
    """What ``att_output_t.cov`` holds for one kind.

    Attributes
    ----------
    columns : tuple of str
        CSV names of ``cov[0]``, ``cov[1]``, ... (the entries the kind fills; the rest are 0).
    meaning : str
        The header comment of those columns (units and frame).
    orientation : str
        How :func:`orientation_covariance` turns them into the Imu message's 3x3 (rad^2).
    diagonal : callable
        (N, 4) ``cov`` (float64) to the (N, 3) diagonal of the orientation covariance, rad^2.

    """

    columns: tuple[str, ...]
    meaning: str
    orientation: str
    matrix: Callable[[NDArray[np.void]], F64]


UNKNOWN_YAW = float(np.float32(np.pi**2 / 3.0))
"""rad^2: the variance of a heading that is not known (uniform over a turn), as ars and mars report it."""


def _diagonal(cov: F64) -> F64:
    """(N, 3) variances as the (N, 9) row-major matrices with them on the diagonal."""
    m = np.zeros((len(cov), 9))
    m[:, [0, 4, 8]] = cov
    return m


def _kf_matrix(out: NDArray[np.void]) -> F64:
    # P = p I (4x4) projects onto the tangent space of the unit sphere at q as p I3; a small rotation
    # dtheta moves q by q (x) (0, dtheta / 2), so dtheta = 2 dq: 4 p rad^2 about the tilt axes. The yaw of
    # this 6-axis filter is not observed: unknown.
    p = np.asarray(out["cov"], np.float64).mean(axis=1)
    return _diagonal(np.stack([4.0 * p, 4.0 * p, np.full_like(p, UNKNOWN_YAW)], axis=1))


def _ekf_matrix(out: NDArray[np.void]) -> F64:
    # The state is the ZYX Euler angles: a small change turns the sensor by
    # dr = z dpsi + Rz(psi) y dtheta + Rz(psi) Ry(theta) x dphi about the earth's axes, so the covariance
    # about them is sum_i var_i v_i v_i^T with v_phi = (c_psi c_theta, s_psi c_theta, -s_theta),
    # v_theta = (-s_psi, c_psi, 0), v_psi = (0, 0, 1) (the EKF reports no correlations: taken as 0). The
    # yaw of this 6-axis filter is not observed: unknown, whatever its variance has grown to.
    cov = np.asarray(out["cov"], np.float64)
    e = np.asarray(out["euler"], np.float64)
    cth, sth, cps, sps = np.cos(e[:, 1]), np.sin(e[:, 1]), np.cos(e[:, 2]), np.sin(e[:, 2])
    v_phi = np.stack([cps * cth, sps * cth, -sth], axis=1)
    v_theta = np.stack([-sps, cps, np.zeros_like(cps)], axis=1)
    m = cov[:, 0, None, None] * (v_phi[:, :, None] * v_phi[:, None, :])
    m += cov[:, 1, None, None] * (v_theta[:, :, None] * v_theta[:, None, :])
    m[:, 2, 2] += UNKNOWN_YAW
    flat: F64 = m.reshape(len(cov), 9)
    return flat


def _first3(out: NDArray[np.void]) -> F64:
    return _diagonal(np.asarray(out["cov"], np.float64)[:, :3])


_COMPLEMENTARY = Covariance(
    ("var_att_e", "var_att_n", "var_att_u"),
    "variance of the attitude error about the earth's east, north, up axes from the covariance model of "
    "docs/filters.md (tilt: both horizontal axes alike; up: the heading), rad^2",
    "the model's tilt and heading variances about the earth's x (east), y (north), z (up) axes on the "
    "diagonal; the heading's pi^2/3 where it is unknown",
    _first3,
)
"""ars and mars: the covariance model of the complementary filters (att_ars.h, att_mars.h)."""

COVARIANCE: dict[FilterKind, Covariance] = {
    FilterKind.ARS: _COMPLEMENTARY,
    FilterKind.MARS: _COMPLEMENTARY,
    FilterKind.KF: Covariance(
        ("var_q_w", "var_q_x", "var_q_y", "var_q_z"),
        "variance of each quaternion component, (unit quaternion)^2 (the KF carries P = p I: all equal)",
        "4 p about the earth's x and y: the isotropic quaternion variance p as a rotation, dtheta = 2 dq; "
        "the yaw, which this 6-axis filter does not observe, pi^2/3 (unknown)",
        _kf_matrix,
    ),
    FilterKind.EKF: Covariance(
        ("var_roll", "var_pitch", "var_yaw", "var_bias"),
        "variance of the ZYX Euler angles roll, pitch, yaw, rad^2 (yaw is not observed: it grows); "
        "var_bias: mean variance of the gyro bias, (rad/s)^2",
        "the roll and pitch variances turned onto the earth's axes through the Euler angles (dr = z dpsi + "
        "Rz(psi) y dtheta + Rz(psi) Ry(theta) x dphi; no correlations reported: taken as 0), off-diagonal "
        "entries included; the yaw, which this 6-axis filter does not observe, pi^2/3 (unknown)",
        _ekf_matrix,
    ),
    FilterKind.MEKF: Covariance(
        ("var_att_e", "var_att_n", "var_att_u", "var_bias"),
        "variance of the attitude error (a rotation vector about the earth's east, north, up axes), rad^2; "
        "var_bias: mean variance of the gyro bias, (rad/s)^2",
        "the attitude error variances about the earth's x (east), y (north), z (up) axes on the diagonal",
        _first3,
    ),
}
"""The kinds with a covariance (:attr:`attica.kinds.KindInfo.covariance`) and what their ``cov`` holds.
Only the diagonal is reported (``att_output_t``), so the off-diagonal entries written are 0 (but the
EKF's, whose Euler angles' variances turn onto the earth's axes)."""

if set(COVARIANCE) != {k.kind for k in KINDS if k.covariance}:  # pragma: no cover - a registry edit
    raise RuntimeError("attica.data.export.COVARIANCE must describe every kind with a covariance")


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


def csv_columns(kind: FilterKind | str) -> list[str]:
    """The columns of :func:`write_csv` for ``kind``, in order."""
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


def _csv_header(kind: FilterKind, rec: Any, absolute: bool, settings: Any, convention: str) -> list[str]:
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
    return [f"# {line}" for line in lines]


def write_csv(
    path: PathLike,
    out: NDArray[np.void],
    rec: Any,
    kind: FilterKind | str,
    settings: Any = None,
    convention: str = "enu",
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

    """
    k = info(kind)
    if convention not in CONVENTION_AXES:
        raise ValueError(f"unknown output convention {convention!r} (enu, ned, nwu)")
    times, absolute = sample_times(rec)
    if len(times) != len(out):
        raise ValueError(f"{len(out)} outputs for a recording of {len(times)} samples")
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
    table = np.hstack([np.asarray(c, np.float64) for c in cols])
    fmt = ["%.9f"] + ["%.9g"] * (10 + ncov) + ["%d", "%d"]
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write("\n".join(_csv_header(k.kind, rec, absolute, settings, convention)) + "\n")
        f.write(",".join(csv_columns(k.kind)) + "\n")
        np.savetxt(f, table, fmt=fmt, delimiter=",")


def write_npz(path: PathLike, out: NDArray[np.void]) -> None:
    """Write the output fields as arrays of a compressed ``.npz`` (``q``, ``euler``, ``flags`` ...)."""
    arrays: dict[str, Any] = {name: out[name] for name in out.dtype.names or ()}
    with open(path, "wb") as f:  # a file object: numpy appends no second ".npz" (e.g. to "out.NPZ")
        np.savez_compressed(f, **arrays)


def orientation_covariance(kind: FilterKind | str, out: NDArray[np.void], settings: Any = None) -> F64:
    """The (N, 9) row-major orientation covariance of ``sensor_msgs/msg/Imu`` for each output, rad^2.

    ``settings``: the kind's settings of the run (None: its defaults); a mekf with ``use_mag`` off is a
    6-axis filter, whose yaw is written as unknown (pi^2/3) like the kf's and the ekf's.

    As the message definition asks: the kind's variances about the earth's axes (:data:`COVARIANCE`:
    on the diagonal, 0 off it where only the diagonal is reported); all zeros, "covariance unknown",
    for a kind without one (gyro, tilt); element 0 = -1, "no orientation estimate", for the samples
    whose flags say q is not one (:data:`OUTPUT_INVALID`: before the first valid sample).
    """
    k = info(kind)
    n = len(out)
    c = np.zeros((n, 9), np.float64)
    if k.kind in COVARIANCE:
        c[:] = COVARIANCE[k.kind].matrix(out)
        if k.kind == FilterKind.MEKF and settings is not None and not getattr(settings, "use_mag", True):
            c[:, 8] = UNKNOWN_YAW  # the 6-axis mekf: its yaw is not observed
    invalid = (np.asarray(out["flags"]) & OUTPUT_INVALID) != 0
    c[invalid] = 0.0
    c[invalid, 0] = -1.0
    return c


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


def write_mcap(
    path: PathLike,
    out: NDArray[np.void],
    rec: Any,
    kind: FilterKind | str,
    *,
    frame_id: str = "imu",
    world_frame: str = "enu",
    settings: Any = None,
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

    The MCAP metadata record ``attica`` names the kind, the clock of the stamps and the covariance's
    meaning. The stamps need 0 <= time < 2^31 s (``builtin_interfaces/msg/Time`` and MCAP log times);
    a recording's own clock outside that is refused (a ValueError). ``settings``: the kind's settings of
    the run (None: its defaults), for the covariance of a mekf with ``use_mag`` off
    (:func:`orientation_covariance`).

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
    problem = stamp_problem(times)
    if problem:
        raise ValueError(problem)
    sec, nsec = ros_stamps(times)
    log_ns = sec * 1_000_000_000 + nsec
    q = np.asarray(out["q"], np.float64)
    ocov = orientation_covariance(k.kind, out, settings)
    gyr = np.asarray(rec.gyr, np.float64)
    acc = np.asarray(rec.acc, np.float64)
    mag = np.asarray(rec.mag, np.float64)
    has_mag = np.isfinite(mag).all(axis=1) & (mag != 0.0).any(axis=1)
    meta = {
        "kind": k.label,
        "clock": "the recording's own clock" if absolute else "from the first sample (index / rate)",
        "orientation": "q sensor-to-earth, ENU world frame",
        "orientation_covariance": COVARIANCE[k.kind].orientation
        if k.kind in COVARIANCE
        else f"all zeros (unknown): {k.label} does not estimate a covariance",
        "no_estimate": "orientation_covariance[0] = -1 where the filter had no attitude estimate yet",
        "frames": f"{world_frame} (ENU) -> {frame_id} (sensor)",
    }
    types = ts.types
    imu_t, tf_t, field_t = types[IMU_TYPE], types[TF_TYPE], types[MAG_TYPE]
    header_t, time_t, quat_t, vec_t = (
        types["std_msgs/msg/Header"],
        types["builtin_interfaces/msg/Time"],
        types["geometry_msgs/msg/Quaternion"],
        types["geometry_msgs/msg/Vector3"],
    )
    stamped_t, transform_t = types["geometry_msgs/msg/TransformStamped"], types["geometry_msgs/msg/Transform"]
    zero = vec_t(x=0.0, y=0.0, z=0.0)
    unknown = np.zeros(9, np.float64)
    with open(path, "wb") as stream:
        w = writer_class(stream)
        w.start(profile="ros2", library=f"attica {_version()}")
        topics = [(IMU_TOPIC, IMU_TYPE), (TF_TOPIC, TF_TYPE)] + (
            [(MAG_TOPIC, MAG_TYPE)] if has_mag.any() else []
        )
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
) -> None:
    """Write one filter's outputs in the format of ``path``'s suffix (:data:`OUTPUT_SUFFIXES`).

    ``convention`` is the earth frame of the outputs' ``q`` (the calibration's output convention): the
    CSV's header says it; ``.mcap`` takes ENU only (REP-145's world frame of ``sensor_msgs/Imu``).

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
        write_npz(path, out)
    elif fmt == ".csv":
        write_csv(path, out, rec, kind, settings, convention)
    else:
        write_mcap(path, out, rec, kind, settings=settings)

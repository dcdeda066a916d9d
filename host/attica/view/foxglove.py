"""``attica view --foxglove``: the attitude on Foxglove's live WebSocket protocol (``foxglove-sdk``).

The bridge runs the SDK's WebSocket server (``foxglove.start_server``, its own port, in its own
:class:`foxglove.Context`) and publishes, at the view's display rate, whenever a new output set came:

- ``/tf`` (schema ``foxglove.FrameTransform``, JSON): the attitude as the transform from the earth frame
  of the node's convention (``parent_frame_id`` ``enu``, ``ned`` or ``nwu``) to the body (``imu``):
  rotation = the node's quaternion (sensor-to-earth), translation zero. Foxglove's 3D panel draws it.
- ``/imu`` (schema ``attica.Imu``, JSON, the fields of ROS ``sensor_msgs/msg/Imu``): orientation (the same
  quaternion), angular velocity (rad/s) and linear acceleration (m/s^2) of the latest IMU sample seen
  on the bus. The orientation covariance is the node's (CAN FD sets of a kind with one, about the
  convention's earth axes: :func:`attica.view.state.orientation_cov`); zeros ("unknown", as ROS says)
  for classic sets, gyro and tilt, and the two other covariances.
- ``/attica/status`` (schema ``attica.Status``, JSON): roll, pitch, yaw (rad), gyro bias (rad/s), the
  flags word and names, the filter kind, steps, the bus health counters, and the hard-iron offset of
  the last ATT_MAG_OFFSET (uT; null without one) with whether it was observable.

Time stamps are the frames' (bus time: the receive time on a live bus, the recorded time of a log).
Foxglove (the app) connects to ``ws://host:port``; nothing is sent anywhere else.
"""

from __future__ import annotations

import logging
from typing import Any

__all__ = ["FoxgloveBridge", "FoxgloveMissingError"]

log = logging.getLogger("attica.view")

EXTRA = "pip install 'attica[foxglove]' (the foxglove-sdk package)"


class FoxgloveMissingError(ImportError):
    """The foxglove-sdk package is not installed."""


def _object(title: str, props: dict[str, Any]) -> dict[str, Any]:
    return {"title": title, "type": "object", "properties": props}


_NUM = {"type": "number"}
_VEC3 = _object("vector3", {"x": _NUM, "y": _NUM, "z": _NUM})
_QUAT = _object("quaternion", {"x": _NUM, "y": _NUM, "z": _NUM, "w": _NUM})
_TIME = _object("time", {"sec": {"type": "integer"}, "nsec": {"type": "integer"}})
_COV = {"type": "array", "items": _NUM, "minItems": 9, "maxItems": 9}

FRAME_TRANSFORM_SCHEMA = _object(
    "foxglove.FrameTransform",
    {
        "timestamp": _TIME,
        "parent_frame_id": {"type": "string"},
        "child_frame_id": {"type": "string"},
        "translation": _VEC3,
        "rotation": _QUAT,
    },
)
"""JSON schema of Foxglove's FrameTransform (the app reads JSON-encoded foxglove schemas by this title)."""

IMU_SCHEMA = _object(
    "attica.Imu",
    {
        "header": _object("header", {"stamp": _TIME, "frame_id": {"type": "string"}}),
        "orientation": _QUAT,
        "orientation_covariance": _COV,
        "angular_velocity": _VEC3,
        "angular_velocity_covariance": _COV,
        "linear_acceleration": _VEC3,
        "linear_acceleration_covariance": _COV,
    },
)
"""The fields of ROS sensor_msgs/msg/Imu, as JSON."""

STATUS_SCHEMA = _object(
    "attica.Status",
    {
        "timestamp": _TIME,
        "roll": _NUM,
        "pitch": _NUM,
        "yaw": _NUM,
        "gyro_bias": _VEC3,
        "flags": {"type": "integer"},
        "flag_names": {"type": "array", "items": {"type": "string"}},
        "kind": {"type": "string"},
        "steps": {"type": "integer"},
        "health": {"type": "object"},
        "mag_offset": _VEC3,
        "mag_offset_estimated": {"type": "boolean"},
    },
)


def _stamp(ts: float) -> dict[str, int]:
    ns = int(round(ts * 1e9))
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _xyz(v: list[float | None] | None) -> dict[str, float | None]:
    """x, y, z of a vector (None where unknown: JSON has no NaN)."""
    v = v or [None, None, None]
    return {k: (float(x) if x is not None else None) for k, x in zip("xyz", v)}


class FoxgloveBridge:
    """Publish the view's snapshots to Foxglove (see the module's documentation).

    Parameters
    ----------
    host, port
        Where the SDK's WebSocket server listens (port 0: a free one, see :attr:`port`).

    Raises
    ------
    FoxgloveMissingError
        When foxglove-sdk is not installed (the message says how to install it).

    """

    def __init__(self, host: str = "127.0.0.1", port: int = 8765) -> None:
        try:
            import foxglove
        except ImportError:
            raise FoxgloveMissingError(
                f"the Foxglove bridge needs the foxglove-sdk package: {EXTRA}"
            ) from None
        self._fg = foxglove
        self.context = foxglove.Context()
        self.server = foxglove.start_server(name="attica", host=host, port=port, context=self.context)
        self.host = host
        self.port = int(self.server.port)
        self.tf = foxglove.Channel("/tf", schema=FRAME_TRANSFORM_SCHEMA, context=self.context)
        self.imu = foxglove.Channel("/imu", schema=IMU_SCHEMA, context=self.context)
        self.status = foxglove.Channel("/attica/status", schema=STATUS_SCHEMA, context=self.context)
        self.published = 0
        self._last_ts: float | None = None
        log.info("Foxglove bridge on ws://%s:%d", host, self.port)

    @property
    def url(self) -> str:
        """``ws://host:port`` for Foxglove's "open connection"."""
        return f"ws://{self.host}:{self.port}"

    def publish(self, snap: dict[str, Any]) -> bool:
        """Publish a snapshot of :meth:`~attica.view.state.ViewState.snapshot` (True: it had a new set)."""
        att = snap.get("att")
        if not att or att.get("ts") == self._last_ts:
            return False
        ts = float(att["ts"])
        self._last_ts = ts
        q = att["q"]
        if any(x is None for x in q):
            return False
        w, x, y, z = (float(v) for v in q)
        rot = {"x": x, "y": y, "z": z, "w": w}
        stamp = _stamp(ts)
        log_time = int(round(ts * 1e9))
        frame = str(snap.get("convention", "ENU")).lower()
        self.tf.log(
            {
                "timestamp": stamp,
                "parent_frame_id": frame,
                "child_frame_id": "imu",
                "translation": {"x": 0.0, "y": 0.0, "z": 0.0},
                "rotation": rot,
            },
            log_time=log_time,
        )
        imu = snap.get("imu") or {}
        zeros = [0.0] * 9
        self.imu.log(
            {
                "header": {"stamp": stamp, "frame_id": "imu"},
                "orientation": rot,
                "orientation_covariance": att.get("cov") or zeros,
                "angular_velocity": _xyz(imu.get("gyr")),
                "angular_velocity_covariance": zeros,
                "linear_acceleration": _xyz(imu.get("acc")),
                "linear_acceleration_covariance": zeros,
            },
            log_time=log_time,
        )
        e = att["euler"]
        health = snap.get("health") or {}
        mo = snap.get("mag_offset")
        keep = ("frames_per_s", "bus_load", "crc_errors", "counter_gaps", "missing_sets", "latency_ms")
        self.status.log(
            {
                "timestamp": stamp,
                "roll": e[0],
                "pitch": e[1],
                "yaw": e[2],
                "gyro_bias": _xyz(att["bias"]),
                "flags": att["flags"],
                "flag_names": att["flag_names"],
                "kind": att["kind"],
                "steps": att["steps"],
                "health": {k: health.get(k) for k in keep},
                "mag_offset": _xyz(mo["offset"] if mo else None),
                "mag_offset_estimated": bool(mo and mo["estimated"]),
            },
            log_time=log_time,
        )
        self.published += 1
        return True

    def stop(self) -> None:
        """Stop the SDK's server."""
        self.server.stop()

"""attica CAN interface: the DBC-based codec (:mod:`attica.can.codec`) and its code generator.

The layout of every frame is defined by firmware/can/attica.dbc; :mod:`attica.can.gen` regenerates
the C pack/unpack code from it; :mod:`attica.can.codec` encodes and decodes frames bit-identically to
firmware/src/can/att_can.c and wraps the C node (firmware/src/node/att_node.c). See docs/can.md.
"""

from __future__ import annotations

from attica.can.codec import (
    DBC_PATH,
    FRAME_DTYPE,
    Ack,
    Check,
    Cmd,
    Gain,
    Node,
    NodeError,
    bus_load,
    check,
    check_status_set,
    crc8,
    decode,
    decode_outputs,
    dequantise,
    e2e_crc,
    encode_cmd,
    encode_imu,
    encode_outputs,
    quantise,
)

__all__ = [
    "DBC_PATH",
    "FRAME_DTYPE",
    "Ack",
    "Check",
    "Cmd",
    "Gain",
    "Node",
    "NodeError",
    "bus_load",
    "check",
    "check_status_set",
    "crc8",
    "decode",
    "decode_outputs",
    "dequantise",
    "e2e_crc",
    "encode_cmd",
    "encode_imu",
    "encode_outputs",
    "quantise",
]

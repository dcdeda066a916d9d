"""The node's ATT_DIAG_BUS hook (att_node_set_bus_diag) and its API's refusals of NULL and bad values.

A port reports its CAN controller's counters through a hook; the node then sends ATT_DIAG_BUS beside
every ATT_DIAG. The ports' own tests run it in their programs (register level, tests/test_ports*.py);
here the node's side runs in the binding: the frame, its values and CRC, the hook's context, the hook
removed, and a hook refused when the two diagnostic frames would take the bus beyond 100 %.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from attica.can import codec as c
from attica.native import ffi, lib

RATE = 100.0
VALUES = {"state": 2, "lec": 3, "bus_off": 4, "recoveries": 5, "error_passive": 6, "error_warning": 7,
          "rx_overruns": 8}  # fmt: skip


def _run(node: c.Node, n: int) -> list[Any]:
    """n samples at rest pushed (each set drained): the frames sent, as att_can_frame_t."""
    out = []
    for _ in range(n):
        assert node.push_sample(np.zeros(3), np.array([0.0, 0.0, 9.81]), np.array([20.0, 0.0, -40.0]))
        fr = node.pop()
        buf = ffi.from_buffer("att_can_frame_t[]", fr)
        for i in range(fr.shape[0]):
            f = ffi.new("att_can_frame_t *")
            f[0] = buf[i]
            out.append(f)
    return out


def test_the_hook_sends_diag_bus_with_each_diag() -> None:
    calls: list[Any] = []
    owner = object()
    handle = ffi.new_handle(owner)

    @ffi.callback("void(void *, att_can_bus_diag_t *)")
    def hook(ctx: Any, d: Any) -> None:
        calls.append(ffi.from_handle(ctx))
        for k, v in VALUES.items():
            setattr(d, k, v)

    node = c.Node("ars", sample_rate=RATE)  # ATT_DIAG every 16th set
    assert lib.att_node_set_bus_diag(node._n, hook, handle) == lib.ATT_OK
    frames = _run(node, 64)
    diag = [f for f in frames if f.id == lib.ATT_CAN_ID_DIAG]
    bus = [f for f in frames if f.id == lib.ATT_CAN_ID_DIAG_BUS]
    assert len(diag) == 4 and len(bus) == 4 and len(calls) == 4 and all(o is owner for o in calls)
    d = ffi.new("att_can_bus_diag_t *")
    for f in bus:
        assert lib.att_can_check(f) == lib.ATT_CAN_OK
        assert lib.att_can_decode_diag_bus(f, d)
        assert {k: getattr(d, k) for k in VALUES} == VALUES
    # removed: ATT_DIAG goes on alone
    assert lib.att_node_set_bus_diag(node._n, ffi.NULL, handle) == lib.ATT_OK
    frames = _run(node, 64)
    assert len([f for f in frames if f.id == lib.ATT_CAN_ID_DIAG]) == 4
    assert not [f for f in frames if f.id == lib.ATT_CAN_ID_DIAG_BUS] and len(calls) == 4
    assert lib.att_node_set_bus_diag(ffi.NULL, hook, handle) == lib.ATT_ERR_NULL


def test_the_hook_is_refused_when_the_bus_has_no_room() -> None:
    """A node whose outputs fit the bus with ATT_DIAG every set, but not with ATT_DIAG_BUS beside it:
    the hook is refused (ATT_ERR_SETTINGS) and no ATT_DIAG_BUS is sent."""

    called: list[Any] = []

    @ffi.callback("void(void *, att_can_bus_diag_t *)")
    def hook(ctx: Any, d: Any) -> None:
        called.append(ctx)  # (an exception raised here would be printed and swallowed by cffi)

    found = None
    for rate in range(300, 700, 5):
        try:
            node = c.Node("ars", sample_rate=float(rate), diag_divider=1)
        except c.NodeError:
            break
        if lib.att_node_set_bus_diag(node._n, hook, ffi.NULL) == lib.ATT_ERR_SETTINGS:
            found = node
            break
    assert found is not None
    frames = _run(found, 4)
    assert len([f for f in frames if f.id == lib.ATT_CAN_ID_DIAG]) == 4
    assert not [f for f in frames if f.id == lib.ATT_CAN_ID_DIAG_BUS] and not called


def test_null_and_bad_values_are_refused() -> None:
    node = c.Node("ars", sample_rate=RATE)
    s = ffi.new("att_node_settings_t *")
    assert lib.att_node_settings_default(lib.ATT_FILTER_ARS, RATE, ffi.NULL) == lib.ATT_ERR_NULL
    for rate in (0.0, -1.0, float("inf")):
        assert lib.att_node_settings_default(lib.ATT_FILTER_ARS, rate, s) == lib.ATT_ERR_SETTINGS, rate
    d = ffi.new("att_can_diag_t *")
    ffi.memmove(d, b"\xa5" * ffi.sizeof("att_can_diag_t"), ffi.sizeof("att_can_diag_t"))
    lib.att_node_diag(ffi.NULL, d)
    assert bytes(ffi.buffer(d)) == b"\xa5" * ffi.sizeof("att_can_diag_t")
    lib.att_node_diag(node._n, ffi.NULL)
    assert lib.att_node_error_count(ffi.NULL) == 0
    assert lib.att_node_rx_ids(node._n, ffi.NULL) == 0 and lib.att_node_rx_ids(ffi.NULL, ffi.NULL) == 0
    assert not lib.att_node_push_sample(node._n, ffi.NULL)
    # the CAN FD frame time: 17 CRC bits up to 16 data bytes, 21 above; no time without both bitrates
    for n in (8, 16, 20, 64):
        want = c.fd_frame_time(n, 500_000, 2_000_000)
        assert lib.att_node_fd_frame_time(n, 500_000, 2_000_000) == pytest.approx(want, rel=1e-6), n
    assert lib.att_node_fd_frame_time(8, 0, 2_000_000) == -1.0

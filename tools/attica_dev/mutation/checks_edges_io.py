"""Stage B: edge cases of the codec, the sample checks, att_filter_step_n and the node.

Each check reaches a line the other checks leave unobserved: a NULL argument of an encoder, an accel
sample exactly at the saturation limit, step counts whose flags differ between their steps, a refused
setting of the stages seen through att_node_settings_check, and the node's running settings after a
SELECT (seen through the next SET_GAIN).
"""

from __future__ import annotations

from typing import Any

from attica_dev.mutation.checks_common import _set, _sha, _values, _why


def _can_null_check() -> str:
    """att_can_encode_status with each pointer NULL in turn: no-ops that leave the frame as it was."""
    from attica.native import ffi, lib

    parts: list[Any] = []
    st = ffi.new("att_can_status_t *", [9, 2])
    st.flags, st.steps, st.error_count, st.ack = 0x1234, 777, 3, 0x85
    fr = ffi.new("att_can_frame_t *")
    ffi.memmove(fr, b"\x5a" * ffi.sizeof(fr[0]), ffi.sizeof(fr[0]))
    lib.att_can_encode_status(ffi.NULL, fr)
    parts.append(bytes(ffi.buffer(fr)))
    lib.att_can_encode_status(st, ffi.NULL)
    lib.att_can_encode_status(ffi.NULL, ffi.NULL)
    lib.att_can_encode_status(st, fr)
    parts.append((fr.id, fr.len, fr.fd, bytes(fr.data), lib.att_can_check(fr)))
    return _sha(parts)


def _accel_limit_check() -> str:
    """Accel samples with |a| exactly at accel_range (32 m/s^2, |a|^2 = 1024 exact): usable, not RANGE.

    Every kind with accel_range in its settings, the limit approached from both sides.
    """
    import numpy as np

    from attica.native import ffi, lib
    from attica.settings import implemented_kinds

    parts: list[Any] = []
    f = ffi.new("att_filter_t *")
    s = ffi.new("att_filter_settings_t *")
    out = ffi.new("att_output_t *")
    smp = ffi.new("att_sample_t *")
    below = float(np.nextafter(np.float32(32.0), np.float32(0.0)))
    above = float(np.nextafter(np.float32(32.0), np.float32(64.0)))
    accs = [(0.0, 0.0, 32.0), (32.0, 0.0, 0.0), (0.0, -32.0, 0.0), (0.0, 0.0, below), (0.0, 0.0, above)]
    accs += [(0.0, 0.0, 9.80665), (0.0, 0.0, -32.0)]
    for kind in implemented_kinds():
        lib.att_filter_settings_default(int(kind), 0.01, s)
        member = getattr(s, kind.label)
        if "accel_range" not in [name for name, _ in ffi.typeof(member).fields]:
            continue
        member.accel_range = 32.0
        parts.append((kind.label, lib.att_filter_init(f, int(kind), s)))
        for i, acc in enumerate(accs * 3):
            smp.gyr = (0.01 * (i % 3), -0.02, 0.005)
            smp.acc = acc
            smp.mag = (20.0, 0.0, -40.0)
            parts.append(lib.att_filter_step(f, smp, out))
            parts.append((out.flags, out.valid, _values(out.q), _values(out.euler)))
    return _sha(parts)


def _step_n_flags_check() -> str:
    """att_filter_step_n's record: the flags ORed over its steps (fresh filters, a clamped count)."""
    from attica.native import ffi, lib
    from attica.settings import implemented_kinds

    parts: list[Any] = []
    f = ffi.new("att_filter_t *")
    s = ffi.new("att_filter_settings_t *")
    out = ffi.new("att_output_t *")
    smp = ffi.new("att_sample_t *")
    smp.gyr, smp.acc, smp.mag = (0.02, -0.01, 0.03), (0.3, -0.2, 9.7), (22.0, 3.0, -41.0)
    for kind in implemented_kinds():
        lib.att_filter_settings_default(int(kind), 0.01, s)
        for n in (2, 3, 65536) if kind.label == "ars" else (2, 3):
            lib.att_filter_init(f, int(kind), s)
            ret = lib.att_filter_step_n(f, smp, n, out)  # 65536: clamped to 65535 steps, CLAMPED
            parts.append((kind.label, n, ret, out.flags, out.steps))
        lib.att_filter_init(f, int(kind), s)
        bad = ffi.new("att_sample_t *", smp[0])
        bad.gyr = (float("nan"), 0.0, 0.0)
        parts.append((lib.att_filter_step_n(f, bad, 1, out), out.flags))
        parts.append((lib.att_filter_step_n(f, smp, 4, out), out.flags))
    return _sha(parts)


def _node_calib_rules_check() -> str:
    """att_node_settings_check / att_node_init with one field of the stages out of its range, each in turn."""
    from attica.native import ffi, lib

    parts: list[Any] = []
    why = ffi.new("att_settings_error_t *")
    node = ffi.new("att_node_t *")
    breaks: tuple[tuple[str, Any], ...] = (
        ("gyro.misalignment.0", 1e9),
        ("gyro.sensitivity.y", -1.0),
        ("gyro.offset.z", 2e3),
        ("accel.misalignment.4", float("nan")),
        ("accel.sensitivity.z", 0.0),
        ("accel.offset.x", -2e4),
        ("mag.soft_iron.8", float("inf")),
        ("mag.hard_iron.y", 2e5),
        ("remap", 25),
        ("mounting.w", 1.1),
        ("convention", 3),
        ("gravity", 0.5),
        ("gravity", 200.0),
    )
    for path, value in breaks:
        s = ffi.new("att_node_settings_t *")
        lib.att_node_settings_default(1, 100.0, s)
        assert _set(s.calib, path, value)
        parts.append((path, lib.att_node_settings_check(s, why), _why(why), lib.att_node_init(node, s)))
    return _sha(parts)


def _node_select_gain_check() -> str:
    """The node's running settings after SELECT, seen through the SET_GAIN commands that follow.

    MARS: SET_GAIN tau_acc, SELECT mars (back to the init settings), SET_GAIN tau_mag, samples; ARS:
    SELECT mars, SET_GAIN tau_mag (a gain the init kind does not have), samples. Answers and sets kept.
    """
    from attica.native import ffi, lib

    parts: list[Any] = []
    node = ffi.new("att_node_t *")
    fr = ffi.new("att_can_frame_t *")
    cmd = ffi.new("att_can_cmd_t *")
    smp = ffi.new("att_sample_t *")
    fbuf = ffi.buffer(fr)
    counter = [0]

    def command(c: int, arg: int, value: float) -> None:
        cmd.counter, cmd.cmd, cmd.arg, cmd.value = counter[0] & 15, c, arg, value
        counter[0] += 1
        lib.att_can_encode_cmd(cmd, fr)
        parts.append(lib.att_node_rx(node, fr))

    def samples(k: int) -> None:
        seen = bytearray()
        for i in range(k):
            smp.gyr = (0.3, -0.1 * (i % 5), 0.2)
            smp.acc = (1.0, -0.5, 9.5)
            smp.mag = (20.0, 5.0, -40.0)
            seen.append(lib.att_node_push_sample(node, smp))
            while lib.att_node_tx(node, fr):
                seen += fbuf[:70]
        parts.append(bytes(seen))

    select, set_gain = int(lib.ATT_CAN_CMD_SELECT), int(lib.ATT_CAN_CMD_SET_GAIN)
    tau_acc, tau_mag = int(lib.ATT_CAN_GAIN_TAU_ACC), int(lib.ATT_CAN_GAIN_TAU_MAG)
    for init_kind, script in (
        (2, ((set_gain, tau_acc, 0.05), (select, 2, 0.0), (set_gain, tau_mag, 0.5))),
        (1, ((select, 2, 0.0), (set_gain, tau_mag, 0.5), (set_gain, tau_acc, 0.07))),
        (1, ((set_gain, tau_acc, 0.05), (select, 1, 0.0), (set_gain, tau_acc, 0.05))),
    ):
        s = ffi.new("att_node_settings_t *")
        lib.att_node_settings_default(init_kind, 100.0, s)
        parts.append(lib.att_node_init(node, s))
        samples(5)
        for c, arg, value in script:
            command(c, arg, value)
            samples(3)
        samples(40)
        parts.append(_values(node.stats))
    return _sha(parts)


def _node_parts_check() -> str:
    """att_node_poll's step counts over IMU parts sent twice, out of order and lost; the NULL node's count."""
    from attica.native import ffi, lib

    parts: list[Any] = [lib.att_node_error_count(ffi.NULL)]
    node = ffi.new("att_node_t *")
    s = ffi.new("att_node_settings_t *")
    lib.att_node_settings_default(1, 100.0, s)
    parts.append(lib.att_node_init(node, s))
    smp = ffi.new("att_sample_t *")
    fr = ffi.new("att_can_frame_t[3]")
    out = ffi.new("att_can_frame_t *")
    # per sample: the order of its parts (0 gyro, 1 acc, 2 mag), a part repeated, a part left out
    orders = ((0, 1, 2), (0, 0, 1, 2), (1, 1, 0, 2, 2), (2, 0, 2, 1), (0, 1), (0, 1, 2), (2, 1, 1, 0))
    for i, order in enumerate(orders * 2):
        smp.gyr, smp.acc, smp.mag = (0.1 * i, -0.2, 0.05), (0.5, 0.1 * i, 9.7), (20.0, -3.0, -40.0 + i)
        lib.att_can_encode_imu(smp, i & 15, fr)
        for j in order:
            parts.append((lib.att_node_rx(node, fr + j), lib.att_node_poll(node)))
        while lib.att_node_tx(node, out):
            parts.append(bytes(out.data))
    parts.append((_values(node.stats), lib.att_node_error_count(node)))
    return _sha(parts)

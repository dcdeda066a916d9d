"""Stage B: the node over the rough streams (stages, hooks, pushed samples) and the CAN codec."""

from __future__ import annotations

from typing import Any

from attica_dev.mutation.checks_common import _sha, _values, _why
from attica_dev.mutation.stage_a import _rough_frames


def _node_sessions(kind: Any) -> str:
    """The node with what att_node_run cannot set, over the rough streams.

    Stages at init, accel outputs, a DIAG divider, the persistence hook (failing every other save) and
    a port's bus counters.
    """
    import numpy as np

    from attica.calibration.stages import StageSettings, fill_c
    from attica.native import ffi, lib

    parts: list[Any] = []
    saves: list[Any] = []

    def persist(ctx: Any, cal: Any) -> bool:
        saves.append(_values(cal))
        return len(saves) % 2 == 1

    def bus(ctx: Any, d: Any) -> None:
        d.state, d.lec = len(saves) % 4, 6
        d.bus_off, d.recoveries, d.error_passive, d.error_warning, d.rx_overruns = 1, 2, 3, 4, 300

    persist_cb = ffi.callback("bool(void *, const att_calib_settings_t *)", persist)
    bus_cb = ffi.callback("void(void *, att_can_bus_diag_t *)", bus)
    stages = StageSettings(
        gyro_offset=(0.01, -0.02, 0.005),
        accel_sensitivity=(0.998, 1.003, 1.0),
        hard_iron=(3.0, -2.0, 5.0),
        remap=7,
        convention=1,
    )
    node = ffi.new("att_node_t *")
    f = ffi.new("att_can_frame_t *")
    for fd in (False, True):
        frames = np.ascontiguousarray(_rough_frames(kind, fd))
        for variant in range(2):
            s = ffi.new("att_node_settings_t *")
            parts.append(lib.att_node_settings_default(int(kind), 200.0, s))
            s.fd = fd
            s.data_bitrate = 5_000_000 if fd else 0
            s.accel_out = True
            s.diag_divider = 3 if variant else 1
            if variant:
                fill_c(s.calib, stages)
            parts.append(lib.att_node_init(node, s))
            lib.att_node_set_persist(node, persist_cb, ffi.NULL)
            parts.append(lib.att_node_set_bus_diag(node, bus_cb if variant else ffi.NULL, ffi.NULL))
            buf = ffi.from_buffer("att_can_frame_t[]", frames)
            seen = bytearray()
            fbuf = ffi.buffer(f)
            for i in range(len(frames)):
                seen += bytes((lib.att_node_rx(node, buf + i), lib.att_node_poll(node) & 0xFF))
                seen += lib.att_node_tx_pending(node).to_bytes(4, "little")
                while lib.att_node_tx(node, f):
                    seen += fbuf[:70]  # id, len, fd, data (not the tail padding)
            parts.append(bytes(seen))
            parts.append((_values(node.stats), lib.att_node_error_count(node), saves[:]))
            ids = ffi.new("uint32_t[]", 64)
            parts.append((lib.att_node_rx_ids(node, ids), list(ids)))
        # bursts: 1 to 100 frames queued before the service calls (the rx ring's indexing and overflow)
        parts.append(lib.att_node_init(node, s))
        seen = bytearray()
        i, k = 0, 1
        while i < len(frames):
            for j in range(i, min(i + k, len(frames))):
                seen.append(lib.att_node_rx(node, buf + j))
            i, k = i + k, k % 100 + 13
            for _ in range(400):
                n = lib.att_node_poll(node)
                seen.append(n & 0xFF)
                while lib.att_node_tx(node, f):
                    seen += fbuf[:70]
                if n == 0:
                    break
        parts.append((bytes(seen), _values(node.stats)))
    # an IMU on the node's board: samples pushed (between frames), the tx ring drained only now and then
    from attica_dev import digests

    g, a, m = digests.adversarial_stream()
    s = ffi.new("att_node_settings_t *")
    lib.att_node_settings_default(int(kind), 200.0, s)
    s.accel_out = True
    parts.append(lib.att_node_init(node, s))
    smp = ffi.new("att_sample_t *")
    frames = np.ascontiguousarray(_rough_frames(kind, False))
    buf = ffi.from_buffer("att_can_frame_t[]", frames)
    seen = bytearray()
    fbuf = ffi.buffer(f)
    for i in range(300):
        smp.gyr, smp.acc, smp.mag = (tuple(float(x) for x in v[i]) for v in (g, a, m))
        if i % 10 == 3:
            lib.att_node_rx(node, buf + i)
        seen += bytes((lib.att_node_push_sample(node, smp),))
        while i % 7 != 0 and lib.att_node_tx(node, f):
            seen += fbuf[:70]
    parts.append((bytes(seen), _values(node.stats)))
    d = ffi.new("att_can_diag_t *")
    lib.att_node_diag(node, d)
    parts.append(_values(d))
    null = ffi.NULL
    parts.append((lib.att_node_rx(node, null), lib.att_node_rx(null, f), lib.att_node_push_sample(null, smp)))
    parts.append(
        (lib.att_node_push_sample(node, null), lib.att_node_tx(null, f), lib.att_node_tx(node, null))
    )
    parts.append((lib.att_node_poll(null), lib.att_node_tx_pending(null), lib.att_node_rx_ids(null, ids)))
    parts.append(
        (
            lib.att_node_init(null, s),
            lib.att_node_init(node, null),
            lib.att_node_set_bus_diag(null, null, null),
        )
    )
    why = ffi.new("att_settings_error_t *")
    parts.append(
        (lib.att_node_settings_default(int(kind), 100.0, null), lib.att_node_settings_check(null, why))
    )
    parts.append(_why(why))
    return _sha(parts)


def _can_check() -> str:
    """The CAN codec: quantisation, CRCs, message table, check and seal, encoders and decoders."""
    import numpy as np

    from attica.native import ffi, lib
    from attica_dev import golden

    parts: list[Any] = []
    xs = np.concatenate([golden.special_floats(), np.linspace(-40, 40, 161, dtype=np.float32)])
    for frac in (-31, -30, -1, 0, 5, 8, 10, 13, 14, 15, 30, 31):
        q = [lib.att_can_quantise(float(x), frac) for x in xs]
        parts.append(
            (frac, q, [lib.att_can_dequantise(v, frac) for v in (-32768, -32767, -1, 0, 1, 12345, 32767)])
        )
    rng = np.random.default_rng(7)
    for n in (0, 1, 7, 8, 63, 64):
        data = bytes(rng.integers(0, 256, n, dtype=np.uint8))
        buf = ffi.new("uint8_t[]", data or b"\0")
        parts.append(
            (lib.att_can_crc8(buf, n, 0xFF), lib.att_can_crc8(buf, n, 0), lib.att_can_e2e_crc(0xA05, buf, n))
        )
    for cid in range(0, 0x800):
        parts.append((lib.att_can_msg_len(cid), lib.att_can_msg_has_crc(cid), lib.att_can_data_id(cid)))
    fr = ffi.new("att_can_frame_t *")
    for cid in (
        0x100,
        0x101,
        0x102,
        0x110,
        0x200,
        0x204,
        0x205,
        0x206,
        0x209,
        0x20A,
        0x210,
        0x211,
        0x300,
        0x7FF,
    ):
        for length in (0, 2, 7, 8, 9, 64):
            for fd in (0, 1):
                fr.id, fr.len, fr.fd = cid, length, fd
                for j in range(64):
                    fr.data[j] = int(rng.integers(0, 256))
                parts.append((cid, length, fd, lib.att_can_check(fr), lib.att_can_counter(fr)))
                lib.att_can_seal(fr)
                parts.append((lib.att_can_check(fr), bytes(fr.data)))
    parts.append(_codec_roundtrips())
    cmd = ffi.new("att_can_cmd_t *")
    for c_, arg, value, counter in ((3, 1, 0.75, 5), (1, 7, float("nan"), 15), (200, 255, -1e30, 16)):
        cmd.cmd, cmd.arg, cmd.value, cmd.counter = c_, arg, value, counter & 0xFF
        lib.att_can_encode_cmd(cmd, fr)
        back = ffi.new("att_can_cmd_t *")
        parts.append(
            (bytes(fr.data), fr.id, fr.len, lib.att_can_decode_cmd(fr, back), bytes(ffi.buffer(back)))
        )
    return _sha(parts)


def _codec_roundtrips() -> list[Any]:
    """Every encoder on random and special values, its frames checked, corrupted and decoded again."""
    import numpy as np

    from attica.native import ffi, lib
    from attica_dev import golden

    rng = np.random.default_rng(2614)
    sp = golden.special_floats()

    def floats(n: int, scale: float) -> list[float]:
        x = rng.normal(0.0, scale, n).astype(np.float32)
        pick = rng.random(n) < 0.15
        x[pick] = rng.choice(sp, int(pick.sum()))
        return [float(v) for v in x]

    out: list[Any] = []
    fr = ffi.new("att_can_frame_t[6]")

    def frames(k: int) -> None:
        for j in range(k):
            out.append((_values(fr[j]), lib.att_can_check(ffi.addressof(fr, j)), lib.att_can_counter(fr + j)))
            bad = ffi.new("att_can_frame_t *", fr[j])
            bad.data[int(rng.integers(0, 8))] ^= 1 << int(rng.integers(0, 8))
            out.append(lib.att_can_check(bad))

    for i in range(40):
        counter = int(rng.integers(0, 256))
        smp = ffi.new("att_sample_t *")
        for name, scale in (("gyr", 5.0), ("acc", 30.0), ("mag", 200.0)):
            setattr(smp, name, floats(3, scale))
        if i % 5 == 0:
            smp.mag = (float("nan"),) * 3
        v = ffi.new("att_vec3_t *")
        lib.att_can_encode_imu(smp, counter, fr)
        frames(3)
        out.extend((lib.att_can_decode_imu_part(fr + j, v), _values(v)) for j in range(4))
        lib.att_can_encode_imu_fd(smp, counter, fr)
        frames(1)
        back = ffi.new("att_sample_t *")
        out.append((lib.att_can_decode_imu_fd(fr, back), _values(back)))
        acc = ffi.new("att_accel_t *")
        acc.gravity, acc.linear, acc.earth = floats(3, 9.8), floats(3, 50.0), floats(3, 50.0)
        acc.valid = int(rng.choice([0, 1, int(lib.ATT_OUT_ACCEL), int(lib.ATT_OUT_ACCEL)]))
        lib.att_can_encode_accel(acc, counter, fr)
        frames(2)
        out.extend((lib.att_can_decode_accel_part(fr + j, v), _values(v)) for j in range(3))
        lib.att_can_encode_accel_fd(acc, counter, fr)
        frames(1)
        acc2 = ffi.new("att_accel_t *")
        ffi.memmove(acc2, b"\xa5" * ffi.sizeof(acc2[0]), ffi.sizeof(acc2[0]))
        out.append((lib.att_can_decode_accel_fd(fr, acc2), _values(acc2)))
        ack = ffi.new("att_can_cal_ack_t *", [int(x) for x in rng.integers(0, 256, 7)])
        lib.att_can_encode_cal_ack(ack, fr)
        frames(1)
        ack2 = ffi.new("att_can_cal_ack_t *")
        out.append((lib.att_can_decode_cal_ack(fr, ack2), _values(ack2)))
        o = ffi.new("att_output_t *")
        o.q, o.euler, o.gyro_bias = floats(4, 1.0), floats(3, 3.0), floats(3, 0.5)
        for j, c in enumerate(floats(4, 1e-3)):
            o.cov[j] = c
        o.flags, o.steps, o.valid = (int(x) for x in rng.integers(0, 2**32, 3, dtype=np.uint64))
        kind = int(rng.integers(0, 9))
        n = lib.att_can_encode_output_set(o, kind, counter, int(rng.integers(0, 256)), fr)
        frames(int(n))
        out.append((n, lib.att_can_status_crc(fr + 5, fr, fr + 1, fr + 2)))
        for j in range(int(n)):
            o2 = ffi.new("att_output_t *")
            out.append((lib.att_can_decode_output(fr + j, o2), _values(o2)))
        lib.att_can_encode_output_fd(o, kind, counter, fr)
        frames(1)
        o2 = ffi.new("att_output_t *")
        out.append((lib.att_can_decode_output(fr, o2), _values(o2)))
        st = ffi.new("att_can_status_t *", [int(x) for x in rng.integers(0, 256, 2)])
        st.flags, st.steps = (int(x) for x in rng.integers(0, 65536, 2))
        st.error_count, st.ack = (int(x) for x in rng.integers(0, 256, 2))
        lib.att_can_encode_status(st, fr)
        frames(1)
        st2 = ffi.new("att_can_status_t *")
        out.append((lib.att_can_decode_status(fr, st2), _values(st2)))
        d = ffi.new("att_can_diag_t *", [int(x) for x in rng.integers(0, 400, 6)])
        lib.att_can_encode_diag(d, counter, fr)
        frames(1)
        bd = ffi.new("att_can_bus_diag_t *", [int(x) for x in rng.integers(0, 8, 2)])
        bd.bus_off, bd.recoveries, bd.error_passive, bd.error_warning, bd.rx_overruns = (
            int(x) for x in rng.integers(0, 400, 5)
        )
        lib.att_can_encode_diag_bus(bd, counter, fr)
        frames(1)
        bd2 = ffi.new("att_can_bus_diag_t *")
        out.append((lib.att_can_decode_diag_bus(fr, bd2), _values(bd2)))
    return out

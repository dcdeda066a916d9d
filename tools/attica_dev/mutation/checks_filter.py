"""Stage B: the filter calls (step counts, poisoned outputs, retunes), the stages, sample checks, names."""

from __future__ import annotations

from typing import Any

from attica_dev.mutation.checks_common import _sha, _values
from attica_dev.mutation.stage_a import _jumps


def _steps_check(kind: Any) -> str:
    """Filter.run with step counts (att_filter_step_n) over the adversarial stream, defaults and seed."""
    import numpy as np

    from attica import native
    from attica.settings import Preset, preset_settings
    from attica_dev import digests

    g, a, m = digests.adversarial_stream()
    rng = np.random.default_rng(2601)
    steps = rng.choice(np.array([1, 1, 1, 1, 2, 3, 5, 17, 400], np.uint32), g.shape[0]).astype(np.uint32)
    steps[[50, 300]] = [65535, 1000]
    parts = []
    for preset in (Preset.DEFAULT, Preset.SEED):
        f = native.Filter(kind, settings=preset_settings(kind, preset, digests.dt()))
        parts.append(f.run(g, a, m, full=True, check_units=False, steps=steps).tobytes())
        r = f.step(g[0], a[0], m[0], n=7)
        parts.append(np.asarray(r).tobytes())
    return _sha(*parts)


def _outputs_check(kind: Any) -> str:
    """Every output written whatever the caller's buffer held (poisoned with 0xA5 bytes).

    att_filter_step, att_filter_step_n, att_filter_output, att_filter_accel, before and after valid
    samples, after reset, with and without the stages; heading calls; the calls with NULL arguments.
    """
    import numpy as np

    from attica.calibration.stages import StageSettings, fill_c
    from attica.native import ffi, lib
    from attica_dev import digests

    g, a, m = digests.adversarial_stream()
    parts: list[Any] = []
    f = ffi.new("att_filter_t *")
    s = ffi.new("att_filter_settings_t *")
    out = ffi.new("att_output_t *")
    acc = ffi.new("att_accel_t *")
    smp = ffi.new("att_sample_t *")
    cs = ffi.new("att_calib_settings_t *")
    fill_c(cs, StageSettings(accel_outputs=True, remap=3, convention=2))

    def poison(x: Any) -> None:
        ffi.memmove(x, b"\xa5" * ffi.sizeof(x[0]), ffi.sizeof(x[0]))

    def record(tag: Any) -> None:
        parts.append((tag, bytes(ffi.buffer(out)), _values(acc)))

    for variant in range(3):
        parts.append(lib.att_filter_settings_default(int(kind), 0.01, s))
        parts.append(lib.att_filter_init(f, int(kind), s))
        if variant == 2:
            parts.append(lib.att_filter_calibrate(f, cs))
        for i in list(range(0, 12)) + [150, 151, 400]:
            smp.gyr, smp.acc, smp.mag = (tuple(float(x) for x in v[i]) for v in (g, a, m))
            if variant == 1 and i < 3:
                smp.acc = (0.0, 0.0, 0.0)
            poison(out)
            n = 1 + i % 3
            flags = lib.att_filter_step_n(f, smp, n, out) if n > 1 else lib.att_filter_step(f, smp, out)
            record(("step", i, flags))
            poison(out)
            lib.att_filter_output(f, out)
            poison(acc)
            lib.att_filter_accel(f, acc)
            record(("output", i))
            if i == 5:
                lib.att_filter_reset(f)
                poison(out)
                lib.att_filter_output(f, out)
                record("reset")
    parts.append(lib.att_filter_step(f, smp, ffi.NULL))
    parts.append(lib.att_filter_step(f, ffi.NULL, out))
    parts.append(lib.att_filter_step(ffi.NULL, smp, out))
    parts.append(lib.att_filter_step_n(f, smp, 0, out))
    parts.append((lib.att_filter_init(f, int(kind), ffi.NULL), lib.att_filter_init(ffi.NULL, int(kind), s)))
    parts.append((lib.att_filter_retune(f, ffi.NULL), lib.att_filter_calibrate(f, ffi.NULL)))
    parts.append(
        (lib.att_filter_set_heading(ffi.NULL, 0.0), lib.att_filter_heading_update(ffi.NULL, 0.0, 0.5, True))
    )
    parts.append(lib.att_filter_settings_default(int(kind), 0.01, ffi.NULL))
    fresh = ffi.new("att_filter_t *")
    poison(fresh)
    poison(out)
    lib.att_filter_output(ffi.NULL, out)
    record("null output")
    parts.append(lib.att_filter_step(fresh, smp, ffi.NULL))
    parts.append((lib.att_filter_set_heading(fresh, 1.0), lib.att_filter_retune(fresh, s)))
    for heading, gain, valid in (
        (1.0, 0.5, True),
        (float("nan"), 0.5, True),
        (1.0, 2.0, True),
        (7.0, 0.5, False),
    ):
        lib.att_filter_init(f, int(kind), s)
        for i in range(5):
            smp.gyr, smp.acc, smp.mag = (tuple(float(x) for x in v[i]) for v in (g, a, m))
            lib.att_filter_step(f, smp, ffi.NULL)
        parts.append(
            (lib.att_filter_heading_update(f, heading, gain, valid), lib.att_filter_set_heading(f, heading))
        )
        poison(out)
        lib.att_filter_output(f, out)
        record(("heading", heading, gain))
    return _sha(parts, np.zeros(1))


RETUNES: dict[str, list[dict[str, Any]]] = {
    "ars": [{"bias_mode": 2}, {"tau": 0.5, "gain": 0.0, "tau_acc_lp": 0.0}, {"integration": 1}],
    "mars": [{"mag_mode": 1}, {"bias_mode": 0}, {"tau_mag": 0.0, "alpha_mag": 0.05}],
    "kf": [{"gate": 20.0, "r_accel": 50.0}, {"noise_rates": False}, {"bias_mode": 2, "tau_acc_lp": 0.0}],
    "ekf": [{"gate": 9.0, "r_accel": 10.0}, {"q_bias": 1e-12}, {"noise_rates": False, "cos_min": 0.2}],
    "gyro": [{"cos_min": 0.2}, {"cos_min": 1e-6}, {"gyro_range": 1.0}, {"dt": 0.02}],
    "tilt": [{"normalise": False}, {"normalise": True}],
    "mekf": [
        {"gyro_scale_sd": 0.05},
        {"gyro_scale_sd": 0.02, "accel_noise": 0.5},
        {"gyro_scale_sd": 0.0},
        {"use_mag": False},
        {"gyro_scale_sd": 0.03, "tau_acc_lp": 0.0, "gate": 9.0},
    ],
}
"""Retunes in sequence per kind (stage B), each after a stretch of the simulated stream: a setting switched
on, changed while on and switched off again (the retune hooks keep or restart the states)."""


def _retune_check(kind: Any) -> str:
    """A run, then each retune of :data:`RETUNES` (refused ones recorded) followed by another run."""
    import dataclasses

    from attica import native
    from attica.settings import make_settings
    from attica_dev import digests

    g, a, m = digests.sim_stream()
    jg, ja, jm = (x[:, 0] for x in _jumps())
    f = native.Filter(kind, settings=make_settings(kind, dt=digests.dt()))
    parts: list[Any] = [f.run(g[:300], a[:300], m[:300], full=True, check_units=False).tobytes()]
    names = {fl.name for fl in dataclasses.fields(make_settings(kind))}
    for j, change in enumerate(RETUNES.get(kind.label, [])):
        change = {k: v for k, v in change.items() if k in names}
        try:
            f.retune(**change)
            parts.append(("ok", j))
        except (native.NativeError, ValueError) as e:
            parts.append(("refused", j, type(e).__name__))
        lo, hi = 300 + 250 * j, 550 + 250 * j
        parts.append(f.run(g[lo:hi], a[lo:hi], m[lo:hi], full=True, check_units=False).tobytes())
        lo, hi = 200 * j, 200 * j + 200
        parts.append(f.run(jg[lo:hi], ja[lo:hi], jm[lo:hi], full=True, check_units=False).tobytes())
    return _sha(parts)


def _stages_check() -> str:
    """att_calib_init's folded stages and att_calib_apply on nasty samples.

    Every remap, with and without a model, a mounting quaternion, each convention; the conventions'
    quaternion and vector maps.
    """
    import numpy as np

    from attica.calibration.stages import StageSettings, fill_c
    from attica.native import ffi, lib
    from attica_dev import golden

    rng = np.random.default_rng(2613)
    sp = golden.special_floats()
    n = 500
    v = rng.normal(0.0, 5.0, (n, 3)).astype(np.float32)
    pick = rng.random((n, 3)) < 0.1
    v[pick] = rng.choice(sp, int(pick.sum()))
    v[::50] = 0.0
    parts: list[Any] = []
    for i in range(60):
        kw: dict[str, Any] = {}
        if i % 2:
            m = (np.eye(3) + rng.normal(0, 0.02, (3, 3))).ravel()
            kw = {
                "gyro_misalignment": tuple(m),
                "gyro_sensitivity": tuple(rng.uniform(0.9, 1.1, 3)),
                "gyro_offset": tuple(rng.normal(0, 0.02, 3)),
                "accel_misalignment": tuple(m[::-1]),
                "accel_sensitivity": tuple(rng.uniform(0.9, 1.1, 3)),
                "accel_offset": tuple(rng.normal(0, 0.2, 3)),
                "soft_iron": tuple((np.eye(3) + rng.normal(0, 0.05, (3, 3))).ravel()),
                "hard_iron": tuple(rng.normal(0, 20, 3)),
            }
        elif i % 4 == 2:
            kw = {"hard_iron": (1.0, -2.0, 0.5)}
        remap = i % 25
        if remap == 0 and i % 3:
            q = rng.normal(size=4)
            kw["mounting"] = tuple(q / np.linalg.norm(q))
        s = StageSettings(remap=remap, convention=i % 3, accel_outputs=bool(i % 2), **kw)
        cs = ffi.new("att_calib_settings_t *")
        fill_c(cs, s)
        c = ffi.new("att_calib_t *")
        parts.append((lib.att_calib_init(c, cs), _values(c)))
        g, a, m_ = v.copy(), v.copy(), v.copy()
        buf = [ffi.from_buffer("float[]", x) for x in (g, a, m_)]
        lib.att_host_calib_apply(c, *buf, n)
        parts.append(g.tobytes() + a.tobytes() + m_.tobytes())
    for conv in range(4):
        for row in golden.math_inputs("quat_mul", 40, seed=conv)[:, :4]:
            q = ffi.new("att_quat_t *", tuple(float(x) for x in row))
            parts.append(_values(lib.att_calib_quat_to(q[0], conv)))
            w = ffi.new("att_vec3_t *", tuple(float(x) for x in row[1:]))
            parts.append(_values(lib.att_calib_vec_to(w[0], conv)))
    return _sha(parts)


def _sensor_check() -> str:
    """The public sample checks (att_sensor.h; the filters use their inline twins) on special vectors."""
    import numpy as np

    from attica.native import ffi, lib
    from attica_dev import golden

    rows = golden.math_inputs("vec3_cross", 600, seed=5)
    rows = np.concatenate([rows[:, :3], rows[:, 3:], np.zeros((4, 3), np.float32)])
    rows[-3] = (float(2.0**-50), 0.0, 0.0)  # |v|^2 = 2^-100 exactly
    rows[-2] = (np.nan, 0.0, 0.0)
    rows[-1] = (0.0, 0.0, np.inf)
    norm = ffi.new("float *")
    parts: list[Any] = []
    for r in rows:
        v = ffi.new("att_vec3_t *", tuple(float(x) for x in r))[0]
        for rng_ in (34.906586, 156.9064, 1000.0, float(np.linalg.norm(r.astype(np.float64))), 0.0):
            norm[0] = -5.0
            a = lib.att_sensor_check_accel(v, rng_, norm)
            parts.append((lib.att_sensor_check_gyro(v, rng_), a, norm[0]))
            norm[0] = -5.0
            parts.append((lib.att_sensor_check_mag(v, rng_, norm), norm[0]))
        parts.append(_values(lib.att_sensor_tilt(v)))
    for sec in (0.0, -1.0, 0.5, 1e-9, 1e9, float("nan"), float("inf"), 3.0):
        for dt in (0.01, 1e-6, 1.0, 0.0, float("nan")):
            parts.append(lib.att_sensor_samples(sec, dt))
    return _sha(parts)


def _names_check() -> str:
    """The names of kinds, flags and calibration errors; flags formatted into buffers of every size."""
    from attica.native import ffi, lib

    def text(p: Any) -> bytes | None:
        return ffi.string(p) if p != ffi.NULL else None

    parts: list[Any] = [text(lib.att_filter_name(k)) for k in range(0, 12)]
    parts += [text(lib.att_flag_name(1 << i)) for i in range(32)]
    parts += [text(lib.att_flag_name(v)) for v in (0, 3, 0xFFFFFFFF)]
    parts += [text(lib.att_calib_error_name(e)) for e in range(0, 40)]
    buf = ffi.new("char[]", 400)
    for flags in (0, 1, 0x5, 0x8000, 0x10000, 0xFFFF, 0xFFFFFFFF, 0x80000001):
        for size in (0, 1, 2, 5, 9, 17, 64, 400):
            n = lib.att_flags_format(flags, buf if size else ffi.NULL, size)
            parts.append((flags, size, n, ffi.string(buf) if size else None))
    return _sha(parts)

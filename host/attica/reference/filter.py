"""Mirror of firmware/src/filters/att_filter.c: one interface over every reference filter."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica import kinds
from attica.checks import filter_settings, warn_units
from attica.outputs import OUT_ALL, OUTPUT_DTYPE
from attica.reference import calib as rc
from attica.reference import detmath as dm
from attica.reference import hardiron as hiron
from attica.reference._common import as_batch, c_state_values, load_c_state, split3, stack, state_values
from attica.results import Outputs, as_outputs
from attica.settings import FilterKind, Flag

STEP_N_MAX = 65535
"""ATT_FILTER_STEP_N_MAX: the largest n of one att_filter_step_n."""


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, np.floating):
        fb = np.float32(b)
        return bool((np.isnan(a) and np.isnan(fb)) or a.view(np.uint32) == fb.view(np.uint32))
    return int(a) == int(b)


class Filter:
    """Any reference filter by kind, ``n`` instances in lockstep, with the C interface's outputs.

    ``Filter("ars", 0.01)``: the sample period in s follows the kind, as in :class:`attica.native.Filter`.

    Parameters
    ----------
    kind
        A kind name of :mod:`attica.kinds` (``"ars"``, ``"mekf"`` ...), its number or a :class:`FilterKind`.
    dt
        Sample period in s (overrides ``settings.dt``); required unless ``settings`` is given (tilt has
        none). A settings dataclass in this place is taken as ``settings``.
    settings
        A settings dataclass for the kind (defaults when None).
    n
        Number of independent instances stepped in lockstep.
    calibration
        Input/output stages (att_filter_calibrate): a :class:`~attica.calibration.Calibration`, a
        :class:`~attica.calibration.stages.StageSettings` or None (identity, ENU).
    accel_outputs
        Keep each step's accel for :meth:`accel` (g: the kind's ``gravity`` setting, else 9.80665),
        when ``calibration`` is a Calibration or None.
    **overrides
        Settings fields to change.

    """

    def __init__(
        self,
        kind: str | int | FilterKind,
        dt: Any = None,
        settings: Any = None,
        n: int = 1,
        calibration: Any = None,
        accel_outputs: bool = False,
        **overrides: Any,
    ) -> None:
        self.kind, self._settings = filter_settings(kind, dt, settings, overrides, "reference.Filter")
        self.n = n
        g = float(getattr(self.settings, "gravity", 9.80665))
        self.stages = rc.Stages(rc.as_stage_settings(calibration, g, accel_outputs))
        self.info = kinds.info(self.kind)
        """The kind's facts (:class:`attica.kinds.KindInfo`)."""
        self.impl: Any = self.info.reference_class()(self.settings, n)

    @property
    def settings(self) -> Any:
        """The settings in use (a frozen dataclass)."""
        return self._settings

    def reset(self) -> None:
        """att_filter_reset (the calibration is kept)."""
        self.impl.reset()
        self.stages.acc_body = None

    def calibrate(self, calibration: Any, gravity: float = 9.80665, accel_outputs: bool = False) -> None:
        """att_filter_calibrate: new input/output stages, the state kept (ValueError when refused).

        A mars or mekf hard-iron estimate starts again when the magnetometer's stage changed (its samples
        are in another frame or scale now); a new convention, gyro or accel model keeps it.
        """
        stages = rc.Stages(rc.as_stage_settings(calibration, gravity, accel_outputs))
        mag_same = stages.mag.same(self.stages.mag)
        self.stages = stages
        if hasattr(self.impl, "hi_on") and not mag_same:
            hiron.reset_where(self.impl, np.ones(self.impl.n, np.bool_))

    def accel(self) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]:
        """att_filter_accel: (gravity, linear, earth) accelerations, each (n, 3), m/s^2."""
        if self.info.q_state:
            g, lin, e = self.stages.accel(self.impl.q)
        else:  # an Euler-angle state (the EKF): q from the angles
            g, lin, e = self.stages.accel(tuple(self.impl.quat.T))
        return stack(g), stack(lin), stack(e)

    def set_heading(self, heading: float) -> None:
        """att_filter_set_heading (rad, the output convention's yaw)."""
        rc.set_heading(self.kind.label, self.impl, self.stages.convention, heading)

    def heading_update(self, heading: float, gain: float, valid: bool = True) -> None:
        """att_filter_heading_update (the kinds whose :func:`attica.kinds.heading` is ``UPDATE``)."""
        rc.heading_update(self.kind.label, self.impl, self.stages.convention, heading, gain, valid)

    def retune(self, settings: Any = None, **overrides: Any) -> None:
        """att_filter_retune: new settings for every instance, the state kept (see each kind's retune).

        ``settings`` (a settings dataclass, default: the current ones) with field ``overrides``; the
        checks of the constructor apply (a time constant > 0 is used, the gain beside it ignored).
        """
        base = settings if settings is not None else self._settings
        _, new = filter_settings(self.kind, None, base, overrides, "reference.Filter.retune")
        self.impl.retune(new)
        self._settings = new

    def load_c_states(self, states: Any) -> None:
        """Set instance i from ``states[i]``, a C ``att_filter_t`` of the same kind (cffi)."""
        for i in range(self.n):
            st = states[i]
            if int(st.kind) != int(self.kind):
                raise ValueError(f"state {i} is a {int(st.kind)} filter, expected {self.kind.label}")
            load_c_state(self.impl, self.impl.STATE, i, getattr(st.u, self.kind.label))

    def state_diff(self, i: int, c_state: Any) -> list[str]:
        """The fields where instance i and the C ``att_filter_t`` differ (bit for bit, NaN == NaN).

        Compared: every state field (``STATE``) and every coefficient (``COEFFS``: what init / retune
        derived from the settings), so a wrong gain left by a retune is seen as well as a wrong state.
        """
        c_kind = getattr(c_state.u, self.kind.label)
        diff = []
        for name, layout in {**self.impl.STATE, **self.impl.COEFFS}.items():
            ours = state_values(self.impl, {name: layout}, i)
            theirs = c_state_values({name: layout}, c_kind)
            if len(ours) != len(theirs) or not all(_same(a, b) for a, b in zip(ours, theirs, strict=True)):
                diff.append(name)
        return diff

    def state_matches(self, i: int, c_state: Any) -> bool:
        """True when instance i equals the C ``att_filter_t`` bit for bit: :meth:`state_diff` is empty."""
        return not self.state_diff(i, c_state)

    def _step_impl(self, gyr: Any, acc: Any, mag: Any) -> NDArray[np.uint32]:
        given = {"gyr": gyr, "acc": acc, "mag": mag}
        return self.impl.step(*(given[s] for s in self.info.sensors))  # type: ignore[no-any-return]

    def output(self) -> Outputs:
        """att_filter_output for every instance: (n,) records of OUTPUT_DTYPE."""
        f = self.impl
        k = self.info
        out = np.zeros(self.n, OUTPUT_DTYPE)
        out["q"] = stack(f.q) if k.q_state else f.quat  # an Euler-angle state: q derived on request
        out["euler"] = stack(f.euler) if k.euler_state else stack(dm.quat_to_euler(f.q))
        if k.gyro_bias:
            out["gyro_bias"] = stack(f.bias)
        if k.covariance:
            out["cov"] = stack(f.output_cov())
        if self.stages.convention != rc.ENU:
            qc = rc.quat_to(tuple(out["q"].T), self.stages.convention)
            out["q"] = stack(qc)
            out["euler"] = stack(dm.quat_to_euler(qc))
        out["flags"] = f.flags
        out["steps"] = f.steps
        out["valid"] = np.uint32(OUT_ALL)
        return as_outputs(out)

    def _step_once(self, gyr: Any, acc: Any, mag: Any) -> NDArray[np.uint32]:
        st = self.stages
        if st.active & (rc.ACTIVE_INPUT | rc.ACTIVE_ACC):
            g3, a3, m3 = st.apply(split3(gyr, self.n), split3(acc, self.n), split3(mag, self.n))
            gyr, acc, mag = stack(g3), stack(a3), stack(m3)
            if st.active & rc.ACTIVE_ACC:
                st.acc_body = a3
        self._step_impl(gyr, acc, mag)
        return np.asarray(self.impl.flags, np.uint32)

    def step(self, gyr: Any, acc: Any, mag: Any = None, n: int = 1) -> Outputs:
        """One step of every instance; inputs (n, 3) or (3,). Returns (n,) output records.

        ``n`` > 1: att_filter_step_n, the sample held over n periods (n steps, flags ORed over them;
        above ``STEP_N_MAX`` clamped and flagged CLAMPED).
        """
        if mag is None:
            mag = np.zeros(3, np.float32)
        count = int(n)
        if count < 1:
            raise ValueError(f"{self.kind.label} reference Filter.step: n must be >= 1, got {n}")
        flags = np.zeros(self.n, np.uint32)
        if count > STEP_N_MAX:
            count = STEP_N_MAX
            flags |= np.uint32(Flag.CLAMPED)
        for _ in range(count):
            flags |= self._step_once(gyr, acc, mag)
        out = self.output()
        out["flags"] = flags
        return out

    def run(
        self, gyr: Any, acc: Any, mag: Any = None, check_units: bool = True, steps: Any = None
    ) -> Outputs:
        """Step through N samples: inputs (N, 3) (all instances fed the same) or (N, n, 3).

        Returns (N,) records for n == 1 and 2-D inputs, else (N, n). ``check_units``: warn
        (:class:`attica.UnitWarning`) when the inputs look like deg/s, g, gauss or nT. ``steps``: (N,)
        periods each row advances (see :meth:`step`), the same for every instance; None: 1 each.
        """
        if check_units:
            warn_units(gyr, acc, mag, f"{self.kind.label} reference Filter.run")
        g, multi = as_batch(gyr, 3)
        a, _ = as_batch(acc, 3)
        m = as_batch(mag, 3)[0] if mag is not None else np.zeros((g.shape[0], 1, 3), np.float32)
        if a.shape[0] != g.shape[0] or m.shape[0] != g.shape[0]:
            raise ValueError("gyr, acc and mag must have the same number of samples")
        counts = np.ones(g.shape[0], np.int64) if steps is None else np.asarray(steps, np.int64)
        if counts.shape != (g.shape[0],):
            raise ValueError(f"steps must have shape ({g.shape[0]},), got {counts.shape}")
        out = np.empty((g.shape[0], self.n), OUTPUT_DTYPE)
        for i in range(g.shape[0]):
            out[i] = self.step(g[i], a[i], m[i], int(counts[i]))
        if not multi and self.n == 1:
            return as_outputs(out[:, 0])
        return as_outputs(out)

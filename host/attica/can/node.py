"""The C node (firmware/src/node/att_node.c, att_node.h) in-process via cffi: push, poll, pop frames."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.can.layout import FRAME_DTYPE, frames
from attica.checks import implied_gains
from attica.cview import CView
from attica.outputs import OUTPUT_DTYPE
from attica.settings import FilterKind, make_settings, to_dict

STATS_FIELDS = (
    "rx_frames",
    "crc_errors",
    "counter_gaps",
    "dlc_errors",
    "unknown_ids",
    "duplicates",
    "stale_partials",
    "rx_overflows",
    "tx_overflows",
    "samples",
    "steps",
    "sets",
    "tx_frames",
    "commands",
)
"""Fields of ``att_node_stats_t``."""


class NodeError(RuntimeError):
    """att_node_init refused the settings."""


class Node:
    """The C node (att_node.h) in-process: push frames, poll, pop frames.

    Parameters
    ----------
    kind
        Filter kind (name or :class:`FilterKind`).
    settings
        Filter settings dataclass (defaults when None); ``dt`` is set to ``1 / sample_rate`` (float32)
        unless given in ``overrides``.
    sample_rate
        Hz.
    bitrate, data_bitrate, fd, output_divider, diag_divider
        As in ``att_node_settings_t``.
    calibration, accel_out
        The node's calibration (a :class:`~attica.calibration.Calibration` or
        :class:`~attica.calibration.stages.StageSettings`; None: identity, ENU) and its acceleration frames.
    id_offset
        Added to every attica CAN ID the node receives and sends (0: the DBC's IDs; -256 .. 1279).
    **overrides
        Filter settings fields to change.

    Raises
    ------
    NodeError
        When ``att_node_init`` refuses the settings (the message names the bus load when > 100 %).

    """

    def __init__(
        self,
        kind: str | int | FilterKind,
        settings: Any = None,
        sample_rate: float = 100.0,
        bitrate: int = 500_000,
        data_bitrate: int = 0,
        fd: bool = False,
        output_divider: int = 1,
        diag_divider: int = 16,
        calibration: Any = None,
        accel_out: bool = False,
        id_offset: int = 0,
        **overrides: Any,
    ) -> None:
        from attica import native
        from attica.calibration.stages import fill_c
        from attica.reference.calib import as_stage_settings

        self._native = native
        ffi, lib = native.ffi, native.lib
        self.kind = FilterKind.parse(kind)
        dt = float(np.float32(1.0) / np.float32(sample_rate))
        overrides.setdefault("dt", dt)
        dt_over = overrides.pop("dt")
        self.settings = make_settings(
            self.kind, settings, dt_over, **implied_gains(self.kind, settings, overrides)
        )
        s = ffi.new("att_node_settings_t *")
        native._check(
            lib.att_filter_settings_default(int(self.kind), dt, ffi.addressof(s, "filter")),
            "att_filter_settings_default",
        )
        native._fill(getattr(s.filter, self.kind.label), to_dict(self.settings))
        s.kind = int(self.kind)
        s.sample_rate = sample_rate
        s.bitrate = bitrate
        s.data_bitrate = data_bitrate
        s.fd = fd
        s.output_divider = output_divider
        s.diag_divider = diag_divider
        fill_c(s.calib, as_stage_settings(calibration, float(getattr(self.settings, "gravity", 9.80665))))
        s.accel_out = accel_out
        s.id_offset = id_offset
        self._s = s
        self.fd = fd
        self.bus_load = float(lib.att_node_bus_load(s))
        self._n = ffi.new("att_node_t *")
        status = int(lib.att_node_init(self._n, s))
        if status != lib.ATT_OK:
            raise NodeError(f"att_node_init: {self._refusal(s, status, sample_rate, id_offset)}")
        self._one = ffi.new("att_can_frame_t *")

    def _refusal(self, s: Any, status: int, sample_rate: float, id_offset: int) -> str:
        """Why att_node_init refused ``s``, from att_node_settings_check (it names the field)."""
        ffi, lib = self._native.ffi, self._native.lib
        why = ffi.new("att_settings_error_t *")
        checked = int(lib.att_node_settings_check(s, why))
        if checked != status:  # the check and init agree by construction (tests/test_node.py)
            raise AssertionError(f"att_node_settings_check {checked} != att_node_init {status}")
        if status != lib.ATT_ERR_SETTINGS or why.field == ffi.NULL:
            return f"status {status}"
        field = ffi.string(why.field).decode()
        rule, unit = ffi.string(why.rule).decode(), ffi.string(why.unit).decode()
        if field == "bus load":
            return f"the outputs need {100 * self.bus_load:.1f} % of the bus (> 100 %)"
        if field == "filter.dt":
            return f"the filter's dt {self.settings.dt:g} s does not match sample_rate {sample_rate:g} Hz"
        if field == "id_offset":
            return f"id_offset {id_offset} moves an ID out of 0 .. 0x7FF (allowed {rule})"
        if field.startswith("calib."):  # a line of the stages' contract (att_calib_settings_rule)
            return f"the calibration is refused: {field[6:]} must be {rule}{' ' + unit if unit else ''}"
        if "." in field:  # a field of the filter's settings
            filt = ffi.addressof(s, "filter")
            problem = self._native.settings_problem(self.kind, filt, "the filter's settings")
            text = str(problem) if problem is not None else field
            if field.endswith(".dt") and 0.0 < sample_rate < 1.0:  # a period given as the rate?
                text += (
                    f" (sample_rate is a rate in Hz, not a period: {sample_rate:g} Hz is one sample "
                    f"every {1.0 / sample_rate:g} s)"
                )
            return text
        value = getattr(s, field)
        return f"{field} = {value} is out of range: allowed {rule}{' ' + unit if unit else ''}"

    @property
    def state(self) -> CView:
        """The C node: a live :class:`~attica.cview.CView` of this node's ``att_node_t *``.

        Live, not a copy (writing through it changes the node); it and everything taken from it
        (``node.state.stats``, ``node.state.f.u``) keep the node's C memory alive. For C calls pass
        ``node.state.ptr``; ``node.state.copy()`` is a snapshot.
        """
        return CView(self._n, self._n, self._native.ffi)

    def stats(self) -> dict[str, int]:
        """The node counters."""
        st = self._n.stats
        return {name: int(getattr(st, name)) for name in STATS_FIELDS}

    def output(self) -> NDArray[np.void]:
        """Output of the last filter step (OUTPUT_DTYPE record, shape ())."""
        out = np.zeros((), OUTPUT_DTYPE)
        self._native.ffi.memmove(out, self._native.ffi.addressof(self._n, "out"), OUTPUT_DTYPE.itemsize)
        return out

    @property
    def running_kind(self) -> FilterKind:
        """The filter kind now running (changes with a select command)."""
        return FilterKind(int(self._n.kind))

    def push(self, fr: NDArray[np.void]) -> int:
        """att_node_rx for each frame; returns how many the rx ring took."""
        fr = np.ascontiguousarray(np.atleast_1d(fr), FRAME_DTYPE)
        ffi, lib = self._native.ffi, self._native.lib
        buf = ffi.from_buffer("att_can_frame_t[]", fr)
        return sum(1 for i in range(fr.shape[0]) if lib.att_node_rx(self._n, buf + i))

    def push_sample(self, gyr: Any, acc: Any, mag: Any = None) -> bool:
        """att_node_push_sample: one sample of an IMU on the node's own board (rad/s, m/s^2, uT).

        Returns False when the tx ring has no room for the outputs (counted in rx_overflows).
        """
        ffi, lib = self._native.ffi, self._native.lib
        s = ffi.new("att_sample_t *")
        nan = float("nan")
        for name, v in (("gyr", gyr), ("acc", acc), ("mag", (nan, nan, nan) if mag is None else mag)):
            x, y, z = (float(np.float32(c)) for c in v)
            getattr(s, name).x = x
            getattr(s, name).y = y
            getattr(s, name).z = z
        return bool(lib.att_node_push_sample(self._n, s))

    def rx_ids(self) -> list[int]:
        """att_node_rx_ids: the CAN IDs the node receives (id_offset applied)."""
        ffi, lib = self._native.ffi, self._native.lib
        ids = ffi.new("uint32_t[]", int(lib.ATT_NODE_RX_IDS_MAX))
        return [int(ids[i]) for i in range(int(lib.att_node_rx_ids(self._n, ids)))]

    def poll(self) -> int:
        """att_node_poll: returns the filter steps run (sample periods: k + 1 for a sample after k lost)."""
        return int(self._native.lib.att_node_poll(self._n))

    def pop(self) -> NDArray[np.void]:
        """Every frame waiting in the tx ring."""
        lib = self._native.lib
        n = int(lib.att_node_tx_pending(self._n))
        out = frames(n)
        buf = self._native.ffi.from_buffer("att_can_frame_t[]", out)
        for i in range(n):
            lib.att_node_tx(self._n, buf + i)
        return out

    def rx_pending(self) -> int:
        """Frames waiting in the rx ring (att_node_poll leaves some while the tx ring is short of room)."""
        return int(self._n.rx_head - self._n.rx_tail) & 0xFFFFFFFF

    def flush(self) -> tuple[NDArray[np.void], int]:
        """Poll and pop until the rx ring is empty; returns (frames sent, filter steps run)."""
        outs = [self.pop()]
        steps = 0
        while True:
            steps += self.poll()
            outs.append(self.pop())
            if self.rx_pending() == 0:
                return np.concatenate(outs), steps

    def run(self, fr: NDArray[np.void]) -> tuple[NDArray[np.void], int]:
        """Feed frames as a port does (rx, poll, drain tx after each); returns (frames sent, filter steps).

        The filter steps are sample periods: ``stats()["samples"]`` counts the samples, ``["steps"]`` the
        periods (a sample after k lost ones steps k + 1, att_node.h).
        """
        fr = np.ascontiguousarray(np.atleast_1d(fr), FRAME_DTYPE)
        ffi, lib = self._native.ffi, self._native.lib
        cap = 8 * fr.shape[0] + 128
        out = frames(cap)
        n_out = ffi.new("size_t *")
        steps = lib.att_host_node_run(
            self._n,
            ffi.from_buffer("att_can_frame_t[]", fr),
            fr.shape[0],
            ffi.from_buffer("att_can_frame_t[]", out),
            cap,
            n_out,
        )
        return out[: int(n_out[0])], int(steps)

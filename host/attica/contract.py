"""The settings contracts, read from the C library: one table per kind, the stages and the node.

The firmware writes each contract once, as a table of checks (``ATT_<KIND>_CHECKS``, ``ATT_CALIB_CHECKS``,
``ATT_NODE_CHECKS``): the validators, the checks that name a refused field and the listing functions
``att_filter_settings_rule``, ``att_calib_settings_rule`` and ``att_node_settings_rule`` are all expanded from
it. This module lists those lines, so that everything the host says about a range (``attica settings``,
the command line's help, docs/settings.md, :class:`~attica.native.SettingsError`) comes from the code that
enforces it. ``tests/test_contract.py`` checks the public headers' field comments, the Python settings
classes and the docs against these lines.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from attica.settings import FilterKind


@dataclass(frozen=True)
class Rule:
    """One line of a settings contract.

    Attributes
    ----------
    field
        ``"<kind>.<field>"`` (``"ars.tau_acc_lp"``, ``"ekf.euler_init.y"``), ``"calib.<field>"`` or the node's
        field (``"bitrate"``).
    rule
        The accepted values in words: ``"[0, 1e4]"``, ``"(gravity, 1e4]"``, ``"0 or 1 (bool)"``.
    unit
        ``"s"``, ``"rad/s"``, ``"m/s^2"``, ``"uT"``, ``"rad"``, ``"Hz"``, ``"bit/s"``; ``""`` for none.
    minimum, maximum
        The rule's bounds for the settings it was read with (a bound that names another field, such as
        ``gravity``, holds that field's value).
    holds
        The line holds for those settings.
    value
        The field's value in those settings (vectors and quaternions as tuples).

    """

    field: str
    rule: str
    unit: str
    minimum: float
    maximum: float
    holds: bool
    value: Any = None

    @property
    def name(self) -> str:
        """The field without its kind or ``calib.`` prefix (``"tau_acc_lp"``, ``"gyro.offset"``)."""
        return self.field.split(".", 1)[1] if "." in self.field else self.field

    @property
    def text(self) -> str:
        """The rule with its unit: ``"[0, 1e4] s"``."""
        return f"{self.rule} {self.unit}" if self.unit else self.rule


def _plain(value: Any) -> Any:
    """A C value as Python: arrays as tuples (structs are tuples already)."""
    from attica.native import ffi

    if isinstance(value, ffi.CData) and ffi.typeof(value).kind == "array":
        return tuple(value)
    return value


def _lines(call: Callable[[int, Any], int], value: Callable[[str], Any]) -> list[Rule]:
    from attica.native import ffi, lib

    out: list[Rule] = []
    r = ffi.new("att_settings_error_t *")
    for index in range(10_000):
        status = int(call(index, r))
        if r.field == ffi.NULL:
            if status != lib.ATT_OK:
                raise ValueError(f"the settings contract could not be listed (status {status})")
            return out
        field = ffi.string(r.field).decode()
        out.append(
            Rule(
                field,
                ffi.string(r.rule).decode(),
                ffi.string(r.unit).decode(),
                float(r.min),
                float(r.max),
                status == lib.ATT_OK,
                _plain(value(field)),
            )
        )
    raise AssertionError("a settings table of 10,000 lines")  # pragma: no cover


def filter_rules(kind: str | int | FilterKind, settings: Any = None, dt: float = 0.01) -> list[Rule]:
    """The kind's settings contract, line by line, in the order the C library checks it.

    Parameters
    ----------
    kind
        The filter kind (name, number or :class:`~attica.kinds.FilterKind`).
    settings
        A settings dataclass of the kind, a mapping of fields to change from the defaults, or None (the
        defaults at ``dt``). The bounds that name other fields are filled in from it.
    dt
        The period of the defaults, s (when ``settings`` is None or a mapping).

    Returns
    -------
    list of Rule
        One per line of ``ATT_<KIND>_CHECKS``.

    """
    from attica import native
    from attica.settings import make_settings

    k = FilterKind.parse(kind)
    if settings is None or isinstance(settings, dict):
        settings = make_settings(k, None, dt, **(settings or {}))
    s = native._c_settings(k, settings)
    member = getattr(s, k.label)
    return _lines(
        lambda i, r: native.lib.att_filter_settings_rule(int(k), s, i, r),
        lambda field: native._c_value(member, field.split(".", 1)[1]),
    )


def calib_rules(stages: Any = None) -> list[Rule]:
    """The input/output stages' settings contract (``att_calib_settings_rule``), line by line.

    Parameters
    ----------
    stages
        A :class:`~attica.calibration.stages.StageSettings` (None: the identity, ENU).

    """
    from attica.calibration.stages import StageSettings, fill_c
    from attica.native import _c_value, ffi, lib

    cs = ffi.new("att_calib_settings_t *")
    fill_c(cs, stages if stages is not None else StageSettings())
    return _lines(
        lambda i, r: lib.att_calib_settings_rule(cs, i, r), lambda field: _c_value(cs, field.split(".", 1)[1])
    )


def node_rules(
    kind: str | int | FilterKind = FilterKind.ARS, sample_rate: float = 100.0, **fields: Any
) -> list[Rule]:
    """The node's own settings contract (``att_node_settings_rule``), line by line.

    Parameters
    ----------
    kind, sample_rate
        As in ``att_node_settings_default``.
    **fields
        ``att_node_settings_t`` fields to change from those defaults (``bitrate=250_000``).

    """
    from attica.native import _c_value, _check, ffi, lib

    s = ffi.new("att_node_settings_t *")
    _check(
        lib.att_node_settings_default(int(FilterKind.parse(kind)), sample_rate, s),
        "att_node_settings_default",
    )
    for name, value in fields.items():
        setattr(s, name, value)
    return _lines(lambda i, r: lib.att_node_settings_rule(s, i, r), lambda field: _c_value(s, field))


def bound_text(value: float) -> str:
    """A bound as short text (``1e-06``, ``10000``, ``inf``)."""
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return f"{value:.7g}"

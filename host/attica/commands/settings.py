"""``attica settings [KIND ...]``: every setting with its default, accepted values and unit.

The table is read from the C library's own contract (``att_filter_settings_rule``,
``att_calib_settings_rule``, ``att_node_settings_rule``; :mod:`attica.contract`): what it prints is what
the firmware enforces. With ``--set NAME=VALUE`` the values are checked as ``attica run`` would, and a
refused line is marked::

    attica settings ekf
    attica settings mars --set tau_acc=0.5 --dt 0.001
    attica settings calib node
    attica settings all --markdown      # docs/settings.md
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Sequence
from typing import Any

from attica.contract import Rule, bound_text, calib_rules, filter_rules, node_rules
from attica.settings import FilterKind

NAME = "settings"
HELP = (
    "list every setting of a filter kind (or calib, node): default, accepted values, unit, from the C checks"
)

EXTRA = ("calib", "node")
"""The contracts that are not a filter kind's."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``attica settings``."""
    kinds = ", ".join(k.label for k in FilterKind)
    p.add_argument(
        "what",
        nargs="*",
        default=["all"],
        metavar="KIND",
        help=f"filter kinds ({kinds}), calib (the input/output stages), node (the CAN node) or all (default)",
    )
    p.add_argument("--dt", type=float, default=0.01, help="the filters' sample period, s (default 0.01)")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="check these filter settings (repeatable): a refused line is marked and the exit status is 1",
    )
    p.add_argument("--markdown", action="store_true", help="Markdown tables (docs/settings.md)")


def _value_text(value: Any) -> str:
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, float):
        return bound_text(value)
    if isinstance(value, tuple):
        return "(" + ", ".join(_value_text(v) for v in value) + ")"
    return str(value)


def _here(r: Rule) -> str:
    """The bounds for these settings when an interval rule names another field ("(gravity, 1e4]")."""
    m = _INTERVAL.match(r.rule)
    if m and any(re.search(r"[a-z_]{2,}", b) for b in (m["lo"], m["hi"])):
        return f"here {r.rule[0]}{bound_text(r.minimum)}, {bound_text(r.maximum)}{r.rule[-1]}"
    return ""


_INTERVAL = re.compile(r"^[\[(](?P<lo>[^,]+), (?P<hi>[^,\])]+)[\])]$")


def contracts(
    what: Sequence[str], dt: float, overrides: dict[FilterKind, dict[str, Any]]
) -> list[tuple[str, list[Rule]]]:
    """(title, lines) for each contract asked for, in the order of ``what`` (``all``: every one)."""
    names: list[str] = []
    for w in what:
        if w == "all":
            names += [k.label for k in FilterKind] + list(EXTRA)
        else:
            names.append(w)
    out: list[tuple[str, list[Rule]]] = []
    for name in dict.fromkeys(names):
        if name == "calib":
            out.append(("calib: the input/output stages (att_calib_settings_t)", calib_rules()))
        elif name == "node":
            out.append(("node: the CAN node's own settings (att_node_settings_t)", node_rules()))
        else:
            k = FilterKind.parse(name)
            title = f"{k.label}: att_{k.label}_settings_t (defaults at dt {dt:g} s)"
            out.append((title, filter_rules(k, overrides.get(k) or None, dt)))
    return out


def render_text(tables: list[tuple[str, list[Rule]]]) -> list[str]:
    """Aligned text tables: field, value, accepted values and unit, a mark on the lines that fail."""
    lines: list[str] = []
    for title, rules in tables:
        lines.append(title)
        rows = [(r.name, _value_text(r.value), r.text, _here(r), "" if r.holds else "REFUSED") for r in rules]
        wn = max(len(x[0]) for x in rows)
        wv = min(max(len(x[1]) for x in rows), 24)
        for name, value, text, here, mark in rows:
            extra = "; ".join(x for x in (here, mark) if x)
            lines.append(f"  {name:<{wn}}  {value:<{wv}}  {text}" + (f"  ({extra})" if extra else ""))
        lines.append("")
    return lines


def render_markdown(tables: list[tuple[str, list[Rule]]]) -> list[str]:
    """One Markdown table per contract: field, default, accepted values, unit."""
    lines: list[str] = []
    for title, rules in tables:
        lines += [f"### {title}", "", "| field | default | accepted | unit |", "| --- | --- | --- | --- |"]
        for r in rules:
            rule = r.rule.replace("|", "\\|")
            lines.append(f"| `{r.name}` | {_value_text(r.value)} | {rule} | {r.unit} |")
        lines.append("")
    return lines


def run(args: argparse.Namespace) -> int:
    """``attica settings``."""
    from attica.commands._common import CliError, plan_overrides

    known = {k.label for k in FilterKind} | set(EXTRA) | {"all"}
    for w in args.what:
        if w not in known:
            raise CliError(f"unknown kind {w!r}: one of {', '.join(sorted(known))}")
    kinds = [FilterKind.parse(w) for w in args.what if w not in EXTRA and w != "all"]
    if args.set and not kinds:
        raise CliError("--set needs a filter kind (attica settings KIND --set NAME=VALUE)")
    if not 1e-6 <= args.dt <= 1.0:
        raise CliError(f"--dt {args.dt:g}: a filter's period is in [1e-6, 1] s")
    overrides = plan_overrides(kinds, args.set) if args.set else {}
    tables = contracts(args.what, args.dt, overrides)
    print("\n".join((render_markdown if args.markdown else render_text)(tables)).rstrip())
    return 0 if all(r.holds for _, rules in tables for r in rules) else 1

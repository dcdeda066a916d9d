"""The ``attica`` command: one entry point, one subcommand per job (:mod:`attica.commands`).

- ``attica demo``: what ``make run`` shows: simulate, run the ARS in C and in the numpy reference,
  prove bit-exact agreement and print the attitude error.
- ``attica run``: run C filters over simulated or recorded data, print their error against truth.
- ``attica sim``: write a simulated IMU recording with ground truth (.npz, BROAD layout).
- ``attica eval``: accuracy on recorded trials with the BROAD metrics, peers side by side.
- ``attica info``: what a recording file holds (ROS bags, MCAP, ULog, EuRoC, phone exports ...): streams,
  rates, time report, sensors.
- ``attica settings``: every setting of a filter kind, the stages and the node, with its default,
  accepted values and unit, read from the C library's checks.
- ``attica paths``: where the firmware sources, headers, flags and DBC of this installation are.
- ``attica dbc``: attica's DBC with every CAN ID moved by an ID offset (a node with ``--id-offset``).
- ``attica node | replay | monitor | verify``: the CAN tools (python-can buses); ``--id-offset N`` for a
  node whose CAN IDs are the DBC's + N.
- ``attica view``: the attitude, the node and the bus on a local web page (live bus, log, ``--demo``).

Every user error is one ``attica: error: ...`` line on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence
from typing import Any

from attica.commands import COMMANDS
from attica.commands._common import CliError, parse_overrides
from attica.commands.run import run_native

__all__ = ["CliError", "build_parser", "main", "parse_overrides", "run_native"]


class _Parser(argparse.ArgumentParser):
    """argparse with errors in the ``attica: error:`` form (usage first, as argparse does)."""

    def error(self, message: str) -> Any:  # noqa: D102 - argparse's hook
        self.print_usage(sys.stderr)
        command = self.prog.removeprefix("attica").strip()
        self.exit(2, f"attica: error: {command + ': ' if command else ''}{message}\n")


def _version() -> str:
    from pathlib import Path

    import attica

    return f"attica {attica.__version__} ({Path(attica.__file__).parent})"


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``attica`` (every subcommand module of :data:`attica.commands.COMMANDS`)."""
    p = _Parser(
        prog="attica",
        description="attica: deterministic attitude estimation firmware, its bit-exact reference and tools.",
    )
    p.add_argument("--version", action="version", version=_version(), help="print the version and exit")
    sub = p.add_subparsers(
        dest="command", required=True, metavar="COMMAND", parser_class=_Parser, help="one of:"
    )
    for name in COMMANDS:
        mod = importlib.import_module(f"attica.commands.{name}")
        text = (mod.__doc__ or mod.HELP).strip().replace("``", "")  # the docstring, without rST quotes
        sp = sub.add_parser(mod.NAME, help=mod.HELP, description=text)
        sp.formatter_class = argparse.RawDescriptionHelpFormatter
        mod.add_arguments(sp)
        sp.set_defaults(func=mod.run)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``attica`` command."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except CliError as exc:
        print(f"attica: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # e.g. attica monitor ... | head
        sys.stderr.close()
        return 0


if __name__ == "__main__":
    sys.exit(main())

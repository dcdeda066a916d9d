"""The subcommands of ``attica``: one module each, registered the same way.

Every module of :data:`COMMANDS` defines ``NAME`` (the subcommand), ``HELP`` (its one-line description),
``add_arguments(parser)`` (its options, each with a help text) and ``run(args) -> int`` (the exit
status). User errors are raised as :class:`attica.commands._common.CliError` and printed by
:func:`attica.cli.main` as one ``attica: error: ...`` line (exit status 2), before any work when they
can be known before it (output paths, names, empty selections).
"""

from __future__ import annotations

COMMANDS = (
    "demo",
    "run",
    "sim",
    "eval",
    "info",
    "settings",
    "calibrate",
    "paths",
    "dbc",
    "node",
    "replay",
    "monitor",
    "verify",
    "view",
)
"""Subcommand modules, in the order ``attica --help`` lists them."""

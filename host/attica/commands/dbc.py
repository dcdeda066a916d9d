"""``attica dbc``: write attica's DBC for a node whose CAN IDs are moved by an ID offset.

``attica dbc --id-offset N -o FILE`` writes firmware/can/attica.dbc with every message ID + N, for a node
with that ID offset (``attica-node --id-offset N``, ``att_node_settings_t.id_offset``, ``attica node
--id-offset N``): the names, signals, comments and attributes stay, and so do the E2E data IDs
(0x0A00 + the attica ID); the file states its offset (attribute AtticaIdOffset and the network comment).
Without ``-o`` the DBC goes to stdout. Every result is checked with cantools against the original.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from attica.commands._can import add_id_offset_argument, id_offset
from attica.commands._common import CliError, check_output_file

NAME = "dbc"
HELP = "write attica's DBC with every CAN ID moved by an ID offset (for a node with --id-offset N)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``attica dbc``."""
    add_id_offset_argument(p, "move every message ID by N, the node's ID offset")
    p.add_argument("-o", "--output", metavar="FILE", help="write the DBC here (default: stdout)")


def run(args: argparse.Namespace) -> int:
    """``attica dbc``."""
    from attica import resources
    from attica.can.dbcshift import DbcShiftError, shifted_dbc
    from attica.can.idoffset import offset_text

    offset = id_offset(args)
    source = resources.dbc_path()
    out = Path(args.output) if args.output else None
    if out is not None:
        check_output_file(out, "DBC")
        if out.exists() and out.resolve() == source.resolve():
            raise CliError(f"{out} is attica's own DBC, the source of the copy; write the copy elsewhere")
    try:
        text = shifted_dbc(offset, source)
    except DbcShiftError as exc:
        raise CliError(str(exc)) from None
    if out is None:
        sys.stdout.write(text)
        return 0
    out.write_text(text, encoding="utf-8")
    moved = f"every message ID {offset_text(offset)}" if offset else "the IDs of attica.dbc (offset 0)"
    print(f"wrote {out}: {moved}; E2E data IDs unchanged (0x0A00 + the attica ID)")
    return 0

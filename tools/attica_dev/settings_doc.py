"""``python -m attica_dev.settings_doc [--update]`` (``make docs-figures``): docs/settings.md's tables.

The tables between ``<!-- settings: begin -->`` and ``<!-- settings: end -->`` are ``attica settings all
--markdown``: every line of every settings contract as the C library lists it. Without ``--update`` it
prints them; tests/test_contract.py checks that the committed page holds them.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Sequence
from pathlib import Path

from attica.commands.settings import contracts, render_markdown

DOC = Path(__file__).resolve().parents[2] / "docs" / "settings.md"
_BLOCK = re.compile(r"(<!-- settings: begin -->\n).*?(<!-- settings: end -->)", re.S)


def tables() -> str:
    """The Markdown of every contract (the defaults at dt 0.01 s)."""
    return "\n".join(render_markdown(contracts(["all"], 0.01, {}))) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    """Print the tables, or rewrite them in docs/settings.md with ``--update``."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--update", action="store_true", help="rewrite the tables in docs/settings.md")
    args = p.parse_args(argv)
    if not args.update:
        sys.stdout.write(tables())
        return 0
    text = DOC.read_text()
    if not _BLOCK.search(text):
        raise SystemExit(f"{DOC}: no settings markers")
    DOC.write_text(_BLOCK.sub(lambda m: m.group(1) + tables() + m.group(2), text))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

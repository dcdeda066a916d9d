"""``attica paths``: where this attica keeps its firmware (for firmware builds) and its extension.

Without options it prints every location; one option prints that one value alone (for scripts)::

    cc $(attica paths --cflags) -O2 -I"$(attica paths --include)" -c $(attica paths --sources)
    cmake -DATTICA_DIR="$(attica paths --firmware)" ...     # add_subdirectory(${ATTICA_DIR} attica)

``--cflags`` prints the flags firmware/attica.mk compiles attica's sources with (``$(ATTICA_CFLAGS)
$(ATTICA_WARNINGS)``, as CMake does): cflags.txt line 1, ``-fno-lto -ffunction-sections
-fdata-sections``, cflags.txt line 2 (:func:`attica.resources.compile_flags`).
"""

from __future__ import annotations

import argparse
import json
import shlex
from pathlib import Path

from attica import resources

NAME = "paths"
HELP = "print where the firmware sources, headers, compiler flags and DBC of this installation are"

_ITEMS = {
    "firmware": (
        "the firmware tree (CMakeLists.txt, attica.mk, src/, include/, can/, ports/)",
        resources.firmware_dir,
    ),
    "include": ("the include directory for -I (holds attica/att_filter.h ...)", resources.include_dir),
    "src": ("the directory of the firmware C sources", resources.source_dir),
    "cflags_file": ("cflags.txt: the flags every build of the firmware must use", resources.cflags_file),
    "dbc": ("the CAN database of the node's frames", resources.dbc_path),
    "version_header": ("att_version.h, the one place the version is written", resources.version_header),
}


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``attica paths``."""
    g = p.add_mutually_exclusive_group()
    for key, (text, _) in _ITEMS.items():
        g.add_argument(
            f"--{key.replace('_', '-')}", dest="only", action="store_const", const=key, help=f"print {text}"
        )
    g.add_argument(
        "--sources",
        dest="only",
        action="store_const",
        const="sources",
        help="print the C sources, one a line",
    )
    g.add_argument(
        "--cflags",
        dest="only",
        action="store_const",
        const="cflags",
        help="print the flags to compile attica's sources with, on one line: cflags.txt line 1, -fno-lto "
        "-ffunction-sections -fdata-sections, cflags.txt line 2 (the same as attica.mk and CMake)",
    )
    g.add_argument(
        "--extension",
        dest="only",
        action="store_const",
        const="extension",
        help="print the cffi extension's file",
    )
    g.add_argument("--json", dest="only", action="store_const", const="json", help="print everything as JSON")


def _extension() -> str:
    import importlib.util

    spec = importlib.util.find_spec("attica._native")
    return spec.origin if spec is not None and spec.origin else "(not built: make build, or pip install .)"


def run(args: argparse.Namespace) -> int:
    """``attica paths``."""
    from attica.commands._common import CliError

    try:
        values: dict[str, str] = {k: str(fn()) for k, (_, fn) in _ITEMS.items()}
    except resources.FirmwareNotFoundError as exc:
        raise CliError(str(exc)) from None
    values["cflags"] = " ".join(shlex.quote(f) for f in resources.compile_flags())
    values["extension"] = _extension()
    sources = [str(s) for s in resources.sources()]
    if args.only == "sources":
        print("\n".join(sources))
    elif args.only == "json":
        print(json.dumps({**values, "sources": sources}, indent=1))
    elif args.only is not None:
        print(values[args.only])
    else:
        width = max(len(k) for k in values)
        for k, v in values.items():
            print(f"{k.replace('_', ' '):<{width}}  {v}")
        print(f"{'sources':<{width}}  {len(sources)} files in {Path(values['src'])}")
    return 0

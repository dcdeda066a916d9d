"""Where attica keeps its firmware: C sources, headers, compiler flags and the CAN database.

An installed attica carries a copy of the repository's firmware/ tree as package data
(``attica/_firmware``, written by the build hook of setup.py) and finds it through
:mod:`importlib.resources`; an editable checkout uses the repository's firmware/ itself. ``attica
paths`` prints these locations for firmware builds, e.g.::

    cc $(attica paths --cflags) -O2 -I"$(attica paths --include)" -c $(attica paths --sources)

where ``--cflags`` prints :func:`compile_flags`: the flags firmware/attica.mk and firmware/CMakeLists.txt
compile attica's sources with, not only the file cflags.txt.

Nothing here writes files or compiles anything.
"""

from __future__ import annotations

import shlex
from importlib import resources
from pathlib import Path

__all__ = [
    "LIBRARY_FLAGS",
    "FirmwareNotFoundError",
    "cflags",
    "cflags_file",
    "compile_flags",
    "dbc_path",
    "firmware_dir",
    "include_dir",
    "source_dir",
    "sources",
    "version_header",
]

_DATA = "_firmware"  # = attica._build.FIRMWARE_DATA (kept literal: _build is build-time code)


class FirmwareNotFoundError(FileNotFoundError):
    """Neither the package data nor a checkout holds the firmware tree."""


def _checkout_firmware() -> Path:
    return Path(__file__).resolve().parents[2] / "firmware"


def firmware_dir() -> Path:
    """The firmware tree: ``src/``, ``include/attica/``, ``cflags.txt``, ``can/attica.dbc``, ``ports/``.

    Raises
    ------
    FirmwareNotFoundError
        When attica was installed without its package data and is not a checkout.

    """
    data = resources.files("attica") / _DATA
    if data.is_dir():
        return Path(str(data))
    checkout = _checkout_firmware()
    if (checkout / "cflags.txt").is_file():
        return checkout
    raise FirmwareNotFoundError(
        f"attica's firmware files are missing: neither {data} (package data of an installed attica) nor "
        f"{checkout} (a checkout) exists; reinstall attica from its wheel or sdist"
    )


def include_dir() -> Path:
    """The include directory to pass as ``-I`` (holds ``attica/att_filter.h`` ...)."""
    return firmware_dir() / "include"


def source_dir() -> Path:
    """The directory of the firmware C sources (``att_*.c`` in its sub-folders: math, core, filters ...)."""
    return firmware_dir() / "src"


def sources() -> list[Path]:
    """The firmware C sources (every ``*.c`` below :func:`source_dir`), sorted by path."""
    return sorted(source_dir().rglob("*.c"))


def cflags_file() -> Path:
    """firmware/cflags.txt: the flags every build of the firmware must use."""
    return firmware_dir() / "cflags.txt"


def cflags() -> list[str]:
    """The flags of :func:`cflags_file` as a list (both lines; see :func:`compile_flags` for a build)."""
    return shlex.split(cflags_file().read_text())


LIBRARY_FLAGS = ("-fno-lto", "-ffunction-sections", "-fdata-sections")
"""What firmware/attica.mk (``ATTICA_CFLAGS``) and firmware/CMakeLists.txt add to line 1 of cflags.txt
for attica's own sources. ``-fno-lto`` is part of the numerics contract: link-time optimisation could
inline attica's code into functions compiled with other floating-point flags (e.g. fused multiply-add)
and change the last bit. ``-ffunction-sections -fdata-sections`` change no bit of any result, only where
the code lands: with them a link with ``--gc-sections`` keeps just the functions (and filter kinds) the
application calls, which the sizes of docs/performance.md assume; they are here so that
``attica paths --cflags`` is exactly what the make fragment and CMake use (tests/test_cli.py compares)."""


def compile_flags() -> list[str]:
    """The flags to compile attica's sources with, in the order firmware/attica.mk gives them.

    ``$(ATTICA_CFLAGS) $(ATTICA_WARNINGS)`` of the make fragment, the same as CMake's: line 1 of
    cflags.txt (the numerics flags), :data:`LIBRARY_FLAGS` (``-fno-lto``, the section flags), then
    line 2 (the warning flags, ``-Werror`` included). Add the CPU and ``-O`` flags of your build; any
    ``-O`` level gives the same bits. ``attica paths --cflags`` prints these on one line.
    """
    lines = cflags_file().read_text().splitlines()
    numerics = shlex.split(lines[0]) if lines else []
    warnings = shlex.split(lines[1]) if len(lines) > 1 else []
    return [*numerics, *LIBRARY_FLAGS, *warnings]


def dbc_path() -> Path:
    """The CAN database (DBC) of the node's frames."""
    return firmware_dir() / "can" / "attica.dbc"


def version_header() -> Path:
    """att_version.h, the one place the version is written."""
    return include_dir() / "attica" / "att_version.h"

"""Where attica keeps its firmware: C sources, headers, compiler flags and the CAN database.

An installed attica carries a copy of the repository's firmware/ tree as package data
(``attica/_firmware``, written by the build hook of setup.py) and finds it through
:mod:`importlib.resources`; an editable checkout uses the repository's firmware/ itself. ``attica
paths`` prints these locations for firmware builds, e.g.::

    cc $(attica paths --cflags) -O2 -I"$(attica paths --include)" -c $(attica paths --sources)

Nothing here writes files or compiles anything.
"""

from __future__ import annotations

import shlex
from importlib import resources
from pathlib import Path

__all__ = [
    "FirmwareNotFoundError",
    "cflags",
    "cflags_file",
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
    """The flags of :func:`cflags_file` as a list."""
    return shlex.split(cflags_file().read_text())


def dbc_path() -> Path:
    """The CAN database (DBC) of the node's frames."""
    return firmware_dir() / "can" / "attica.dbc"


def version_header() -> Path:
    """att_version.h, the one place the version is written."""
    return include_dir() / "attica" / "att_version.h"

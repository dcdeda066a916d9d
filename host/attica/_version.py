"""Read the version from att_version.h, the one place it is written (standard library only).

Used by ``attica.__version__`` at run time (on the installed copy of the header) and by setup.py at
build time (on the checkout's header, loading this file by path).
"""

from __future__ import annotations

import re

_MACRO = re.compile(r"^#define ATT_VERSION_(MAJOR|MINOR|PATCH|STRING)\s+(\S+)", re.M)


def parse_version_header(text: str) -> tuple[int, int, int]:
    """(major, minor, patch) of the text of att_version.h.

    Raises
    ------
    ValueError
        When a macro is missing or ``ATT_VERSION_STRING`` disagrees with the numbers.

    """
    found = dict(_MACRO.findall(text))
    try:
        numbers = (int(found["MAJOR"]), int(found["MINOR"]), int(found["PATCH"]))
        string = found["STRING"].strip('"')
    except KeyError as exc:
        raise ValueError(f"att_version.h: no ATT_VERSION_{exc.args[0]}") from None
    dotted = "{}.{}.{}".format(*numbers)
    if string != dotted:
        raise ValueError(f"att_version.h: ATT_VERSION_STRING {string!r} is not {dotted!r}")
    return numbers

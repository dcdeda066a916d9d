"""attica's DBC for a node with a CAN ID offset: every message ID moved by N, nothing else.

A node with ID offset N (``att_node_settings_t.id_offset``, ``attica-node --id-offset N``) sends and
receives every attica message at its DBC ID + N; the bytes, and the E2E data ID of each message
(0x0A00 + its attica ID, attribute ``E2EDataId``), do not change. :func:`shifted_dbc` writes
firmware/can/attica.dbc with every message ID + N (``attica dbc --id-offset N``), so that cantools, a
bus analyser or another ECU decodes that node's frames at their bus IDs.

The transform is a careful text transform: the message ID of every statement that names a message
(``BO_``, ``CM_ BO_``, ``CM_ SG_``, ``BA_ ... BO_``/``SG_``, ``VAL_``, ``SIG_VALTYPE_``, ``BO_TX_BU_``,
``SG_MUL_VAL_``, ``SIG_GROUP_``, ``BA_REL_``) moves; inside quoted strings nothing does. So names,
signals, comments, attributes, value tables and the file's layout stay as they are. The file states
its offset twice: a network attribute ``AtticaIdOffset`` (:func:`dbc_id_offset` reads it) and a
sentence at the end of the network comment. Every result is checked with cantools against the source
(:func:`check_shifted`): same messages, signals, comments and attributes, each ID + N.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

from attica.can.idoffset import check_id_offset

if TYPE_CHECKING:
    import cantools.database

__all__ = [
    "OFFSET_ATTRIBUTE",
    "DbcShiftError",
    "check_shifted",
    "dbc_id_offset",
    "shift_dbc_text",
    "shifted_dbc",
]

OFFSET_ATTRIBUTE = "AtticaIdOffset"
"""Network attribute of a DBC written for an ID offset: the offset (absent: 0)."""

_ID_STATEMENT = re.compile(
    r"^(\s*(?:BO_|BO_TX_BU_|CM_\s+(?:BO_|SG_)|BA_\s+\"[^\"]*\"\s+(?:BO_|SG_)|VAL_|SIG_VALTYPE_|"
    r"SG_MUL_VAL_|SIG_GROUP_|SIG_TYPE_REF_|"
    r"BA_REL_\s+\"[^\"]*\"\s+(?:BU_BO_REL_\s+\w+|BU_SG_REL_\s+\w+\s+SG_))\s+)(\d+)(?=\s|:|$)"
)
"""A statement that names a message by its ID (group 2), at the start of a line outside a string."""

_NETWORK_COMMENT = re.compile(r'^(CM_[ \t]+")((?:[^"\\]|\\.)*)(")', re.M)
"""The network comment ``CM_ "...";`` (no object type), possibly over several lines."""

_EXTENDED = 0x80000000
"""Bit 31 of a DBC message ID: an extended (29-bit) ID; attica's messages are 11-bit."""


class DbcShiftError(ValueError):
    """The DBC cannot be moved by this offset (out of range, already moved, or the result differs)."""


def dbc_id_offset(db: cantools.database.can.Database) -> int:
    """The ID offset a DBC was written for (its ``AtticaIdOffset`` attribute; 0 when it has none)."""
    dbc = db.dbc
    attr = dbc.attributes.get(OFFSET_ATTRIBUTE) if dbc is not None else None
    return int(attr.value) if attr is not None else 0


def _string_open(line: str, inside: bool) -> bool:
    """Whether a quoted string is open after ``line``, given whether one was open before it."""
    i = 0
    while i < len(line):
        c = line[i]
        if inside and c == "\\":
            i += 2
            continue
        if c == '"':
            inside = not inside
        i += 1
    return inside


def _note(offset: int) -> str:
    """The sentence appended to the network comment."""
    if offset == 0:
        return f" ID offset 0 (attribute {OFFSET_ATTRIBUTE}; attica dbc): the message IDs are the attica IDs."
    sign = "-" if offset > 0 else "+"
    return (
        f" ID offset {offset} ({hex(offset)}; attribute {OFFSET_ATTRIBUTE}; written by attica dbc "
        f"--id-offset {offset}) for a node with att_node_settings_t.id_offset = {offset}: every message ID "
        f"here is the attica ID {'+' if offset > 0 else '-'} {abs(offset)}. The E2E data IDs do not move: "
        f"E2EDataId and the CRC comments are 0x0A00 + the attica ID = 0x0A00 + CAN ID {sign} {abs(offset)}."
    )


def _insert_after_last(lines: list[str], pattern: str, new: str) -> None:
    """Insert ``new`` after the last line matching ``pattern`` (at the end when none does)."""
    rx = re.compile(pattern)
    where = [i for i, line in enumerate(lines) if rx.match(line)]
    lines.insert(where[-1] + 1 if where else len(lines), new)


def _insert_before_first(lines: list[str], pattern: str, new: str) -> None:
    """Insert ``new`` before the first line matching ``pattern`` (at the end when none does)."""
    rx = re.compile(pattern)
    where = [i for i, line in enumerate(lines) if rx.match(line)]
    lines.insert(where[0] if where else len(lines), new)


def shift_dbc_text(text: str, offset: int) -> str:
    """The DBC text ``text`` with every message ID + ``offset`` and the offset stated in the file.

    Raises
    ------
    DbcShiftError
        The offset is out of range, the text already states an offset, or an ID would leave 0 .. 0x7FF.

    """
    try:
        check_id_offset(offset)
    except ValueError as exc:
        raise DbcShiftError(str(exc)) from None
    if f'"{OFFSET_ATTRIBUTE}"' in text:
        raise DbcShiftError(
            f"this DBC already states an ID offset ({OFFSET_ATTRIBUTE}); move attica's own DBC"
        )
    lines = text.splitlines(keepends=True)
    newline = "\r\n" if lines and lines[0].endswith("\r\n") else "\n"
    inside = False
    for i, line in enumerate(lines):
        if not inside:
            m = _ID_STATEMENT.match(line)
            if m is not None and not int(m.group(2)) & _EXTENDED:
                old = int(m.group(2))
                new = old + offset
                if not 0 <= new <= 0x7FF:
                    raise DbcShiftError(
                        f"message ID {old:#x} + {offset} = {new:#x} is not an 11-bit ID (0 .. 0x7FF)"
                    )
                lines[i] = line[: m.start(2)] + str(new) + line[m.end(2) :]
        inside = _string_open(line, inside)
    _insert_after_last(lines, r"BA_DEF_\s", f'BA_DEF_  "{OFFSET_ATTRIBUTE}" INT -256 1279;{newline}')
    _insert_after_last(lines, r"BA_DEF_DEF_\s", f'BA_DEF_DEF_  "{OFFSET_ATTRIBUTE}" 0;{newline}')
    _insert_before_first(lines, r"BA_\s", f'BA_ "{OFFSET_ATTRIBUTE}" {offset};{newline}')
    out = "".join(lines)
    m = _NETWORK_COMMENT.search(out)
    if m is None:
        note = _note(offset).strip().replace('"', "'")
        lines = out.splitlines(keepends=True)
        _insert_before_first(lines, r"(CM_|BA_DEF_)\s", f'CM_ "{note}";{newline}')
        return "".join(lines)
    return out[: m.end(2)] + _note(offset) + out[m.end(2) :]


def _attributes(x: Any) -> dict[str, Any]:
    """The DBC attributes of a message or signal, by name."""
    dbc = getattr(x, "dbc", None)
    return {name: a.value for name, a in dbc.attributes.items()} if dbc is not None else {}


def _message(m: Any) -> tuple[Any, ...]:
    """What of a message must survive the move: everything but its ID."""
    return (m.name, m.comment, _attributes(m), m.length, m.is_fd, tuple(m.senders), m.cycle_time)


def _signal(s: Any) -> tuple[Any, ...]:
    """Everything of a signal."""
    return (
        s.name,
        s.comment,
        _attributes(s),
        s.start,
        s.length,
        s.byte_order,
        s.is_signed,
        s.is_float,
        s.scale,
        s.offset,
        s.minimum,
        s.maximum,
        s.unit,
        dict(s.choices or {}),
        tuple(s.receivers),
    )


def check_shifted(source: str, shifted: str, offset: int) -> None:
    """Check with cantools that ``shifted`` is ``source`` with every message ID + ``offset``.

    Raises
    ------
    DbcShiftError
        On the first difference (message, signal, comment, attribute) or a wrong stated offset.

    """
    import cantools

    a = cantools.database.load_string(source, database_format="dbc", strict=True)
    b = cantools.database.load_string(shifted, database_format="dbc", strict=True)
    assert isinstance(a, cantools.database.can.Database) and isinstance(b, cantools.database.can.Database)
    if [m.name for m in a.messages] != [m.name for m in b.messages]:
        raise DbcShiftError("the moved DBC does not hold the same messages")
    if [n.name for n in a.nodes] != [n.name for n in b.nodes]:
        raise DbcShiftError("the moved DBC does not hold the same nodes")
    if dbc_id_offset(b) != offset:
        raise DbcShiftError(f"the moved DBC states ID offset {dbc_id_offset(b)}, not {offset}")
    for ma, mb in zip(a.messages, b.messages):
        want = ma.frame_id if ma.is_extended_frame else ma.frame_id + offset
        if mb.frame_id != want or mb.is_extended_frame != ma.is_extended_frame:
            raise DbcShiftError(f"{ma.name}: ID {mb.frame_id:#x}, expected {want:#x}")
        if _message(ma) != _message(mb):
            raise DbcShiftError(f"{ma.name}: the message changed beyond its ID: {_message(mb)}")
        if [_signal(s) for s in ma.signals] != [_signal(s) for s in mb.signals]:
            raise DbcShiftError(f"{ma.name}: its signals changed")


def shifted_dbc(offset: int, source: str | Path | None = None) -> str:
    """The text of attica's DBC (or ``source``) with every message ID + ``offset``, checked.

    The result is compared with the source by :func:`check_shifted`.

    Raises
    ------
    DbcShiftError
        Out-of-range offset (the message says the range), or a source that cannot be moved.

    """
    from attica import resources

    path = Path(source) if source is not None else resources.dbc_path()
    text = path.read_text(encoding="utf-8")
    out = shift_dbc_text(text, offset)
    check_shifted(text, out, offset)
    return out

"""The node's CAN ID offset on the host side: every attica frame on the bus at its DBC ID + N.

A node with ID offset N (``att_node_settings_t.id_offset``, ``attica-node --id-offset N``,
``Node(id_offset=N)``) receives and sends every attica message at its DBC ID + N. Nothing else moves:
the frame's bytes, its E2E data ID (0x0A00 + the DBC ID) and so its CRC are those of the same message
at offset 0. The host tools apply the offset once, at the edge, and the codec (:mod:`attica.can.layout`,
:mod:`~attica.can.frames`, :mod:`~attica.can.e2e`) only ever sees the DBC's IDs:

- :class:`OffsetBus` wraps a python-can bus (``attica.can.bus.open_bus(..., id_offset=N)``): frames sent
  get +N, frames received -N;
- :func:`to_bus` / :func:`from_bus`: the same for one message (logs read and written, the monitor, which
  shows the frames as they are on the bus).

The mapping is ``(id - N) mod 0x800`` on 11-bit data frames, one to one: a frame whose bus ID minus N is
not an attica ID gets an ID that is not one either (it is "not attica", like any unknown ID), and the
frames received, shifted back with :func:`to_bus`, are exactly those of the bus (so logs written from
them are). Extended-ID, remote and error frames are left alone.

When no attica output comes back, :func:`silent_node_hint` says which offset was used and, from the E2E
CRCs of the frames that did arrive (:func:`guess_id_offset`), at which offset they are attica frames.
"""

from __future__ import annotations

import collections
import copy
from collections.abc import Iterable

import can

from attica.can.e2e import data_id, e2e_crc
from attica.can.layout import ACK_ANSWER, ID_STATUS, MSG_LEN, NO_CRC

__all__ = [
    "ID_OFFSET_MAX",
    "ID_OFFSET_MIN",
    "IdOffsetError",
    "OffsetBus",
    "check_id_offset",
    "from_bus",
    "from_bus_id",
    "guess_id_offset",
    "id_offset_of",
    "offset_text",
    "option_text",
    "parse_id_offset",
    "silent_node_hint",
    "to_bus",
    "to_bus_id",
]

ID_OFFSET_MIN = -256
"""Lowest ID offset (``ATT_NODE_ID_OFFSET_MIN``): the lowest attica ID, 0x100, moves to 0."""

ID_OFFSET_MAX = 1279
"""Highest ID offset (``ATT_NODE_ID_OFFSET_MAX``): the highest attica ID, 0x300, moves to 0x7FF."""

STD_ID_MASK = 0x7FF
"""11-bit identifiers: the offset arithmetic is modulo 0x800."""


class IdOffsetError(ValueError):
    """An ID offset that is not an integer in ``ID_OFFSET_MIN .. ID_OFFSET_MAX``."""


def offset_text(offset: int) -> str:
    """An offset as text: ``0``, ``+0x20 (32)``, ``-0x100 (-256)``."""
    if offset == 0:
        return "0"
    return f"{'-' if offset < 0 else '+'}0x{abs(offset):X} ({offset})"


def option_text(offset: int) -> str:
    """The command line option of an offset: ``--id-offset 0x20``, ``--id-offset=-0x20``.

    argparse takes a negative hex value only after ``=``.
    """
    return f"--id-offset {hex(offset)}" if offset >= 0 else f"--id-offset={hex(offset)}"


def check_id_offset(offset: int) -> int:
    """``offset`` when it is a valid ID offset.

    Raises
    ------
    IdOffsetError
        Not an integer, or out of range (an attica ID would leave 0 .. 0x7FF).

    """
    if isinstance(offset, bool) or not isinstance(offset, int):
        raise IdOffsetError(f"the ID offset must be an integer, got {offset!r}")
    if not ID_OFFSET_MIN <= offset <= ID_OFFSET_MAX:
        raise IdOffsetError(
            f"ID offset {offset} ({hex(offset)}) is out of range: it must be from {ID_OFFSET_MIN} to "
            f"{ID_OFFSET_MAX} (-0x100 .. 0x4FF), so that every attica ID (0x100 .. 0x300) stays an 11-bit "
            "ID (0 .. 0x7FF)"
        )
    return offset


def parse_id_offset(text: str) -> int:
    """An ID offset from the command line: decimal or ``0x`` hex, optionally signed (``-0x20``).

    Raises
    ------
    IdOffsetError
        Not an integer, or out of range.

    """
    try:
        value = int(text.strip(), 0)
    except ValueError:
        raise IdOffsetError(
            f"expected an integer from {ID_OFFSET_MIN} to {ID_OFFSET_MAX}, decimal or 0x hex "
            f"(e.g. 32 or 0x20), got {text!r}"
        ) from None
    return check_id_offset(value)


def to_bus_id(can_id: int, offset: int) -> int:
    """The bus ID of a DBC ID: ``(can_id + offset) mod 0x800``."""
    return (can_id + offset) & STD_ID_MASK


def from_bus_id(bus_id: int, offset: int) -> int:
    """The DBC ID of a bus ID: ``(bus_id - offset) mod 0x800`` (not an attica ID for other frames)."""
    return (bus_id - offset) & STD_ID_MASK


def _moves(msg: can.Message) -> bool:
    """True for the frames the offset applies to: 11-bit data frames."""
    return not (msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id)


def _with_id(msg: can.Message, can_id: int) -> can.Message:
    moved = copy.copy(msg)
    moved.arbitration_id = can_id
    return moved


def to_bus(msg: can.Message, offset: int) -> can.Message:
    """``msg`` (at its DBC ID) as it goes on the bus: a copy with the ID + offset (itself for offset 0)."""
    if offset == 0 or not _moves(msg):
        return msg
    return _with_id(msg, to_bus_id(msg.arbitration_id, offset))


def from_bus(msg: can.Message, offset: int) -> can.Message:
    """``msg`` as received on the bus, at its DBC ID: a copy with the ID - offset (itself for offset 0)."""
    if offset == 0 or not _moves(msg):
        return msg
    return _with_id(msg, from_bus_id(msg.arbitration_id, offset))


class OffsetBus(can.BusABC):
    """A bus seen through an ID offset: frames sent get ``+id_offset``, frames received ``-id_offset``.

    Parameters
    ----------
    inner
        The bus (its frames carry the bus IDs).
    id_offset
        The node's ID offset (:func:`check_id_offset`).

    """

    def __init__(self, inner: can.BusABC, id_offset: int) -> None:
        self._inner = inner
        self.id_offset = check_id_offset(id_offset)
        super().__init__(channel=str(getattr(inner, "channel_info", "") or "offset"))
        self._can_protocol = inner.protocol
        self.channel_info = f"{inner.channel_info} (attica ID offset {offset_text(id_offset)})"

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        msg = self._inner.recv(timeout)
        if msg is None:
            return None, False
        return from_bus(msg, self.id_offset), False

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Send a copy of ``msg`` at its bus ID."""
        self._inner.send(to_bus(msg, self.id_offset), timeout)

    def fileno(self) -> int:
        """The inner bus's file descriptor."""
        return int(self._inner.fileno())

    def shutdown(self) -> None:
        """Close the inner bus too."""
        super().shutdown()
        self._inner.shutdown()


def id_offset_of(bus: can.BusABC) -> int:
    """The ID offset a bus applies (0 unless it is an :class:`OffsetBus`)."""
    return bus.id_offset if isinstance(bus, OffsetBus) else 0


def _offsets(msg: can.Message) -> list[int]:
    """The ID offsets at which a bus frame is a well-formed attica frame with a good E2E CRC.

    Frames without a CRC of their own (the quaternion frames, ATT_STATUS of an output set) say nothing.
    """
    if not _moves(msg):
        return []
    data = bytes(msg.data)
    out = []
    for can_id, length in MSG_LEN.items():
        if can_id in NO_CRC or len(data) != length or bool(msg.is_fd) != (length == 64):
            continue
        if can_id == ID_STATUS and not data[7] & ACK_ANSWER:
            continue
        offset = msg.arbitration_id - can_id
        if ID_OFFSET_MIN <= offset <= ID_OFFSET_MAX and e2e_crc(data_id(can_id), data[1:]) == data[0]:
            out.append(offset)
    return out


def guess_id_offset(msgs: Iterable[can.Message]) -> int | None:
    """The ID offset at which most of ``msgs`` (bus frames) are attica frames by their E2E CRC, or None.

    A CRC-8 matches by chance once in 256 tries (and a frame is tried at every attica ID), so the guess
    needs at least three frames and more than twice the votes of the runner-up.
    """
    votes: collections.Counter[int] = collections.Counter()
    for msg in msgs:
        votes.update(set(_offsets(msg)))
    ranked = votes.most_common(2)
    if not ranked or ranked[0][1] < 3 or (len(ranked) > 1 and ranked[0][1] <= 2 * ranked[1][1]):
        return None
    return ranked[0][0]


def silent_node_hint(bus: can.BusABC | int, seen: Iterable[can.Message] = ()) -> str:
    """Why no attica output may have come back, for an error message.

    Parameters
    ----------
    bus
        The bus the command went out on (its :func:`id_offset_of` is the offset used), or the offset.
    seen
        Frames received meanwhile that are not attica frames at that offset (as the bus returned them,
        i.e. at bus ID - offset).

    """
    offset = bus if isinstance(bus, int) else id_offset_of(bus)
    raw = [to_bus(m, offset) for m in seen if _moves(m)]
    text = f"no attica output came back at ID offset {offset_text(offset)}"
    guess = guess_id_offset(raw)
    if guess is not None and guess != offset:
        return (
            f"{text}; the frames on the bus are attica frames at ID offset {offset_text(guess)} by their E2E "
            f"CRC: pass {option_text(guess)}"
        )
    if raw:
        ids = sorted({m.arbitration_id for m in raw})
        shown = ", ".join(f"0x{i:03X}" for i in ids[:8]) + (" ..." if len(ids) > 8 else "")
        text += f" ({len(raw)} other frames seen, bus IDs {shown})"
    return (
        f"{text}. Is a node running on this bus? If it runs with an ID offset (attica-node --id-offset N, "
        "att_node_settings_t.id_offset), pass the same --id-offset N"
    )

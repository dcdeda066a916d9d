"""Code size and stack of attica beside Fusion and VQF on the Cortex-M boards (part of ``make footprint``).

For every board (M4F, M7, M33) and optimisation level (-Os, -O2):

- .text (code + constants) the filter library contributes to a minimal firmware image that
  initialises one filter and updates it in a loop, linked with our start-up, newlib-nano and
  ``--gc-sections``, attributed per input object from the linker map: attica's per-filter images of
  tests/c/att_m4f_image.c against libattica.a, the peers' ``-DATT_PEER_IMAGE`` images of their
  drivers against their objects (lib<peer>.a, built from the sdists by
  :mod:`attica_dev.peer_sources`). What newlib, libm, libgcc and libstdc++ add (memcpy, sinf, powf,
  atan2f, soft-float double helpers...) is a column of its own;
- stack: the deepest update measured on the target with the same painted-stack probe and the same
  inputs for both (tests/c/att_bench_common.h: att_bench ``KIND N stack`` through att_filter_step,
  the peers' drivers through att_peer_step), 1000 steps;

then the ratios attica / peer for each pair of filters with the same inputs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from attica_dev import cross, cycles, peer_sources
from attica_dev.boards import BOARDS
from attica_dev.footprint import IMAGES, OUT, link_image, map_sizes

BOARDS_COMPARED = ("m4f", "m7", "m33")
OPTS = ("-Os", "-O2")
STACK_STEPS = 1000
ATTICA_IMAGES = {"ars": IMAGES["ars"], "kf": IMAGES["kf"], "ekf": IMAGES["ekf"], "mars": IMAGES["mars"]}
"""attica's compared filters and their ATT_IMAGE numbers."""


@dataclass
class Entry:
    """Sizes (bytes) and stack of one filter on one board at one level (None: not measured)."""

    text: int | None = None
    libc: int | None = None
    stack: int | None = None


def _stack(program: Path, board: str, kind: str) -> int:
    out = cross.run_checked([*BOARDS[board].prefix, str(program), kind, str(STACK_STEPS), "stack"], 300)
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[0] == "stack" and parts[1] == kind:
            return int(parts[2])
    raise cross.CrossError(f"{program}: no stack line for {kind}:\n{out}")


def measure(board: str, opt: str, out: Path, notes: list[str]) -> dict[str, Entry]:
    """The entries of attica's filters and of the peers on ``board`` at ``opt``."""
    from attica_dev import footprint

    res: dict[str, Entry] = {}
    wd = out / "peers-beside" / f"{board}{opt}"
    lib, _ = footprint.library(opt, wd, board)
    bench = cross.TARGETS[board].build([cycles.BENCH_SOURCE], opt, "att_bench.elf", wd / "bench")
    for kind, image in ATTICA_IMAGES.items():
        _, map_file = link_image(kind, image, lib, opt, wd / "images", board)
        s = map_sizes(map_file)
        res[kind] = Entry(s.attica.text, s.libc.text, _stack(bench, board, kind))
    tc = peer_sources.board_toolchain(board)
    for name, plib in peer_sources.LIBRARIES.items():
        try:
            prog = peer_sources.build(plib, tc, opt, wd / "peers").program
            for k in plib.kinds:
                img = peer_sources.build(plib, tc, opt, wd / "peers", image=k.axes)
                s = map_sizes(
                    img.program.with_suffix(".map"), f"lib{plib.name.lower()}", {o.stem for o in img.objects}
                )
                res[k.name] = Entry(s.attica.text, s.libc.text, _stack(prog, board, k.name))
        except (peer_sources.PeerUnavailableError, cross.CrossError) as e:
            notes.append(f"{name} on {board} {opt}: {e}")
            for k in plib.kinds:
                res[k.name] = Entry()
    return res


def _total(e: Entry) -> int | None:
    return None if e.text is None or e.libc is None else e.text + e.libc


def _v(x: int | None) -> str:
    return "n/a" if x is None else f"{x:,}"


def _r(a: int | None, b: int | None) -> str:
    return "n/a" if a is None or b is None or b == 0 else f"{a / b:.2f}"


def report(boards: Sequence[str] = BOARDS_COMPARED, opts: Sequence[str] = OPTS, out: Path = OUT) -> str:
    """The tables of attica beside the peers, one per board."""
    notes: list[str] = []
    lines = [
        "attica beside the peers: library .text in a minimal image (init + update in a loop, own API, "
        "--gc-sections; + libc = newlib / libm / libgcc / libstdc++ pulled in) and the deepest update "
        f"measured on the target (painted stack, {STACK_STEPS} steps of the att_bench inputs; attica through "
        "att_filter_step, peers through att_peer_step). Peers built from their sdists with the same flags."
    ]
    labels = list(ATTICA_IMAGES) + list(peer_sources.KINDS)
    for board in boards:
        if cross.TARGETS[board].missing():
            lines.append(f"{board}: skipped, missing {cross.install_hint(cross.TARGETS[board].missing())}")
            continue
        data = {opt: measure(board, opt, out, notes) for opt in opts}
        headers = [f"filter ({BOARDS[board].core})"]
        headers += [f".text {o}" for o in opts] + [f"+libc {o}" for o in opts] + [f"stack {o}" for o in opts]
        rows = []
        for label in labels:
            e = {o: data[o][label] for o in opts}
            name = label if label in ATTICA_IMAGES else f"{label} ({peer_sources.KINDS[label][0].label})"
            rows.append(
                [name]
                + [_v(e[o].text) for o in opts]
                + [_v(e[o].libc) for o in opts]
                + [_v(e[o].stack) for o in opts]
            )
        lines += ["", cross._table(headers, rows)]
        rheaders = ["attica / peer"] + [f".text {o}" for o in opts]
        rheaders += [f".text+libc {o}" for o in opts] + [f"stack {o}" for o in opts]
        rrows = []
        for a, p in cycles.pairs([*cycles.attica_rows(), *cycles.peer_rows()]):
            if a.label not in ATTICA_IMAGES:
                continue
            ea = {o: data[o][a.label] for o in opts}
            ep = {o: data[o][p.label] for o in opts}
            row = [f"{a.label} / {p.label}"]
            row += [_r(ea[o].text, ep[o].text) for o in opts]
            row += [_r(_total(ea[o]), _total(ep[o])) for o in opts]
            row += [_r(ea[o].stack, ep[o].stack) for o in opts]
            rrows.append(row)
        lines.append(cross._table(rheaders, rrows))
    lines += [f"note: {n}" for n in notes]
    return "\n".join(lines)

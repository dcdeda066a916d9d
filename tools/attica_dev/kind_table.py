"""The "choose a kind" table of docs/firmware-quickstart.md, computed: flash, RAM, instructions, accuracy.

``python -m attica_dev.kind_table [--update]`` (``make docs-figures``) computes for every filter kind:

- flash: the library .text of a Cortex-M4F image that runs the kind alone through att_filter.h (the
  build configuration with only that kind and no stages; -Os, newlib-nano, ``--gc-sections``; the
  footprint image 13 of :mod:`attica_dev.footprint`);
- RAM: ``sizeof(att_filter_t)`` in that configuration (the filter's whole state);
- instructions per update: att_filter_step on the M4F at -O2, mean over :data:`cycles.BENCH_STEPS`
  steps of tests/c/att_bench.c, counted in a QEMU trace (:mod:`attica_dev.cycles`);
- accuracy: the BROAD RMSE in degrees over the trials in ../shared/data/broad with the kind's defaults
  (inclination for 6-axis filters, total error for 9-axis ones; ``attica eval``'s figures, in sample:
  the defaults were chosen on these trials, see docs/accuracy.md for leave-one-out and other data).

With ``--update`` it rewrites the table between ``<!-- kind-table -->`` and ``<!-- /kind-table -->``
in docs/firmware-quickstart.md, and the quickstart node's size (:mod:`attica_dev.app_size`) between
``<!-- node-size -->`` and ``<!-- /node-size -->``; tests/test_quickstart.py recomputes the flash, RAM
and accuracy columns and the node's size and compares.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from attica import _build
from attica.kinds import KINDS, KindInfo
from attica_dev import cycles, footprint

ROOT = _build.ROOT
DOC = ROOT / "docs" / "firmware-quickstart.md"
BROAD = ROOT.parent / "shared" / "data" / "broad"
OUT = ROOT / "build" / "firmware" / "kind_table"
BEGIN, END = "<!-- kind-table -->", "<!-- /kind-table -->"
NODE_BEGIN, NODE_END = "<!-- node-size -->", "<!-- /node-size -->"


@dataclass
class KindRow:
    """One kind's figures (None: not measured)."""

    kind: KindInfo
    text: int
    ram: int
    instructions: float | None = None
    accuracy: dict[str, float] | None = None
    """'6-axis' / '9-axis' -> RMSE in degrees."""


def sizes(kinds: Sequence[KindInfo] = KINDS, out: Path = OUT) -> dict[str, tuple[int, int]]:
    """Label -> (library .text of the kind's image, sizeof att_filter_t), M4F -Os, the kind alone."""
    configs = {k.label: (footprint.only(k.kind.name, calib=False), k.kind.name, 13) for k in kinds}
    return {
        c.name: (c.sizes.attica.text, c.types["att_filter_t"])
        for c in footprint.config_sizes("-Os", out, configs=configs)
    }


def instructions(out: Path = OUT) -> dict[str, float]:
    """Label -> mean instructions per att_filter_step on the M4F at -O2."""
    counts = cycles.Counts()
    config: cycles.Config = ("m4f", "-O2")
    cycles.count_cortex(config, cycles.attica_rows(), cycles.BENCH_STEPS, out / "cycles", counts)
    result = {}
    for k in KINDS:
        mean = cycles._mean(counts.cortex.get((config, k.label)))
        if mean is None:
            raise footprint.FootprintError(f"no instruction count for {k.label}: {counts.notes}")
        result[k.label] = mean
    return result


def accuracy(data: Path = BROAD) -> dict[str, dict[str, float]]:
    """Label -> {'6-axis' or '9-axis': BROAD RMSE, deg} with the defaults (mekf both ways)."""
    from attica.evaluate import attica_method, load_trials, run_methods

    methods = []
    for k in KINDS:
        methods.append(attica_method(k.kind))
        if k.label == "mekf":
            methods.append(attica_method(k.kind, variant="mekf6"))
    report = run_methods(methods, load_trials(data), progress=False)
    result: dict[str, dict[str, float]] = {}
    for r in report.results:
        label = "mekf" if r.method.name == "mekf6" else r.method.name
        axes = "9-axis" if r.method.nine_axis else "6-axis"
        result.setdefault(label, {})[axes] = float(r.mean(r.method.score_metric))
    return result


def rows(with_instructions: bool = True, data: Path | None = BROAD) -> list[KindRow]:
    """Every kind's figures."""
    sz = sizes()
    ins = instructions() if with_instructions else {}
    acc = accuracy(data) if data is not None else {}
    return [KindRow(k, *sz[k.label], ins.get(k.label), acc.get(k.label)) for k in KINDS]


def _acc(k: KindRow) -> str:
    if not k.accuracy:
        return "n/a"
    if k.kind.baseline:
        return "baseline: " + ", ".join(f"{v:.2f} ({a})" for a, v in sorted(k.accuracy.items()))
    return " / ".join(f"{v:.2f} ({a})" for a, v in sorted(k.accuracy.items()))


def table(rs: Sequence[KindRow]) -> str:
    """The Markdown table."""
    head = (
        "| kind | axes | flash (.text, B) | RAM (att_filter_t, B) | instructions per update | "
        "BROAD RMSE, deg |\n|---|---|---:|---:|---:|---|\n"
    )
    lines = []
    for r in rs:
        ins = "n/a" if r.instructions is None else f"{r.instructions:,.0f}"
        axes = "6 or 9" if r.kind.label == "mekf" else ("-" if r.kind.baseline else str(r.kind.axes()))
        lines.append(f"| {r.kind.label} | {axes} | {r.text:,} | {r.ram:,} | {ins} | {_acc(r)} |")
    return head + "\n".join(lines) + "\n"


def update(text: str, tbl: str, begin: str = BEGIN, end: str = END) -> str:
    """``text`` with what is between the markers ``begin`` and ``end`` replaced by ``tbl``."""
    pattern = re.compile(re.escape(begin) + r"\n.*?" + re.escape(end), re.S)
    if not pattern.search(text):
        raise ValueError(f"{DOC.name} has no {begin} ... {end} section")
    return pattern.sub(lambda _: f"{begin}\n{tbl}{end}", text)


def node_block(report: str) -> str:
    """The node-size section: :func:`attica_dev.app_size.report` as a preformatted block."""
    return f"```\n{report}\n```\n"


def documented_node() -> str:
    """The node-size section of docs/firmware-quickstart.md as written."""
    text = DOC.read_text()
    return text[text.index(NODE_BEGIN) + len(NODE_BEGIN) + 1 : text.index(NODE_END)]


def documented() -> dict[str, list[str]]:
    """The cells of the table in docs/firmware-quickstart.md: label -> the row's cells."""
    text = DOC.read_text()
    body = text[text.index(BEGIN) : text.index(END)]
    out = {}
    for line in body.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 6 and cells[0] in {k.label for k in KINDS}:
            out[cells[0]] = cells
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m attica_dev.kind_table``."""
    p = argparse.ArgumentParser(prog="python -m attica_dev.kind_table", description=__doc__.split("\n")[0])
    p.add_argument("--update", action="store_true", help=f"rewrite the table in {DOC.relative_to(ROOT)}")
    p.add_argument("--no-instructions", action="store_true", help="skip the QEMU trace (n/a)")
    args = p.parse_args(argv)
    from attica_dev import app_size

    tbl = table(rows(not args.no_instructions, BROAD if BROAD.is_dir() else None))
    node = node_block(app_size.report(app_size.measure()))
    print(tbl + node, end="")
    if args.update:
        DOC.write_text(update(update(DOC.read_text(), tbl), node, NODE_BEGIN, NODE_END))
        print(f"written to {DOC.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Size of the quickstart's CAN node application (examples/c/can_node) on the Cortex-M4F.

The application is built as a user builds it: its own Makefile through firmware/attica.mk, its own
configuration header (my_attica_config.h: ARS only, no stages, classic frames, rings of 8),
arm-none-eabi-gcc -Os, newlib-nano, ``--gc-sections``, the bxCAN port and attica's start-up. The linker
map attributes every input section: the library (libattica.a), the port (bxCAN HAL, start-up,
floating-point environment), the application's own objects, the C library.

Targets of issue 22: library .text <= 12 KiB (must: 16 KiB); RAM (att_node_t and all static data of
the library, the port and the application) <= 2 KiB. ``make footprint`` prints the table; the test
tests/test_quickstart.py checks the targets.
"""

from __future__ import annotations

import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

from attica import _build
from attica_dev.footprint import FootprintError, Sizes, map_sizes

ROOT = _build.ROOT
APP = ROOT / "examples" / "c" / "can_node"
OUT = ROOT / "build" / "firmware" / "can_node"
TARGETS = {"text": 12 * 1024, "text_must": 16 * 1024, "ram": 2 * 1024}
"""Library .text (goal and limit) and RAM of the application, bytes."""
PORT_OBJECTS = {"att_can_hal", "startup", "att_fpenv"}


@dataclass
class AppSizes:
    """The application's image by origin (bytes)."""

    library: Sizes
    port: Sizes
    app: Sizes
    libc: Sizes
    elf: Path

    @property
    def ram(self) -> int:
        """.data + .bss of the library, the port and the application (the stack not included)."""
        return sum(s.data + s.bss for s in (self.library, self.port, self.app))


def build(out: Path = OUT) -> Path:
    """Build the application with its Makefile; return the linker map."""
    if shutil.which("arm-none-eabi-gcc") is None:
        raise FootprintError("arm-none-eabi-gcc is not installed (apt-get install gcc-arm-none-eabi)")
    proc = subprocess.run(
        ["make", "-s", "-B", "-f", str(APP / "Makefile"), f"BUILD={out}"],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    if proc.returncode != 0:
        raise FootprintError(f"examples/c/can_node does not build:\n{proc.stdout}{proc.stderr}")
    return out / "can_node.map"


def measure(out: Path = OUT) -> AppSizes:
    """Build and attribute the application's image."""
    sizes = map_sizes(build(out))
    port, app = Sizes(), Sizes()
    for origin, s in sizes.other_objects.items():
        obj = Path(origin)
        if obj.parent.name == "ports" and obj.stem in PORT_OBJECTS:
            target = port
        elif obj.parent == out:
            target = app
        else:
            continue
        target.text += s.text
        target.data += s.data
        target.bss += s.bss
    return AppSizes(sizes.attica, port, app, sizes.libc, out / "can_node.elf")


def report(s: AppSizes) -> str:
    """The table of ``make footprint``."""
    rows = [
        ("attica library", s.library),
        ("port (bxCAN, start-up, fpenv)", s.port),
        ("application (main.c, board.c)", s.app),
        ("C library (newlib-nano, libgcc)", s.libc),
    ]
    lines = [
        "The quickstart's CAN node (examples/c/can_node: ARS only, no stages, classic frames, rings of 8; "
        "M4F -Os, --gc-sections):",
        f"{'':34} {'.text':>7} {'.data':>6} {'.bss':>6}",
    ]
    lines += [f"{name:34} {v.text:>7,} {v.data:>6,} {v.bss:>6,}" for name, v in rows]
    lines.append(
        f"library .text {s.library.text:,} B (goal <= {TARGETS['text']:,}, limit {TARGETS['text_must']:,}); "
        f"RAM of library, port and application {s.ram:,} B (goal <= {TARGETS['ram']:,})"
    )
    return "\n".join(lines)

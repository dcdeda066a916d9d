"""The Cortex-M boards attica runs on under QEMU: code generation, start-up, linker script, machine.

Every board uses the same start-up (firmware/ports/cortex_m/startup.c: vector table, .data/.bss, FPU
on with FPSCR and FPDSCR in IEEE mode and checked by att_fpenv.c, when the core has one) and semihosting glue
(semihost.c), its own linker script, and runs under ``qemu-system-arm`` through
firmware/ports/cortex_m/qemu-cortex-m.sh:

=======  ==============================  ===========================================  ===============
board    core (QEMU machine)             code generation                              linker script
=======  ==============================  ===========================================  ===============
m4f      Cortex-M4F (mps2-an386)         ``-mcpu=cortex-m4 -mfpu=fpv4-sp-d16``        mps2_an386.ld
m7       Cortex-M7 (mps2-an500)          ``-mcpu=cortex-m7 -mfpu=fpv5-d16``           mps2_an500.ld
m33      Cortex-M33 (mps2-an505)         ``-mcpu=cortex-m33 -mfpu=fpv5-sp-d16``       mps2_an505.ld
m0plus   Cortex-M0+ (microbit's M0)      ``-mcpu=cortex-m0plus -mfloat-abi=soft``     microbit.ld
=======  ==============================  ===========================================  ===============

(all ``-mthumb``; the FPU boards ``-mfloat-abi=hard``). The M7 gets the double-precision FPv5 of most
M7 parts (STM32F7/H7): attica uses single precision only, but a peer with ``double`` state runs it in
hardware there. QEMU has no Cortex-M0+ model; the micro:bit's Cortex-M0 executes the same ARMv6-M
instruction set. The micro:bit has 16 KiB of RAM: its test images use newlib-nano, a 512-byte
command line and at most :attr:`CortexM.max_streams` filters at once.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from attica import _build

PORT = _build.FIRMWARE / "ports" / "cortex_m"
QEMU_SCRIPT = PORT / "qemu-cortex-m.sh"
STARTUP_SOURCES = (PORT / "startup.c", PORT / "att_fpenv.c")
"""The start-up of every board image: vector table and reset handler, and the floating-point environment
it sets and checks (att_fpenv.c, a file of its own so that a vendor start-up can link it alone)."""
PORT_SOURCES = (*STARTUP_SOURCES, PORT / "semihost.c")
"""The sources of a semihosted test image: the start-up and the semihosting glue."""
SECTIONS = ("-ffunction-sections", "-fdata-sections")


@dataclass(frozen=True)
class CortexM:
    """A Cortex-M core on a QEMU board."""

    name: str
    """Short name (``m4f``, ``m7``, ``m33``, ``m0plus``): the board argument of qemu-cortex-m.sh."""
    core: str
    """Human name of the core, e.g. ``Cortex-M4F``."""
    machine: str
    """QEMU machine (``-M``)."""
    qemu_cpu: str
    """QEMU CPU model (``-cpu``)."""
    cpu: tuple[str, ...]
    """Code generation flags of every object built for the board."""
    linker_script: str
    """File name under firmware/ports/cortex_m."""
    fpu: bool
    """The core has a (single-precision) FPU: the start-up sets and checks FPSCR."""
    specs: tuple[str, ...] = ("--specs=rdimon.specs",)
    """C library of test images: newlib (+ nano) with semihosting."""
    defines: tuple[str, ...] = ()
    """More -D flags for test images (semihost.c buffer sizes)."""
    ldflags: tuple[str, ...] = ()
    """Link flags after the objects."""
    max_streams: int = 0
    """Filters a golden run may keep alive at once (0: no limit; the micro:bit's RAM holds few)."""

    @property
    def script(self) -> Path:
        """The linker script."""
        return PORT / self.linker_script

    @property
    def link(self) -> tuple[str, ...]:
        """Link flags of test images: our start-up and linker script, newlib + semihosting."""
        return (*self.specs, "-nostartfiles", "-T", str(self.script), "-Wl,--gc-sections")

    @property
    def image_flags(self) -> tuple[str, ...]:
        """Compile + link flags of test images (port headers, semihosting stdio, sections, link)."""
        return ("-I", str(PORT), "-DATT_SEMIHOST_NEWLIB", *self.defines, *SECTIONS, *self.link)

    @property
    def prefix(self) -> tuple[str, ...]:
        """Command prefix that runs an image of this board (``prefix image args...``)."""
        return (str(QEMU_SCRIPT), self.name)

    def qemu_command(
        self, elf: Path, args: str = "", trace: Path | None = None, per_instruction: bool = False
    ) -> list[str]:
        """The qemu-system-arm command line for ``elf``; with ``trace``, log what executes there.

        The trace is ``-d in_asm,exec,nochain``: every translation block's instructions when it is
        translated, and a line per execution of a block (no chaining, so every execution is logged);
        with ``per_instruction``, ``-d exec,nochain -singlestep``: one line per executed instruction.
        """
        cmd = [
            "qemu-system-arm",
            "-M",
            self.machine,
            "-cpu",
            self.qemu_cpu,
            "-nographic",
            "-monitor",
            "none",
            "-serial",
            "null",
            "-semihosting-config",
            "enable=on,target=native",
            "-kernel",
            str(elf),
            "-append",
            args,
        ]
        if trace is not None and per_instruction:
            cmd += ["-d", "exec,nochain", "-singlestep", "-D", str(trace)]
        elif trace is not None:
            cmd += ["-d", "in_asm,exec,nochain", "-D", str(trace)]
        return cmd


BOARDS: dict[str, CortexM] = {
    "m4f": CortexM(
        "m4f",
        "Cortex-M4F",
        "mps2-an386",
        "cortex-m4",
        ("-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard"),
        "mps2_an386.ld",
        True,
    ),
    "m7": CortexM(
        "m7",
        "Cortex-M7",
        "mps2-an500",
        "cortex-m7",
        ("-mcpu=cortex-m7", "-mthumb", "-mfpu=fpv5-d16", "-mfloat-abi=hard"),
        "mps2_an500.ld",
        True,
    ),
    "m33": CortexM(
        "m33",
        "Cortex-M33",
        "mps2-an505",
        "cortex-m33",
        ("-mcpu=cortex-m33", "-mthumb", "-mfpu=fpv5-sp-d16", "-mfloat-abi=hard"),
        "mps2_an505.ld",
        True,
    ),
    "m0plus": CortexM(
        "m0plus",
        "Cortex-M0+",
        "microbit",
        "cortex-m0",
        ("-mcpu=cortex-m0plus", "-mthumb", "-mfloat-abi=soft"),
        "microbit.ld",
        False,
        specs=("--specs=nano.specs", "--specs=rdimon.specs"),
        defines=("-DATT_SH_CMDLINE_BYTES=512u",),
        ldflags=("-lm",),
        max_streams=10,
    ),
}
"""Every Cortex-M board, by name."""

FPU_BOARDS: Sequence[str] = tuple(n for n, b in BOARDS.items() if b.fpu)

"""Every C snippet of the docs and the public headers compiles, runs and prints what the text says.

Snippets are the ```c blocks of README.md, docs/*.md and examples/README.md, and the ``@code`` ..
``@endcode`` blocks of the public headers (firmware/include/attica, firmware/ports). Each is built
as a user builds it (``-std=c99 -Wall -Wextra -Werror -pedantic``) against the library compiled with
firmware/cflags.txt, around tests/c/att_doc_prelude.h: the IMU driver, CAN driver and ``publish`` the
snippets assume, simulated (a still board rolled by 0.3 rad). A ``{ ... }`` error branch becomes a call
that fails the run when it is taken.

Every snippet has an entry in SPECS saying how it runs (statements in ``main``; definitions whose
functions ``main`` calls; a configuration header; or, for code that touches a microcontroller's
registers, a compile-only build for the Cortex-M4F with the reason) and what its output must show. A
new snippet without an entry fails the test, and so does an entry whose snippet is gone.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

from attica import _build

from helpers import ROOT, need

PRELUDE_DIR = ROOT / "tests" / "c"
PORT = ROOT / "firmware" / "ports" / "cortex_m"
USER_FLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-Wno-unused-function", "-O1"]
ROLL = 0.3  # rad, the simulated board's roll (att_doc_prelude.h)


@dataclass(frozen=True)
class Snippet:
    """One C snippet: where it is (file, index among that file's snippets, line) and its text."""

    source: str
    index: int
    line: int
    text: str


@dataclass(frozen=True)
class Report:
    """The report line att_doc_prelude.h prints at exit."""

    samples: int
    published: int
    q: tuple[float, ...]
    v: tuple[float, ...]
    flags: int
    sent: int
    quat_frames: int


def _report(text: str) -> Report:
    m = re.search(
        r"^report samples=(\d+) published=(\d+) q=(\S+) v=(\S+) flags=0x([0-9a-f]+) sent=(\d+) "
        r"quat_frames=(\d+)$",
        text,
        re.M,
    )
    assert m is not None, text
    return Report(
        int(m.group(1)),
        int(m.group(2)),
        tuple(float(x) for x in m.group(3).split(",")),
        tuple(float(x) for x in m.group(4).split(",")),
        int(m.group(5), 16),
        int(m.group(6)),
        int(m.group(7)),
    )


@dataclass(frozen=True)
class Spec:
    """How a snippet runs and what it must print.

    mode: ``body`` (statements inside ``main``), ``file`` (definitions; ``main`` calls ``calls`` in
    order, the last one in a loop until the simulated samples end), ``config`` (a configuration header:
    the public headers compile with it), ``arm`` (compile only, Cortex-M4F, with the ports' headers:
    ``why`` says why it cannot run here).
    """

    mode: str
    check: Callable[[Report], None] | None = None
    calls: tuple[str, ...] = ()
    why: str = ""
    expect: str = ""
    """A regular expression the program's output must match (what the snippet's comment says it prints)."""
    sources: tuple[str, ...] = ()
    """More C files (paths from the checkout's root) the snippet is built with, their directories on the
    include path: an example's code the snippet uses (examples/c/persist/att_persist.c)."""


def _level_roll(r: Report, heading: bool = False) -> None:
    """The attitude of the still board: roll 0.3 rad, pitch 0 (and yaw 0 for a 9-axis filter)."""
    assert r.samples > 0 and r.published > 0, r
    assert abs(r.v[0] - ROLL) < 0.02 and abs(r.v[1]) < 0.02, r
    if heading:
        assert abs(r.v[2]) < 0.05, r
    assert r.flags & 0xC000 == 0, r  # not NOT_READY / BAD_ARG


def _node_outputs(r: Report) -> None:
    """The node stepped and sent output sets whose Euler angles show the roll."""
    assert r.sent > 0 and r.quat_frames > 0 and r.published > 0, r
    assert abs(r.v[0] - ROLL) < 0.02 and abs(r.v[1]) < 0.02, r


SPECS: dict[tuple[str, int], Spec] = {
    ("docs/integration.md", 0): Spec("config"),
    ("docs/integration.md", 1): Spec("file", _level_roll, ("attitude_init", "imu_sample_ready")),
    ("docs/integration.md", 2): Spec("file", None, ("attitude_init", "imu_sample_ready")),
    ("docs/integration.md", 3): Spec("arm", why="the Cortex-M FPU registers (CPACR, FPSCR, FPCCR)"),
    ("docs/integration.md", 4): Spec("arm", why="the bxCAN peripheral at its STM32 address"),
    ("docs/firmware-quickstart.md", 0): Spec("file", _level_roll, ("attitude_init", "imu_sample_ready")),
    ("docs/firmware-quickstart.md", 1): Spec("config"),
    ("docs/firmware-quickstart.md", 2): Spec("arm", why="the bxCAN peripheral at its STM32 address"),
    ("docs/firmware-quickstart.md", 3): Spec(
        "file",
        _node_outputs,
        ("node_start", "node_loop"),
        expect=r"^configuration: none \(save 0\)$",
        sources=("examples/c/persist/att_persist.c",),
    ),
    ("firmware/include/attica/att_filter.h", 0): Spec("body", _level_roll),
    ("firmware/include/attica/att_filter.h", 1): Spec("body", expect=r"^ars\.tau_acc_lp: \[0, 1e4\] s$"),
    ("firmware/include/attica/att_filter.h", 2): Spec(
        "body", expect=r"\Aars\.dt: \[1e-6, 1\] s(\nars\.\w+: [^\n]+){20}\Z"
    ),
    ("firmware/include/attica/att_calib.h", 0): Spec("body", expect=r"\A\Z"),  # accepted: prints nothing
    ("firmware/include/attica/att_node.h", 0): Spec("body", _node_outputs),
    ("firmware/include/attica/attica.h", 0): Spec("file"),
    ("firmware/ports/cortex_m/att_can_hal.h", 0): Spec(
        "arm", why="the bxCAN peripheral at its STM32 address"
    ),
    ("firmware/ports/cortex_m/att_fdcan_hal.h", 0): Spec(
        "arm", why="the FDCAN peripheral and its message RAM at their STM32G4 addresses"
    ),
}
"""Every snippet, by (file, index): how it runs and its check."""


def snippets() -> list[Snippet]:
    """Every C snippet of the docs and headers, in file order."""
    out: list[Snippet] = []
    md = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), ROOT / "examples" / "README.md"]
    for path in md:
        text = path.read_text()
        for i, m in enumerate(re.finditer(r"^```c\n(.*?)^```$", text, re.S | re.M)):
            line = text.count("\n", 0, m.start()) + 2
            out.append(Snippet(str(path.relative_to(ROOT)), i, line, m.group(1)))
    headers = sorted((ROOT / "firmware" / "include" / "attica").glob("*.h")) + sorted(
        (ROOT / "firmware" / "ports").rglob("*.h")
    )
    for path in headers:
        text = path.read_text()
        for i, m in enumerate(
            re.finditer(r"^ \* *@code(?:\{\.c\})?\n(.*?)^ \* *@endcode$", text, re.S | re.M)
        ):
            line = text.count("\n", 0, m.start()) + 2
            body = "\n".join(re.sub(r"^ \*( |$)", "", ln) for ln in m.group(1).splitlines())
            out.append(Snippet(str(path.relative_to(ROOT)), i, line, _dedent(body) + "\n"))
    return out


def _dedent(text: str) -> str:
    lines = text.splitlines()
    indent = min((len(ln) - len(ln.lstrip()) for ln in lines if ln.strip()), default=0)
    return "\n".join(ln[indent:] for ln in lines)


def _program(s: Snippet, spec: Spec) -> str:
    code = re.sub(r"\{\s*\.\.\.\s*\}", "{ att_doc_fail(__LINE__); }", s.text)
    head = f'#include "att_doc_prelude.h"\n#line {s.line} "{s.source}"\n'
    if spec.mode == "body":
        return f"{head}int main(void)\n{{\n{code}\nreturn 0;\n}}\n"
    calls = "".join(f"    {c}();\n" for c in spec.calls[:-1])
    last = f"    for (;;) {{\n        {spec.calls[-1]}();\n    }}\n" if spec.calls else ""
    protos = "".join(f"void {c}(void);\n" for c in spec.calls)
    return f"{protos}{head}{code}\nint main(void)\n{{\n{calls}{last}}}\n"


@pytest.fixture(scope="module")
def library(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """libattica.a for the host, compiled with firmware/cflags.txt (every kind and stage)."""
    need(shutil.which("cc") is not None and shutil.which("ar") is not None, "cc/ar are not installed")
    out = tmp_path_factory.mktemp("docs_c_lib")
    objs = [o for o in _build.compile_objects("cc", "-O2", out) if not o.stem.startswith("att_host")]
    lib = out / "libattica.a"
    subprocess.run(["ar", "rcs", str(lib), *map(str, objs)], check=True)
    return lib


def test_every_snippet_has_a_spec() -> None:
    found = {(s.source, s.index) for s in snippets()}
    assert found == set(SPECS), f"new: {sorted(found - set(SPECS))}; gone: {sorted(set(SPECS) - found)}"


@pytest.mark.parametrize("key", sorted(SPECS), ids=lambda k: f"{k[0]}#{k[1]}")
def test_snippet_compiles_and_runs(key: tuple[str, int], library: Path, tmp_path: Path) -> None:
    spec = SPECS[key]
    s = next(x for x in snippets() if (x.source, x.index) == key)
    src = tmp_path / "snippet.c"
    inc = ["-I", str(_build.INCLUDE), "-I", str(PRELUDE_DIR)]
    if spec.mode == "config":
        (tmp_path / "snippet_config.h").write_text(s.text)
        src.write_text('#include "attica/attica.h"\nint main(void) { return ATT_WITH_ARS ? 0 : 1; }\n')
        flags = ['-DATT_CONFIG_HEADER="snippet_config.h"', "-I", str(tmp_path)]
        subprocess.run(["cc", *USER_FLAGS, *flags, *inc, str(src), "-o", str(tmp_path / "x")], check=True)
        return
    if spec.mode == "arm":
        assert spec.why, key
        need(shutil.which("arm-none-eabi-gcc") is not None, "arm-none-eabi-gcc is not installed")
        code = re.sub(r"\{\s*\.\.\.\s*\}", "{ att_doc_fail(__LINE__); }", s.text)
        src.write_text(
            '#include "attica/attica.h"\n#include "att_can_hal.h"\n#include "att_fdcan_hal.h"\n'
            '#include "att_port.h"\n'
            "void att_doc_fail(int line);\nvoid snippet(void);\nbool imu_sample_is_ready(void);\n"
            "void imu_read(att_sample_t *in);\n"
            f'#line {s.line} "{s.source}"\nvoid snippet(void)\n{{\n{code}\n}}\n'
        )
        cpu = ["-mcpu=cortex-m4", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv4-sp-d16"]
        cmd = [
            "arm-none-eabi-gcc",
            *USER_FLAGS,
            *cpu,
            *inc,
            "-I",
            str(PORT),
            "-c",
            str(src),
            "-o",
            str(tmp_path / "x.o"),
        ]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr
        return
    src.write_text(_program(s, spec))
    exe = tmp_path / "snippet"
    extra = [ROOT / x for x in spec.sources]
    for path in extra:
        inc += ["-I", str(path.parent)]
    proc = subprocess.run(
        ["cc", *USER_FLAGS, *inc, str(src), *map(str, extra), str(library), "-o", str(exe)],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, f"{s.source}:{s.line}: the snippet does not compile\n{proc.stderr}"
    run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, f"{s.source}:{s.line}: exit {run.returncode}\n{run.stdout}{run.stderr}"
    if spec.check is not None:
        spec.check(_report(run.stdout))
    if spec.expect:
        shown = "\n".join(ln for ln in run.stdout.splitlines() if not ln.startswith("report "))
        assert re.search(spec.expect, shown, re.M), f"{s.source}:{s.line}: printed {shown!r}"

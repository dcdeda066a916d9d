"""The C test programs under ASan+UBSan, the firmware under more compilers' eyes (docs/robustness.md).

- The golden runner (tests/c/att_golden.c) built with clang -fsanitize=address,undefined: every math
  function and every filter kind (defaults and variants) on the adversarial golden inputs, still bit
  for bit equal to the reference; and the same runner built with gcc -m32 (i386, SSE2 arithmetic).
- The CAN HAL tests (tests/c/att_can_hal_test.c: bxCAN, tests/c/att_fdcan_hal_test.c: FDCAN / M_CAN;
  frames through a real node), the flash persistence example's test (examples/c/persist) and
  attica-node (firmware/ports/linux) under ASan+UBSan.
- The firmware and the Cortex-M CAN HALs compile warning-free with -std=c11 (gcc and clang) and with
  clang -Weverything minus WEVERYTHING_OFF, each entry justified there.
- cppcheck and clang-tidy report nothing on the files this baseline covers (ANALYSED).
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from attica_dev import cross, golden

from helpers import ROOT, need

SAN = ("-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer", "-g")
FW = sorted((ROOT / "firmware" / "src").rglob("*.c"))
INC = ROOT / "firmware" / "include"

# clang -Weverything minus these, each for a reason:
WEVERYTHING_OFF = {
    "-Wno-padded": "struct padding is reported for every public struct; layouts are part of the ABI",
    "-Wno-declaration-after-statement": "C99 allows it (clang 14 warns about it as a C89 rule)",
    "-Wno-unknown-pragmas": "none expected; kept for the STDC FP_CONTRACT pragma on old clangs",
    "-Wno-covered-switch-default": "defaults guard casts of out-of-range enum values from users",
    "-Wno-switch-enum": "switches on att_filter_kind_t list the kinds they handle; default covers the rest",
    "-Wno-unused-macros": "the generated DBC header defines every signal's constants",
    "-Wno-reserved-identifier": "the generated DBC code uses __attribute__-style names from cantools",
    "-Wno-float-equal": "exact comparisons are deliberate: a zero vector means 'no sample' (att_sensor.c)",
}

PORT = ROOT / "firmware" / "ports" / "cortex_m"
PERSIST = ROOT / "examples" / "c" / "persist"
CORTEX_M_PORTS = [PORT / "att_can_hal.c", PORT / "att_fdcan_hal.c", PORT / "att_fpenv.c"]
"""The Cortex-M port files that are plain C (startup.c and semihost.c are ARM assembly glue): the two CAN
HALs and the floating-point environment (its no-FPU branch on the host)."""
ANALYSED = [
    *FW,
    ROOT / "firmware" / "ports" / "linux" / "att_node_linux.c",
    *CORTEX_M_PORTS,
    PERSIST / "att_persist.c",
]
"""The files of the static-analysis baseline: every firmware source (filters, math, calib, CAN codec
and its generated code, node), the Linux port, the Cortex-M CAN HALs and floating-point environment,
and the flash persistence example. Clean, with one inline suppression: cppcheck
uninitvar at att_core.h att_i_pd6 (a false positive: d[k] and l[j][k] are read only for k < j,
written by the earlier passes of the same loop). cppcheck runs with ATT_CONFIG_HEADER undefined (it
would try the configuration with a user's header it does not have)."""


def _have(*tools: str) -> None:
    missing = [t for t in tools if shutil.which(t) is None]
    need(not missing, f"not installed: {', '.join(missing)} (host/tools/install-system-deps.sh)")


@pytest.fixture(scope="module")
def golden_inputs(
    tmp_path_factory: pytest.TempPathFactory,
) -> tuple[Path, cross.MathData, list[cross.FilterCase]]:
    work = tmp_path_factory.mktemp("san")
    data = cross.math_data(work, rows=20_000)
    cases = cross.synthetic_cases(steps=200, streams=50)
    return work, data, cases


def _golden(target: cross.Target, work: Path, data: cross.MathData, cases: list[cross.FilterCase]) -> None:
    runner = target.build([golden.RUNNER_SOURCE], "-O1", "att_golden", work / target.name)
    (work / f"{target.name}-math").mkdir(exist_ok=True)
    res = cross.compare_math(runner, (), data, work / f"{target.name}-math")
    want = {c.name: cross.reference_case(c) for c in cases}
    (work / f"{target.name}-in").mkdir(exist_ok=True)
    (work / f"{target.name}-filters").mkdir(exist_ok=True)
    (work / f"{target.name}-math").mkdir(exist_ok=True)
    files = cross.write_case_inputs(cases, work / f"{target.name}-in")
    res += cross.compare_filters(runner, (), cases, want, files, work / f"{target.name}-filters")
    bad = [f"{r.what}: {r.differ} of {r.compared} differ; {r.detail}" for r in res if not r.ok]
    assert not bad, "\n".join(bad)
    print(f"{target.name}: {sum(r.compared for r in res)} values compared, all bit-exact")


def test_golden_runner_asan_ubsan(golden_inputs: tuple[Path, cross.MathData, list[cross.FilterCase]]) -> None:
    _have("clang")
    t = cross.Target("x86_64-asan", "x86-64, clang, ASan+UBSan", "clang", flags=SAN, ldflags=("-lm",))
    _golden(t, *golden_inputs)


def test_golden_runner_m32(
    golden_inputs: tuple[Path, cross.MathData, list[cross.FilterCase]], tmp_path: Path
) -> None:
    """i386 with SSE2 arithmetic (x87 would break FLT_EVAL_METHOD == 0, which att_fp.h refuses).

    Needs libc6-dev-i386 and lib32gcc (not gcc-multilib, which conflicts with the cross compilers on
    Debian): the one header gcc-multilib would add, /usr/include/asm, is given here.
    """
    _have("gcc")
    inc = tmp_path / "m32-include"
    inc.mkdir()
    (inc / "asm").symlink_to("/usr/include/x86_64-linux-gnu/asm")
    cpu = ("-m32", "-msse2", "-mfpmath=sse", "-idirafter", str(inc))
    probe = subprocess.run(
        ["gcc", *cpu, "-x", "c", "-", "-o", str(tmp_path / "probe"), "-lm"],
        input="#include <errno.h>\n#include <math.h>\nint main(void){return 0;}\n",
        capture_output=True,
        text=True,
    )
    need(
        probe.returncode == 0,
        f"gcc -m32 cannot build (libc6-dev-i386, lib32gcc-12-dev): {probe.stderr[-300:]}",
    )
    t = cross.Target("i386-sse2", "i386, gcc -m32 -msse2 -mfpmath=sse", "gcc", cpu=cpu, ldflags=("-lm",))
    _golden(t, *golden_inputs)


@pytest.mark.parametrize(
    "sources",
    [
        (PORT / "att_can_hal.c", ROOT / "tests" / "c" / "att_can_hal_test.c"),
        (PORT / "att_fdcan_hal.c", ROOT / "tests" / "c" / "att_fdcan_hal_test.c"),
        (PERSIST / "att_persist.c", PERSIST / "att_persist_test.c"),
    ],
    ids=["bxcan", "fdcan", "persist"],
)
def test_port_tests_asan_ubsan(sources: tuple[Path, Path], tmp_path: Path) -> None:
    _have("clang")
    prog = golden.build_program(
        list(sources),
        "clang",
        "-O1",
        ["-I", str(PORT), "-I", str(sources[0].parent), *SAN],
        sources[1].stem,
        tmp_path,
    )
    r = subprocess.run([str(prog)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "0 failure(s)" in r.stdout, r.stdout[-2000:] + r.stderr[-3000:]


def test_attica_node_asan_ubsan(tmp_path: Path) -> None:
    """The Linux port under ASan+UBSan: argument parsing and every error path without a CAN bus."""
    _have("clang")
    exe = tmp_path / "attica-node"
    flags = [*(ROOT / "firmware" / "cflags.txt").read_text().split(), "-O1", *SAN, "-I", str(INC)]
    port = ROOT / "firmware" / "ports" / "linux" / "att_node_linux.c"
    subprocess.run(
        ["clang", *flags, "-std=gnu99", "-c", str(port), "-o", str(tmp_path / "port.o")], check=True
    )
    subprocess.run(["clang", *flags, *map(str, FW), str(tmp_path / "port.o"), "-o", str(exe)], check=True)
    for args, rc in (
        (["--help"], 0),
        (["--channel", "vcan0", "--filter", "nosuch"], 2),
        (["--channel", "vcan0", "--rate", "5000"], 2),
        (["--channel", "vcan0", "--rate", "abc"], 2),
        (["--channel", "x" * 40], 2),
        (["--channel", "nosuchcan9"], 1),
        (["--channel", "vcan0", "--count", "-1"], 2),
        (["--channel"], 2),
    ):
        r = subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=30)
        assert r.returncode == rc and "Sanitizer" not in r.stderr, (args, r.returncode, r.stderr)


@pytest.mark.parametrize("cc", ["gcc", "clang"])
def test_firmware_c11(cc: str, tmp_path: Path) -> None:
    _have(cc)
    flags = [f for f in (ROOT / "firmware" / "cflags.txt").read_text().split() if f != "-std=c99"]
    for src in [*FW, *CORTEX_M_PORTS]:
        r = subprocess.run(
            [
                cc,
                "-std=c11",
                *flags,
                "-O2",
                "-I",
                str(INC),
                "-I",
                str(PORT),
                "-c",
                str(src),
                "-o",
                str(tmp_path / "x.o"),
            ],
            capture_output=True,
            text=True,
        )
        assert r.returncode == 0 and not r.stderr.strip(), (src.name, r.stderr)


def test_firmware_clang_weverything(tmp_path: Path) -> None:
    _have("clang")
    for src in [*FW, *CORTEX_M_PORTS]:
        r = subprocess.run(
            [
                "clang",
                "-std=c99",
                "-Weverything",
                "-Werror",
                *WEVERYTHING_OFF,
                "-ffp-contract=off",
                "-O2",
                "-I",
                str(INC),
                "-I",
                str(PORT),
                "-c",
                str(src),
                "-o",
                str(tmp_path / "x.o"),
            ],
            capture_output=True,
            text=True,
        )
        assert r.returncode == 0, (src.name, r.stderr[-3000:])


def test_cppcheck_clean() -> None:
    _have("cppcheck")
    r = subprocess.run(
        [
            "cppcheck",
            "--enable=warning,portability,performance",
            "--std=c99",
            "--error-exitcode=1",
            "--quiet",
            "--inline-suppr",
            "-UATT_CONFIG_HEADER",
            "-I",
            str(INC),
            "-I",
            str(PORT),
            "-I",
            str(PERSIST),
            *map(str, ANALYSED),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stdout + r.stderr


def test_clang_tidy_clean() -> None:
    _have("clang-tidy")
    checks = "clang-analyzer-*,bugprone-*,-bugprone-easily-swappable-parameters,-bugprone-reserved-identifier"
    r = subprocess.run(
        [
            "clang-tidy",
            f"--checks=-*,{checks}",
            "--warnings-as-errors=*",
            "--quiet",
            *map(str, ANALYSED),
            "--",
            "-std=gnu99",  # the Linux port needs the GNU socket definitions; the core is C99 anyway
            "-I",
            str(INC),
            "-I",
            str(PORT),
            "-I",
            str(PERSIST),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-2000:]

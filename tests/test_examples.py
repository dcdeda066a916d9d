"""examples/: the Python quickstart runs; the C main loop builds with add_subdirectory, with
find_package(attica) against an installed attica, and with firmware/attica.mk, all printing the
same bits; the umbrella header attica/attica.h holds the whole public API and compiles on its own; the
flash persistence example (examples/c/persist) keeps the node's configuration (kind, filter settings,
calibration) in two alternating flash slots over a reboot and survives a power cut at every byte of a save
and a flipped bit anywhere on RAM-backed fake flash pages, and compiles for the Cortex-M4F (also without
the calibration stages)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from attica import _build
from attica_dev import golden

from helpers import ROOT, need

EXAMPLES = ROOT / "examples"
INCLUDE = ROOT / "firmware" / "include" / "attica"


def _tool(name: str) -> None:
    from shutil import which

    need(which(name) is not None, f"{name} is not installed")


def test_python_quickstart_runs(tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT / "host")}
    proc = subprocess.run(
        [sys.executable, str(EXAMPLES / "python" / "quickstart.py")],
        capture_output=True,
        text=True,
        cwd=tmp_path,  # from another directory, as a user would
        env=env,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    out = proc.stdout
    assert "C and numpy reference bit-identical" in out and "inclination RMSE" in out
    assert "steps  q (w x y z)" in out  # the labelled table


def test_umbrella_header_has_every_public_header(tmp_path: Path) -> None:
    text = (INCLUDE / "attica.h").read_text()
    included = set(re.findall(r'#include "attica/(att_\w+\.h)"', text))
    public = {p.name for p in INCLUDE.glob("att_*.h")}
    assert included == public, f"attica.h misses {sorted(public - included)}"
    _tool("cc")
    src = tmp_path / "only_umbrella.c"
    src.write_text(
        '#include "attica/attica.h"\n'
        "int main(void) { att_filter_t f; att_filter_settings_t s;\n"
        "  if (att_filter_settings_default(ATT_FILTER_ARS, 0.01f, &s) != ATT_OK) return 1;\n"
        "  return att_filter_init(&f, ATT_FILTER_ARS, &s) == ATT_OK && ATT_VERSION_MAJOR >= 0 ? 0 : 1; }\n"
    )
    for std in ("-std=c99", "-std=c11"):
        proc = subprocess.run(
            [
                "cc",
                std,
                "-Wall",
                "-Wextra",
                "-Werror",
                "-pedantic",
                f"-I{ROOT / 'firmware' / 'include'}",
                "-fsyntax-only",
                str(src),
            ],
            capture_output=True,
            text=True,
        )
        assert proc.returncode == 0, proc.stderr


def _run(cmd: list[str], cwd: Path | None = None) -> str:
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=cwd, timeout=600)
    assert proc.returncode == 0, " ".join(cmd) + "\n" + proc.stdout + proc.stderr
    return proc.stdout


def _example_output(exe: Path) -> str:
    out = _run([str(exe)])
    assert re.match(r"^steps 1000 flags 0x[0-9a-f]{4} q( [0-9a-f]{8}){4} yaw ", out), out
    return out


def test_c_example_three_ways_same_bits(tmp_path: Path) -> None:
    _tool("cmake")
    _tool("cc")
    _tool("make")
    jobs = "2"
    # 1. add_subdirectory of the source tree
    sub = tmp_path / "sub"
    _run(["cmake", "-S", str(EXAMPLES / "c"), "-B", str(sub)])
    _run(["cmake", "--build", str(sub), "-j", jobs])
    via_subdir = _example_output(sub / "example")
    # 2. install attica, then find_package(attica) from a prefix
    fw, prefix = tmp_path / "fw", tmp_path / "prefix"
    _run(["cmake", "-S", str(ROOT / "firmware"), "-B", str(fw)])
    _run(["cmake", "--build", str(fw), "-j", jobs])
    _run(["cmake", "--install", str(fw), "--prefix", str(prefix)])
    assert (prefix / "include" / "attica" / "attica.h").is_file()
    assert list(prefix.glob("lib*/cmake/attica/attica-config.cmake"))
    pkg = tmp_path / "pkg"
    _run(
        [
            "cmake",
            "-S",
            str(EXAMPLES / "c"),
            "-B",
            str(pkg),
            "-DATTICA_EXAMPLE_FIND_PACKAGE=ON",
            f"-DCMAKE_PREFIX_PATH={prefix}",
        ]
    )
    _run(["cmake", "--build", str(pkg), "-j", jobs])
    via_package = _example_output(pkg / "example")
    # 3. plain make with firmware/attica.mk
    mk = tmp_path / "mk"
    _run(["make", "-f", str(EXAMPLES / "c" / "Makefile"), f"BUILD={mk}", "-j", jobs], cwd=ROOT)
    via_make = _example_output(mk / "example")
    assert via_subdir == via_package == via_make


PORT_FILES = (
    "att_can_hal.c",
    "att_can_hal.h",
    "att_fdcan_hal.c",
    "att_fdcan_hal.h",
    "att_fpenv.c",
    "att_port.h",
    "startup.c",
    "arm-none-eabi-m4f.cmake",
)
"""Port files a consumer needs from an installed attica (share/attica/ports/cortex_m)."""

PORT_CONSUMER_C = r"""
#include <stdio.h>
#include "att_can_hal.h"
#include "att_fdcan_hal.h"
#include "att_port.h"
int main(void)
{
    att_fdcan_timing_t t;
    static att_node_t node;
    att_node_settings_t s;
    uint32_t ids[ATT_NODE_RX_IDS_MAX];
    if (att_fdcan_hal_timing(160000000u, 500000u, 2000000u, &t) != ATT_OK ||
        att_node_settings_default(ATT_FILTER_ARS, 100.0f, &s) != ATT_OK ||
        att_node_init(&node, &s) != ATT_OK) {
        return 1;
    }
    att_port_fp_init();
    printf("btr %08lx nbtp %08lx dbtp %08lx tdcr %08lx g4 rx %lu fp %d ids %lu\n",
           (unsigned long)att_can_hal_btr(42000000u, 500000u), (unsigned long)t.nbtp, (unsigned long)t.dbtp,
           (unsigned long)t.tdcr, (unsigned long)att_fdcan_layout_g4.rx_fifo0_n, att_port_fp_ok() ? 1 : 0,
           (unsigned long)att_node_rx_ids(&node, ids));
    return att_fdcan_hal_receive(NULL) == 0u && att_can_hal_receive(NULL) == 0u ? 0 : 1;
}
"""

PORT_CONSUMER_CMAKE = """
cmake_minimum_required(VERSION 3.13)
project(port_consumer C)
option(CONSUMER_FIND_PACKAGE "installed attica" ON)
if(CONSUMER_FIND_PACKAGE)
  find_package(attica REQUIRED CONFIG)
else()
  set(ATTICA_CORTEX_M_BXCAN ON CACHE BOOL "" FORCE)
  set(ATTICA_CORTEX_M_FDCAN ON CACHE BOOL "" FORCE)
  set(ATTICA_CORTEX_M_FPENV ON CACHE BOOL "" FORCE)
  add_subdirectory(${ATTICA_FIRMWARE} attica)
endif()
add_executable(consumer main.c)
target_link_libraries(consumer PRIVATE attica::bxcan attica::fdcan attica::fpenv)
"""

PORT_CONSUMER_MK = """
include $(ATTICA_FIRMWARE)/attica.mk
CFLAGS += -std=c99 -Wall -Wextra -Werror $(ATTICA_INCLUDES) $(ATTICA_PORT_INCLUDES)
PORT_OBJS := $(ATTICA_BXCAN_OBJS) $(ATTICA_FDCAN_OBJS) $(ATTICA_FPENV_OBJS)
$(BUILD)/consumer: $(BUILD)/main.o $(PORT_OBJS) $(ATTICA_LIB)
\t$(CC) $(CFLAGS) $^ -o $@
$(BUILD)/main.o: $(SRC)/main.c
\t@mkdir -p $(@D)
\t$(CC) $(CFLAGS) -c $< -o $@
"""


def _port_consumer(tmp_path: Path) -> Path:
    src = tmp_path / "consumer"
    src.mkdir()
    (src / "main.c").write_text(PORT_CONSUMER_C)
    (src / "CMakeLists.txt").write_text(PORT_CONSUMER_CMAKE)
    (src / "consumer.mk").write_text(PORT_CONSUMER_MK)
    return src


def _consumer_output(exe: Path) -> str:
    out = _run([str(exe)])
    assert re.match(
        r"^btr 001a0005 nbtp [0-9a-f]{8} dbtp [0-9a-f]{8} tdcr 00003c00 g4 rx 3 fp 1 ids [45]$", out
    ), out
    return out


def test_ports_installed_and_usable(tmp_path: Path) -> None:
    """cmake --install ships the Cortex-M port (share/attica/ports/cortex_m: both CAN HALs, the
    floating-point environment, the start-up, the toolchain file); a consumer project finds it with
    find_package(attica) and links attica::bxcan, attica::fdcan and attica::fpenv (the port sources
    compiled in its build); the same project with add_subdirectory and the ATTICA_CORTEX_M_* options
    gives the same output."""
    _tool("cmake")
    _tool("cc")
    fw, prefix = tmp_path / "fw", tmp_path / "prefix"
    _run(["cmake", "-S", str(ROOT / "firmware"), "-B", str(fw)])
    _run(["cmake", "--build", str(fw), "-j", "2"])
    _run(["cmake", "--install", str(fw), "--prefix", str(prefix)])
    port = prefix / "share" / "attica" / "ports" / "cortex_m"
    missing = [f for f in PORT_FILES if not (port / f).is_file()]
    assert not missing, f"not installed: {missing}"
    for f in PORT_FILES:
        assert (port / f).read_bytes() == (ROOT / "firmware" / "ports" / "cortex_m" / f).read_bytes(), f
    src = _port_consumer(tmp_path)
    pkg = tmp_path / "pkg"
    _run(["cmake", "-S", str(src), "-B", str(pkg), f"-DCMAKE_PREFIX_PATH={prefix}"])
    _run(["cmake", "--build", str(pkg), "-j", "2"])
    via_package = _consumer_output(pkg / "consumer")
    sub = tmp_path / "sub"
    _run(
        [
            "cmake",
            "-S",
            str(src),
            "-B",
            str(sub),
            "-DCONSUMER_FIND_PACKAGE=OFF",
            f"-DATTICA_FIRMWARE={ROOT / 'firmware'}",
        ]
    )
    _run(["cmake", "--build", str(sub), "-j", "2"])
    assert (sub / "attica" / "libattica_fdcan.a").is_file() and (
        sub / "attica" / "libattica_fpenv.a"
    ).is_file()
    assert _consumer_output(sub / "consumer") == via_package


def test_ports_make_fragment(tmp_path: Path) -> None:
    """firmware/attica.mk reaches the port: ATTICA_PORT_INCLUDES and the HAL / floating-point
    environment objects (ATTICA_BXCAN_OBJS, ATTICA_FDCAN_OBJS, ATTICA_FPENV_OBJS), compiled with the
    library's strict flags, link into a consumer with ATTICA_LIB."""
    _tool("cc")
    _tool("make")
    src = _port_consumer(tmp_path)
    build = tmp_path / "mk"
    proc = subprocess.run(
        [
            "make",
            "-f",
            str(src / "consumer.mk"),
            f"ATTICA_FIRMWARE={ROOT / 'firmware'}",
            f"SRC={src}",
            f"BUILD={build}",
            f"ATTICA_BUILD={build / 'attica'}",
            "-j",
            "2",
            str(build / "consumer"),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "att_fdcan_hal.c" in proc.stdout and "-Werror" in proc.stdout  # strict flags on the port
    for obj in ("att_can_hal.o", "att_fdcan_hal.o", "att_fpenv.o"):
        assert (build / "attica" / "ports" / obj).is_file(), obj
    _consumer_output(build / "consumer")


PERSIST = EXAMPLES / "c" / "persist"


def test_persistence_example(tmp_path: Path) -> None:
    """examples/c/persist on the host with the strict firmware flags, against two fake flash pages: erased
    pages give the firmware's configuration; SET_CONVENTION, SET_GAIN, a calibration session, SELECT and
    SET_REMAP over CAN frames are saved (the node's hook, att_persist_poll) into alternating slots and loaded
    whole at the next start. A power cut before, during (11 points) and after every byte of the erase and
    programming of six saves, and every bit of both slots flipped: each reboot runs the old or the new
    configuration bit for bit, never a mix, and reports which (sequence number, slot, source new/old/none).
    Records of another version, refused by att_node_init, a wrong magic, the sequence wrap, unreadable or
    too small pages, NULL arguments."""
    _tool("cc")
    prog = golden.build_program(
        [PERSIST / "att_persist.c", PERSIST / "att_persist_test.c"],
        "cc",
        "-O2",
        ["-I", str(PERSIST)],
        "att_persist_test",
        tmp_path,
    )
    out = _run([str(prog)])
    print(out)
    assert "FAIL" not in out and out.rstrip().endswith("0 failure(s)")
    for case in (
        "erased pages: source none",
        "each change (SET_CONVENTION, SET_GAIN, a calibration session, SELECT, SET_REMAP) is saved",
        "the saves alternate between slot 0 and slot 1",
        "a power cut at every byte of 6 saves",
        "none with a mix",
        "each reboot reports which",
        "never reported as saved",
        "every bit of both slots flipped",
        "layout, not loaded",
        "att_node_init refuses",
        "across the wrap",
        "wrong magic: corrupt",
        "pages that cannot be read",
    ):
        assert case in out, case
    cuts = re.search(r"(\d+) reboots, (\d+) with the old configuration, (\d+) with the new one", out)
    assert cuts is not None and int(cuts[1]) > 6 * 377 and int(cuts[1]) == int(cuts[2]) + int(cuts[3]), out


def test_persistence_example_builds_for_m4f(tmp_path: Path) -> None:
    """The persistence example compiles for the Cortex-M4F with the strict flags and at most 1 KB of stack
    per function, needing nothing but att_node_init, att_node_set_persist and memcpy/memset/memcmp; also
    in a build without the calibration stages (ATT_WITH_CALIB 0)."""
    _tool("arm-none-eabi-gcc")
    _tool("arm-none-eabi-nm")
    obj = tmp_path / "att_persist.o"
    _run(
        [
            "arm-none-eabi-gcc",
            *_build.cflags(),
            "-Os",
            "-mcpu=cortex-m4",
            "-mthumb",
            "-mfpu=fpv4-sp-d16",
            "-mfloat-abi=hard",
            "-Wstack-usage=1024",
            "-I",
            str(ROOT / "firmware" / "include"),
            "-I",
            str(PERSIST),
            "-c",
            str(PERSIST / "att_persist.c"),
            "-o",
            str(obj),
        ]
    )
    undefined = {
        line.split()[-1] for line in _run(["arm-none-eabi-nm", "-u", str(obj)]).splitlines() if line.strip()
    }
    allowed = {"att_node_init", "att_node_set_persist"}
    assert undefined <= allowed | {"memcpy", "memset", "memcmp"}, undefined
    # without the calibration stages it keeps the kind and the filter settings (no hook to register)
    (tmp_path / "nocal.h").write_text("#define ATT_WITH_CALIB 0\n")
    _run(
        [
            "arm-none-eabi-gcc",
            *_build.cflags(),
            "-Os",
            "-mcpu=cortex-m4",
            "-mthumb",
            "-mfpu=fpv4-sp-d16",
            "-mfloat-abi=hard",
            "-Wstack-usage=1024",
            '-DATT_CONFIG_HEADER="nocal.h"',
            "-I",
            str(tmp_path),
            "-I",
            str(ROOT / "firmware" / "include"),
            "-I",
            str(PERSIST),
            "-c",
            str(PERSIST / "att_persist.c"),
            "-o",
            str(tmp_path / "nocal.o"),
        ]
    )
    undefined = {
        line.split()[-1]
        for line in _run(["arm-none-eabi-nm", "-u", str(tmp_path / "nocal.o")]).splitlines()
        if line.strip()
    }
    assert undefined <= {"att_node_init", "memcpy", "memset", "memcmp"}, undefined


@pytest.mark.parametrize(
    "name",
    [
        "README.md",
        "c/main.c",
        "c/CMakeLists.txt",
        "c/Makefile",
        "c/persist/att_persist.c",
        "python/quickstart.py",
    ],
)
def test_examples_are_where_a_newcomer_looks(name: str) -> None:
    assert (EXAMPLES / name).is_file()
    assert "examples/" in (ROOT / "README.md").read_text()

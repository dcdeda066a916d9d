"""examples/: the Python quickstart runs; the C main loop builds with add_subdirectory, with
find_package(attica) against an installed attica, and with firmware/attica.mk, all printing the
same bits; the umbrella header attica/attica.h holds the whole public API and compiles on its own."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

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


@pytest.mark.parametrize(
    "name", ["README.md", "c/main.c", "c/CMakeLists.txt", "c/Makefile", "python/quickstart.py"]
)
def test_examples_are_where_a_newcomer_looks(name: str) -> None:
    assert (EXAMPLES / name).is_file()
    assert "examples/" in (ROOT / "README.md").read_text()

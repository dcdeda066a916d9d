"""Build configurations (att_config.h): single-kind and no-stage builds give every output bit the
default build gives, refuse the kinds they leave out with ATT_ERR_DISABLED, and are as small as
their kinds.

Each configuration builds the golden runner (tests/c/att_golden.c) natively with its -D flags and
hashes the runner's records over the digest streams: the hashes must equal the committed lines of
tests/digests.txt that the default build (the cffi binding) wrote. The per-configuration sizes on
the Cortex-M4F are in ``make footprint`` (tools/attica_dev/footprint.py CONFIGS).
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest

from attica.settings import FilterKind, implemented_kinds
from attica_dev import digests, footprint, golden

from helpers import ROOT, need

CONFIGS: dict[str, list[str]] = {
    "ars-only": footprint.only("ARS"),
    "mekf-only": footprint.only("MEKF"),
    "ars-mars-only": footprint.only("ARS", "MARS"),
    "no-stages": ["-DATT_WITH_CALIB=0"],
    "ars-only-no-stages": footprint.only("ARS", calib=False),
    "no-hard-iron": ["-DATT_WITH_HARD_IRON=0"],
}
"""Configurations built here (CI builds each of them; the default is every other test)."""

ATT_ERR_DISABLED = -5
ATT_ERR_KIND = -3
ATT_ERR_SETTINGS = -2
ACK_OK, ACK_BAD_ARG, ACK_REFUSED = 0, 2, 3


def enabled(defines: list[str]) -> set[str]:
    """Lower-case names of the kinds a configuration compiles in."""
    off = {m.group(1).lower() for d in defines if (m := re.fullmatch(r"-DATT_WITH_([A-Z]+)=0", d))}
    return {k.label for k in implemented_kinds()} - off


@pytest.fixture(scope="module", params=sorted(CONFIGS))
def config(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> tuple[str, Path]:
    need(shutil.which("gcc") is not None, "gcc is not installed")
    name: str = request.param
    out = tmp_path_factory.mktemp(name)
    return name, golden.build_runner("gcc", "-O2", CONFIGS[name], out_dir=out)


def test_single_kind_builds_give_the_committed_digests(config: tuple[str, Path], tmp_path: Path) -> None:
    name, runner = config
    committed = digests.read()
    kinds = enabled(CONFIGS[name])
    checked = 0
    for kind in implemented_kinds():
        if kind.label not in kinds:
            continue
        for preset in ("default", "seed"):
            settings = digests._settings(kind, preset)
            for stream in ("sim", "adversarial"):
                g, a, m = digests.sim_stream() if stream == "sim" else digests.adversarial_stream()
                recs = golden.run_filter(runner, kind, settings, g, a, m, workdir=tmp_path)
                key = f"{kind.label}.{preset}.{stream}.run"
                assert digests.sha(recs.reshape(-1)) == committed[key], f"{name}: {key} differs"
                checked += 1
    assert checked == 4 * len(kinds)


def test_a_left_out_kind_is_refused(config: tuple[str, Path]) -> None:
    name, runner = config
    kinds = enabled(CONFIGS[name])
    for kind in implemented_kinds():
        if kind.label in kinds:
            continue
        with pytest.raises(golden.GoldenError, match=f"unknown command '{kind.label}'"):
            golden.run_filter(runner, kind, None, *digests.sim_stream())


@dataclass(frozen=True)
class ConfigReport:
    """What tests/c/att_config_test.c printed for one configuration."""

    kinds: dict[int, tuple[str, int, int]]  # value -> (name, settings_default status, init status)
    selects: dict[int, int]  # kind value -> the node's SELECT answer (ack result)
    size: tuple[int, int]  # sizeof(att_filter_t), the largest kind compiled in
    calibrate: int  # att_filter_calibrate's status
    hard_iron: dict[str, tuple[int, int]]  # mars / mekf: init with hard_iron_tau 60, att_filter_mag_offset


def _config_program(defines: list[str], out: Path) -> ConfigReport:
    exe = golden.build_program(
        [ROOT / "tests" / "c" / "att_config_test.c"], "gcc", "-O2", defines, "att_config_test", out
    )
    text = subprocess.run([str(exe)], capture_output=True, text=True, check=True, timeout=60).stdout
    kinds = {
        int(m.group(1)): (m.group(2), int(m.group(3)), int(m.group(4)))
        for m in re.finditer(r"^kind (\d+) (\S+) default=(-?\d+) init=(-?\d+)$", text, re.M)
    }
    selects = {
        int(m.group(1)): int(m.group(2)) for m in re.finditer(r"^select (\d+) result=(-?\d+)$", text, re.M)
    }
    size = re.search(r"^sizeof att_filter_t=(\d+) largest_kind=(\d+)$", text, re.M)
    cal = re.search(r"^calibrate=(-?\d+)$", text, re.M)
    assert size and cal, text
    hard_iron = {
        m.group(1): (int(m.group(2)), int(m.group(3)))
        for m in re.finditer(r"^hard_iron (\S+) init=(-?\d+) offset=(-?\d+)$", text, re.M)
    }
    sizes = (int(size.group(1)), int(size.group(2)))
    return ConfigReport(kinds, selects, sizes, int(cal.group(1)), hard_iron)


@pytest.mark.parametrize("name", ["default", *sorted(CONFIGS)])
def test_configuration_interface(name: str, tmp_path: Path) -> None:
    need(shutil.which("gcc") is not None, "gcc is not installed")
    defines = CONFIGS.get(name, [])
    res = _config_program(defines, tmp_path)
    kinds = enabled(defines)
    got = res.kinds
    for kind in FilterKind:
        label, default, init = got[int(kind)]
        assert label == kind.label  # a kind left out is still named
        if kind.label in kinds:
            assert (default, init) == (0, 0), f"{name}: {kind.label}"
        else:
            assert (default, init) == (ATT_ERR_DISABLED, ATT_ERR_DISABLED), f"{name}: {kind.label}"
    assert got[0][1:] == (ATT_ERR_KIND, ATT_ERR_KIND) and got[8] == ("?", ATT_ERR_KIND, ATT_ERR_KIND)
    selects = res.selects
    for kind in FilterKind:
        assert selects[int(kind)] == (ACK_OK if kind.label in kinds else ACK_REFUSED), f"{name}: {kind.label}"
    assert selects[8] == ACK_BAD_ARG
    size, largest = res.size
    stages = "-DATT_WITH_CALIB=0" not in defines
    assert res.calibrate == (0 if stages else ATT_ERR_DISABLED)
    hard = "-DATT_WITH_HARD_IRON=0" not in defines
    assert set(res.hard_iron) == {"mars", "mekf"} & kinds, res.hard_iron
    for label, (init, offset) in res.hard_iron.items():
        # compiled out: hard_iron_tau > 0 refused (ATT_ERR_SETTINGS), the offset ATT_ERR_DISABLED
        want = (0, 0) if hard else (ATT_ERR_SETTINGS, ATT_ERR_DISABLED)
        assert (init, offset) == want, f"{name}: {label}"
    if not stages:
        assert size <= largest + 16, f"{name}: att_filter_t {size} B for a largest kind of {largest} B"


def test_config_header_is_included_first(tmp_path: Path) -> None:
    """-DATT_CONFIG_HEADER names a header of the user's (libcanard's CANARD_CONFIG_HEADER pattern)."""
    need(shutil.which("gcc") is not None, "gcc is not installed")
    (tmp_path / "my_attica_config.h").write_text("#define ATT_WITH_EKF 0\n#define ATT_WITH_CALIB 0\n")
    res = _config_program(['-DATT_CONFIG_HEADER="my_attica_config.h"', f"-I{tmp_path}"], tmp_path)
    kinds = res.kinds
    assert kinds[int(FilterKind.EKF)][1:] == (ATT_ERR_DISABLED, ATT_ERR_DISABLED)
    assert kinds[int(FilterKind.ARS)][1:] == (0, 0) and res.calibrate == ATT_ERR_DISABLED


@pytest.mark.parametrize(
    ("defines", "message"),
    [
        (["-DATT_WITH_ARS=2"], "ATT_WITH_ARS must be 0 or 1"),
        (footprint.only(), "at least one filter kind"),
        (["-DATT_WITH_CALIB=-1"], "ATT_WITH_CALIB must be 0 or 1"),
    ],
)
def test_bad_configuration_stops_the_build(defines: list[str], message: str, tmp_path: Path) -> None:
    need(shutil.which("gcc") is not None, "gcc is not installed")
    with pytest.raises(golden.GoldenError, match=message):
        golden.build_program(
            [ROOT / "tests" / "c" / "att_config_test.c"], "gcc", "-O0", defines, "x", tmp_path
        )


def _example_output(exe: Path) -> str:
    proc = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60, check=True)
    assert proc.stdout.startswith("steps 1000 "), proc.stdout
    return proc.stdout


def test_make_fragment_and_cmake_take_a_configuration(tmp_path: Path) -> None:
    """examples/c (ARS through att_filter.h) built with ARS only and no stages by firmware/attica.mk
    (ATTICA_CONFIG) and by CMake (ATTICA_CONFIG_DEFINITIONS, ATTICA_CONFIG_HEADER): the same bits as
    the default build."""
    for tool in ("make", "cmake", "cc"):
        need(shutil.which(tool) is not None, f"{tool} is not installed")
    example = ROOT / "examples" / "c"
    flags = footprint.only("ARS", calib=False)
    outputs = {}
    for name, config in (("default", []), ("ars", flags)):
        build = tmp_path / f"mk-{name}"
        proc = subprocess.run(
            ["make", "-f", str(example / "Makefile"), f"BUILD={build}", f"ATTICA_CONFIG={' '.join(config)}"],
            cwd=ROOT,
            check=True,
            capture_output=True,
            text=True,
        )
        compiles = [line for line in proc.stdout.splitlines() if " -c " in line]
        assert compiles and all(("-DATT_WITH_MARS=0" in line) == bool(config) for line in compiles)
        outputs[f"make {name}"] = _example_output(build / "example")
    header = tmp_path / "cfg" / "my_attica_config.h"
    header.parent.mkdir()
    header.write_text("".join(f"#define {f[2:].replace('=', ' ')}\n" for f in flags))
    defs = ";".join(f[2:] for f in flags)
    for name, option in (
        ("definitions", f"-DATTICA_CONFIG_DEFINITIONS={defs}"),
        ("header", f"-DATTICA_CONFIG_HEADER={header}"),
    ):
        build = tmp_path / f"cmake-{name}"
        subprocess.run(
            ["cmake", "-S", str(example), "-B", str(build), option, "-DCMAKE_EXPORT_COMPILE_COMMANDS=ON"],
            check=True,
            capture_output=True,
        )
        subprocess.run(["cmake", "--build", str(build)], check=True, capture_output=True)
        entries = json.loads((build / "compile_commands.json").read_text())
        want = "ATT_WITH_MARS=0" if name == "definitions" else "ATT_CONFIG_HEADER="
        assert len(entries) > 10 and all(want in e["command"] for e in entries), (
            "configuration not everywhere"
        )
        outputs[f"cmake {name}"] = _example_output(build / "example")
    assert len(set(outputs.values())) == 1, outputs


def test_the_config_header_of_the_docs(tmp_path: Path) -> None:
    """The configuration header shown in docs/integration.md compiles and does what it says (ARS only)."""
    need(shutil.which("gcc") is not None, "gcc is not installed")
    text = (ROOT / "docs" / "integration.md").read_text()
    block = re.search(r"```c\n(/\* my_attica_config\.h.*?)```", text, re.S)
    assert block, "docs/integration.md lost its configuration header example"
    (tmp_path / "my_attica_config.h").write_text(block.group(1))
    res = _config_program(['-DATT_CONFIG_HEADER="my_attica_config.h"', f"-I{tmp_path}"], tmp_path)
    kinds = res.kinds
    on = {kinds[int(k)][0] for k in FilterKind if kinds[int(k)][1:] == (0, 0)}
    assert on == {"ars"} and res.calibrate == ATT_ERR_DISABLED

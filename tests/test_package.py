"""The package as a new user gets it: sdist and wheel built from a plain copy of the repository, each
installed into a fresh venv and used from a directory outside the checkout.

Smoke check in every venv: the C filter (the extension built by the wheel's build hook) bit-exact with
the numpy reference, ``attica verify --with-node`` bit-exact, ``attica --version`` equal to
att_version.h, the firmware package data found through importlib.resources (``attica paths``), nothing
written into the installation by importing or running it. The wheel's installed firmware copy also
builds and runs the C example of examples/c with the flags it ships.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from attica._version import parse_version_header

from helpers import ROOT

VERSION = "{}.{}.{}".format(
    *parse_version_header((ROOT / "firmware/include/attica/att_version.h").read_text())
)

_SKIP = (".git", ".venv", "build", "dist", "__pycache__", "*.so", "*.stamp", "*.egg-info", "_firmware")
_SKIP += (".pytest_cache", ".mypy_cache", ".ruff_cache", "out", "eval")

SMOKE = r"""
import importlib.metadata, sys, warnings
from pathlib import Path
import numpy as np
import attica
from attica import native, reference, resources
here = Path(attica.__file__).resolve().parent
assert str(here).startswith(sys.prefix), (here, sys.prefix)  # the installed copy, not the checkout
assert attica.__version__ == importlib.metadata.version("attica") == sys.argv[1], attica.__version__
lib = native.lib
assert (lib.ATT_VERSION_MAJOR, lib.ATT_VERSION_MINOR, lib.ATT_VERSION_PATCH) == attica.VERSION_INFO
assert resources.firmware_dir() == here / "_firmware", resources.firmware_dir()
for p in (resources.dbc_path(), resources.cflags_file(), resources.include_dir() / "attica" / "att_filter.h"):
    assert p.is_file(), p
assert len(resources.sources()) >= 10
rec = attica.simulate(attica.SimConfig(duration=12.0, rate=200.0, seed=3, taps=1))
for kind in attica.kinds.labels():
    c = attica.Filter(kind, 1 / rec.rate).run(rec.gyr, rec.acc, rec.mag)
    r = reference.Filter(kind, 1 / rec.rate).run(rec.gyr[:400], rec.acc[:400], rec.mag[:400])
    assert (c["q"][:400].view(np.uint32) == r["q"].view(np.uint32)).all(), kind
    assert (c["flags"][:400] == r["flags"]).all(), kind
print("smoke ok", attica.__version__, len(rec.gyr))
"""


def _run(cmd: list[str], cwd: Path, timeout: float = 600, env: dict[str, str] | None = None) -> str:
    r = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env)
    assert r.returncode == 0, (
        f"{' '.join(cmd)} failed ({r.returncode}):\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    )
    return r.stdout


def _clean_env() -> dict[str, str]:
    """The environment without this checkout on the path (a user's shell)."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    return env


@pytest.fixture(scope="module")
def dists(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """sdist and wheel of a plain copy of the repository (``python -m build``: the wheel from the sdist)."""
    tmp = tmp_path_factory.mktemp("package")
    src = tmp / "attica-src"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(*_SKIP))
    out = tmp / "dist"
    _run(
        [sys.executable, "-m", "build", "--outdir", str(out), str(src)],
        cwd=tmp,
        timeout=900,
        env=_clean_env(),
    )
    wheels = sorted(out.glob("attica-*.whl"))
    sdists = sorted(out.glob("attica-*.tar.gz"))
    assert len(wheels) == 1 and len(sdists) == 1, sorted(p.name for p in out.iterdir())
    return {"wheel": wheels[0], "sdist": sdists[0]}


def test_dists_hold_what_they_must(dists: dict[str, Path]) -> None:
    import tarfile
    import zipfile

    wheel = dists["wheel"]
    # a platform wheel with the extension, not py3-none-any
    assert wheel.name.startswith(f"attica-{VERSION}-cp") and "none-any" not in wheel.name, wheel.name
    names = zipfile.ZipFile(wheel).namelist()
    assert any(n.startswith("attica/_native") and n.endswith(".so") for n in names), names
    for must in (
        "attica/_firmware/cflags.txt",
        "attica/_firmware/can/attica.dbc",
        "attica/_firmware/include/attica/att_version.h",
        "attica/_firmware/include/attica/att_filter.h",
        "attica/_firmware/src/filters/att_filter.c",
        "attica/_firmware/CMakeLists.txt",
        "attica/py.typed",
        f"attica-{VERSION}.dist-info/licenses/LICENSE",
    ):
        assert must in names, must
    assert not [n for n in names if n.endswith((".o", ".stamp", ".lock"))]
    members = tarfile.open(dists["sdist"]).getnames()
    root = f"attica-{VERSION}"
    for must in ("LICENSE", "setup.py", "MANIFEST.in", "firmware/cflags.txt", "firmware/can/attica.dbc"):
        assert f"{root}/{must}" in members, must
    assert (
        f"{root}/firmware/src/filters/att_filter.c" in members
        and f"{root}/host/attica/csrc/att_host.c" in members
    )
    assert not [m for m in members if m.endswith((".so", ".o", ".stamp"))]


def _venv(path: Path) -> Path:
    subprocess.run([sys.executable, "-m", "venv", str(path)], check=True, timeout=300)
    return path / "bin"


def _tree_listing(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*") if "__pycache__" not in p.parts}


@pytest.mark.parametrize("what", ["wheel", "sdist"])
def test_install_and_use_outside_the_checkout(dists: dict[str, Path], what: str, tmp_path: Path) -> None:
    """pip install <wheel> | <sdist> into a fresh venv; every command works from elsewhere.

    (``pip install .`` of a source tree takes the same path as building the wheel from the sdist.)
    """
    bin_dir = _venv(tmp_path / "venv")
    env = _clean_env()
    pip = [str(bin_dir / "pip"), "install", "-q", "--no-compile"]
    _run([*pip, str(dists[what])], cwd=tmp_path, timeout=900, env=env)
    away = tmp_path / "elsewhere"
    away.mkdir()
    site = Path(
        _run(
            [str(bin_dir / "python"), "-c", "import attica, os; print(os.path.dirname(attica.__file__))"],
            away,
            env=env,
        ).strip()
    )
    before = _tree_listing(site)
    out = _run([str(bin_dir / "python"), "-c", SMOKE, VERSION], away, env=env)
    assert "smoke ok" in out
    attica = str(bin_dir / "attica")
    assert _run([attica, "--version"], away, env=env).split()[:2] == ["attica", VERSION]
    out = _run([attica, "verify", "--with-node", "--duration", "3", "-q"], away, env=env)
    assert "verdict: BIT-EXACT" in out, out
    out = _run([attica, "demo", "--duration", "8", "-q"], away, env=env)
    assert "0 differ: bit-exact" in out, out
    assert Path(_run([attica, "paths", "--dbc"], away, env=env).strip()).is_file()
    log = away / "bus.log"
    _run(
        [attica, "verify", "--with-node", "--filter", "mars", "--duration", "2", "-q", "-w", str(log)],
        away,
        env=env,
    )
    assert "BIT-EXACT" in _run([attica, "verify", "--log", str(log), "--filter", "mars"], away, env=env)
    assert _tree_listing(site) == before, "running attica wrote into its installation"
    if what == "wheel":
        # the shipped firmware copy builds a firmware program with the shipped flags
        cflags = _run([attica, "paths", "--cflags"], away, env=env).split()
        inc = _run([attica, "paths", "--include"], away, env=env).strip()
        srcs = _run([attica, "paths", "--sources"], away, env=env).split()
        cc = os.environ.get("CC", "cc")
        objs = []
        for src in srcs:
            objs.append(str(away / (Path(src).stem + ".o")))
            _run([cc, *cflags, "-O2", "-I", inc, "-c", src, "-o", objs[-1]], away)
        exe = away / "example"
        main = ROOT / "examples" / "c" / "main.c"
        _run([cc, "-std=c99", "-O2", "-I", inc, str(main), *objs, "-o", str(exe)], away)
        assert _run([str(exe)], away).strip()

"""The snapshot of the sources and its unmutated build (build/mutation/base-<hash>).

The objects, the stage A runners' mains, the cffi wrapper of the binding, the inputs and the digests of
the unmutated runs of stages A and B.
"""

from __future__ import annotations

import fnmatch
import hashlib
import json
import os
import shlex
import shutil
import subprocess
import tempfile
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

from attica_dev.mutation.config import CC, OPT, ROOT, WORK
from attica_dev.mutation.stage_a import Case, _run_case, _write_cases
from attica_dev.mutation.stage_b import _binding_run


@dataclass(frozen=True)
class Runner:
    """A test program of stage A: its main source, extra include folders, the firmware sources it links."""

    name: str
    source: str
    includes: tuple[str, ...] = ()
    """Relative to the tree; ``@gen``: the golden runner's generated field table."""
    links: tuple[str, ...] | None = None
    """None: every firmware source."""


_RUNNERS = (
    Runner("golden", "tests/c/att_golden.c", ("@gen",)),
    Runner("node", "tests/c/att_node_run.c"),
    Runner("config", "tests/c/att_config_test.c"),
    Runner("core", "tests/c/att_core_test.c", ("firmware/src/core",), ("firmware/src/math/att_math.c",)),
)
"""The programs of stage A (the suite's own: tests/test_cross.py, test_node_configs.py, test_configs.py and
test_core.py build them), each linked with the firmware objects it needs."""
_SNAPSHOT = (
    "firmware/src",
    "firmware/include",
    "firmware/cflags.txt",
    "host/attica",
    "tools/attica_dev",
    *(r.source for r in _RUNNERS),
)
"""What a base copies: the sources, the runners, and the Python that makes the inputs and runs stage B."""
_IGNORE = ("*.o", "__pycache__", "_native*.so", "_native.stamp")
_UNUSED = ("host/attica/reference/", "host/attica/view/", "host/attica/evaluate/", "host/attica/commands/")
"""Copied but not hashed: the oracle does not use them (other work on them does not rebuild the base)."""


def _obj_name(rel: str) -> str:
    return rel.replace("/", "__").removesuffix(".c") + ".o"


def _snapshot_digest() -> str:
    """A hash of every file the oracle is built from (sources, runners, the Python of inputs and stage B)."""
    h = hashlib.sha256()
    files: list[Path] = []
    for part in _SNAPSHOT:
        p = ROOT / part
        files.extend(sorted(q for q in p.rglob("*") if q.is_file()) if p.is_dir() else [p])
    for f in files:
        rel = f.relative_to(ROOT).as_posix()
        skip = any(fnmatch.fnmatch(f.name, g) for g in _IGNORE) or "__pycache__" in f.parts
        if skip or rel.startswith(_UNUSED):
            continue
        h.update(rel.encode())
        h.update(f.read_bytes())
    h.update(CC.encode())
    return h.hexdigest()[:16]


def _run(cmd: Sequence[str], what: str, cwd: Path | None = None) -> None:
    proc = subprocess.run(list(cmd), capture_output=True, text=True, cwd=cwd)
    if proc.returncode != 0:
        raise RuntimeError(f"{what} failed ({shlex.join(cmd)}):\n{proc.stderr[-4000:]}")


@dataclass
class Base:
    """The unmutated build of one snapshot: objects, the runners' mains, the binding's wrapper, inputs."""

    dir: Path
    tree: Path
    sources: list[str]
    """firmware/src/**/*.c, relative to the tree."""
    includers: dict[str, list[str]]
    """Private header -> the sources that include it (directly or not)."""
    cases: list[Case]
    baseline: dict[str, str]
    """Stage A: case name -> digest of the unmutated run."""
    seconds: dict[str, float]
    binding: dict[str, str]
    """Stage B: check name -> digest of the unmutated library."""
    binding_seconds: float

    @property
    def cflags(self) -> list[str]:
        """The firmware flags (the snapshot's cflags.txt), the optimisation level, position independence."""
        return [*shlex.split((self.tree / "firmware" / "cflags.txt").read_text()), OPT, "-fPIC"]

    @property
    def obj(self) -> Path:
        """The unmutated objects."""
        return self.dir / "obj"

    def compile(
        self, tree: Path, src: str, obj: Path, extra: Sequence[str] = ()
    ) -> subprocess.CompletedProcess[str]:
        """Compile ``tree``/``src`` with the firmware flags (``extra``: more -I).

        The compiler runs in ``tree`` on the relative name, so that the object of an unchanged source is
        the same bytes in every tree (what tells a mutant the compiler made equivalent).
        """
        include = str(self.tree / "firmware" / "include")
        cmd = [CC, *self.cflags, "-I", include, *extra, "-c", src, "-o", str(obj)]
        return subprocess.run(cmd, capture_output=True, text=True, cwd=tree)

    def objects(self, replaced: dict[str, Path] | None = None) -> list[str]:
        """The firmware objects, with ``replaced`` (source -> object) in place of the unmutated ones."""
        replaced = replaced or {}
        return [str(replaced.get(s, self.obj / _obj_name(s))) for s in self.sources]

    def main_flags(self, r: Runner) -> list[str]:
        """The -I flags of a runner's main."""
        out = []
        for inc in r.includes:
            out += ["-I", str(self.dir / "gen") if inc == "@gen" else inc]
        return out

    def link(
        self,
        out_dir: Path,
        replaced: dict[str, Path] | None = None,
        mains: dict[str, Path] | None = None,
        only: Sequence[str] | None = None,
    ) -> dict[str, Path]:
        """Link the stage A programs (``only`` those) into ``out_dir``; returns name -> program.

        ``replaced``: firmware source -> mutated object; ``mains``: runner -> recompiled main object.
        """
        exes = {}
        replaced = replaced or {}
        for r in _RUNNERS:
            if only is not None and r.name not in only:
                continue
            exe = out_dir / f"att_{r.name}"
            main = (mains or {}).get(r.name, self.dir / f"{r.name}_main.o")
            objs = self.objects(replaced)
            if r.links is not None:
                objs = [str(replaced.get(s, self.obj / _obj_name(s))) for s in r.links]
            _run([CC, str(main), *objs, "-lm", "-o", str(exe)], f"link {r.name}")
            exes[r.name] = exe
        return exes

    def link_binding(self, out_dir: Path, replaced: dict[str, Path] | None = None) -> Path:
        """Link the library as ``attica._native`` (the cffi wrapper and host kernels built once)."""
        import sysconfig

        so = out_dir / ("_native" + (sysconfig.get_config_var("EXT_SUFFIX") or ".so"))
        host = sorted(str(p) for p in (self.dir / "host").glob("*.o"))
        _run(
            [
                CC,
                "-shared",
                str(self.dir / "cffi_wrap.o"),
                *host,
                *self.objects(replaced),
                "-lm",
                "-o",
                str(so),
            ],
            "link",
        )
        return so


def _copy_tree(dst: Path) -> None:
    for part in _SNAPSHOT:
        src = ROOT / part
        target = dst / part
        target.parent.mkdir(parents=True, exist_ok=True)
        if src.is_dir():
            shutil.copytree(src, target, ignore=shutil.ignore_patterns(*_IGNORE))
        else:
            shutil.copy2(src, target)


def _includers(base: Base, units: list[tuple[str, str, list[str]]]) -> dict[str, list[str]]:
    """Private header -> the units (key, source, -I flags) that include it, directly or not."""
    tree = base.tree
    out: dict[str, list[str]] = {}
    for s, src, extra in units:
        cmd = [CC, *base.cflags, "-I", str(tree / "firmware" / "include"), *extra, "-MM", src]
        proc = subprocess.run(cmd, capture_output=True, text=True, check=True, cwd=tree)
        for dep in proc.stdout.replace("\\\n", " ").split(":", 1)[1].split():
            p = Path(os.path.normpath(tree / dep))
            try:
                rel = p.relative_to(tree).as_posix()
            except ValueError:
                continue
            if rel.startswith("firmware/src/") and rel.endswith(".h"):
                if s not in out.setdefault(rel, []):
                    out[rel].append(s)
    return out


def _build_wrapper(tree: Path, out: Path) -> None:
    """The cffi wrapper of attica._native (the snapshot's declarations), compiled to ``out``."""
    import sysconfig

    from attica import _build

    saved = (_build.FIRMWARE, _build.INCLUDE, _build.CSRC)
    try:
        _build.FIRMWARE = tree / "firmware"
        _build.INCLUDE = tree / "firmware" / "include"
        _build.CSRC = tree / "host" / "attica" / "csrc"
        ffi = _build.make_ffi([])
        c_file = out.with_suffix(".c")
        ffi.emit_c_code(str(c_file))
        dirs = _build.include_dirs()  # the snapshot's: the public headers, the host kernels, the codec's
    finally:
        _build.FIRMWARE, _build.INCLUDE, _build.CSRC = saved
    inc = ["-I", sysconfig.get_paths()["include"]]
    for d in dirs:
        inc += ["-I", str(d)]
    _run([CC, "-O1", "-fPIC", *inc, "-c", str(c_file), "-o", str(out)], "the cffi wrapper")


def _prepare(jobs: int, log: Callable[[str], None]) -> Base:
    """The base of the current sources: built once per snapshot (build/mutation/base-<hash>), then reused."""
    digest = _snapshot_digest()
    final = WORK / f"base-{digest}"
    meta = final / "base.json"
    if not meta.exists():
        WORK.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f"base-{digest}.", dir=WORK))
        t0 = time.perf_counter()
        log(f"building the unmutated base in {tmp.relative_to(ROOT)} ...")
        try:
            _build_base(tmp, jobs, log)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        try:
            os.replace(tmp, final)
        except OSError:  # another process made the same base meanwhile
            shutil.rmtree(tmp, ignore_errors=True)
        log(f"base ready in {time.perf_counter() - t0:.1f} s")
    _prune(keep=final)
    data = json.loads(meta.read_text())
    return Base(
        final,
        final / "tree",
        data["sources"],
        data["includers"],
        [Case(**c) for c in data["cases"]],
        data["baseline"],
        data["seconds"],
        data["binding"],
        data["binding_seconds"],
    )


def _prune(keep: Path, hours: float = 12.0) -> None:
    """Remove the bases of other snapshots (and runs left by killed processes) older than ``hours``."""
    limit = time.time() - 3600.0 * hours
    for d in WORK.glob("*"):
        if d != keep and d.is_dir() and d.name.startswith(("base-", "run-")) and d.stat().st_mtime < limit:
            shutil.rmtree(d, ignore_errors=True)


def _build_base(d: Path, jobs: int, log: Callable[[str], None]) -> None:
    from attica_dev import golden

    tree = d / "tree"
    _copy_tree(tree)
    sources = [p.relative_to(tree).as_posix() for p in sorted((tree / "firmware" / "src").rglob("*.c"))]
    base = Base(d, tree, sources, {}, [], {}, {}, {}, 0.0)
    base.obj.mkdir(parents=True)
    (d / "host").mkdir()
    csrc = tree / "host" / "attica" / "csrc"
    golden.write_fields_header(d / "gen")
    work: list[tuple[Path, str, Path, list[str]]] = [(tree, s, base.obj / _obj_name(s), []) for s in sources]
    for p in sorted(csrc.glob("*.c")):
        work.append((tree, p.relative_to(tree).as_posix(), d / "host" / (p.stem + ".o"), ["-I", str(csrc)]))
    work += [(tree, r.source, d / f"{r.name}_main.o", base.main_flags(r)) for r in _RUNNERS]

    def one(item: tuple[Path, str, Path, list[str]]) -> None:
        proc = base.compile(*item)
        if proc.returncode != 0:
            raise RuntimeError(f"the unmutated {item[1]} does not compile:\n{proc.stderr[-4000:]}")

    with ThreadPoolExecutor(max(jobs, 1)) as ex:
        wrapper = ex.submit(_build_wrapper, tree, d / "cffi_wrap.o")
        list(ex.map(one, work))
        wrapper.result()
    units: list[tuple[str, str, list[str]]] = [(s, s, []) for s in sources]
    units += [(f"main:{r.name}", r.source, base.main_flags(r)) for r in _RUNNERS]
    includers = _includers(base, units)
    log("writing the oracle's inputs ...")
    cases = _write_cases(d / "inputs")
    exes = base.link(d)
    baseline, seconds = {}, {}
    for c in cases:
        t0 = time.perf_counter()
        out = _run_case(c, exes, d / "inputs", d, timeout=600.0)
        seconds[c.name] = time.perf_counter() - t0
        if out.startswith("!"):
            raise RuntimeError(f"the unmutated firmware fails case {c.name}: {out}")
        baseline[c.name] = out
    so_dir = d / "binding"
    so_dir.mkdir()
    so = base.link_binding(so_dir)
    t0 = time.perf_counter()
    status, binding = _binding_run(tree, so, None, "", timeout=600.0)
    if status != "ok":
        raise RuntimeError(f"the binding checks fail on the unmutated library: {status}")
    meta = {
        "sources": sources,
        "includers": includers,
        "cases": [asdict(c) for c in cases],
        "baseline": baseline,
        "seconds": seconds,
        "binding": binding,
        "binding_seconds": time.perf_counter() - t0,
    }
    (d / "base.json").write_text(json.dumps(meta, indent=1))

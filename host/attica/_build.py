"""Build the cffi API-mode extension ``attica._native`` from the firmware sources.

The firmware sources (firmware/src/**/*.c) and the host batch kernels (host/attica/csrc/*.c) are
compiled to objects with exactly the flags in firmware/cflags.txt (the same as every other build)
and linked into the extension; only the cffi wrapper itself is compiled with Python's flags. The C
declarations given to cffi are the ``ATT_CDEF_BEGIN``/``ATT_CDEF_END`` sections of the headers, so
the headers are the single source of the API.

Two callers, one set of steps:

- ``setup.py`` (``pip install .``, ``python -m build``): its ``build_ext`` hook compiles the objects
  and the wrapper into the wheel, and its ``build_py`` hook copies the firmware tree into the package
  as ``attica/_firmware`` (:func:`copy_firmware`), so that an installed attica carries its sources,
  headers, flags and DBC (:mod:`attica.resources`).
- ``python -m attica._build`` (``make build``): builds the extension in place for an editable
  checkout and writes ``_native.stamp`` (a digest of its inputs); :mod:`attica.native` refuses to load
  an extension whose stamp no longer matches the checkout (it never builds anything itself).

This module uses the standard library only (``setup.py`` loads it by path in the build environment);
the paths below are those of a checkout (``ROOT`` is the repository).
"""

from __future__ import annotations

import hashlib
import os
import re
import shlex
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path
from typing import Any

PKG = Path(__file__).resolve().parent
ROOT = PKG.parent.parent
FIRMWARE = ROOT / "firmware"
INCLUDE = FIRMWARE / "include"
CSRC = PKG / "csrc"
BUILD = ROOT / "build" / "native"
LIVE_SOURCE = CSRC / "py" / "att_live.c"
"""attica._live: the CPython method behind ``Filter.update`` (Python's flags; no filter arithmetic)."""
STAMP = PKG / "_native.stamp"
VERSION_HEADER = INCLUDE / "attica" / "att_version.h"
"""The version (read by setup.py and attica.__version__ through attica._version)."""

FIRMWARE_DATA = "_firmware"
"""Name of the firmware copy inside an installed package (``attica/_firmware``)."""

_CDEF = re.compile(r"/\* ATT_CDEF_BEGIN \*/(.*?)/\* ATT_CDEF_END \*/", re.S)


def firmware_sources() -> list[Path]:
    """The firmware C sources (every ``*.c`` below firmware/src, sorted by path)."""
    return sorted((FIRMWARE / "src").rglob("*.c"))


def private_headers() -> list[Path]:
    """The firmware's private headers (every ``*.h`` below firmware/src, sorted by path)."""
    return sorted((FIRMWARE / "src").rglob("*.h"))


_INCLUDE_RE = re.compile(r'^#include "(?:attica/)?(att_\w+\.h)"', re.M)


def headers() -> list[Path]:
    """Public headers then host headers, each after the headers it includes (dependency order)."""
    pool = {h.name: h for h in sorted((INCLUDE / "attica").glob("*.h"))}
    pool.update({h.name: h for h in sorted(CSRC.glob("*.h"))})
    ordered: list[Path] = []
    visiting: set[str] = set()

    def visit(name: str) -> None:
        if name not in pool or pool[name] in ordered:
            return
        if name in visiting:
            raise RuntimeError(f"include cycle through {name}")
        visiting.add(name)
        for dep in _INCLUDE_RE.findall(pool[name].read_text()):
            visit(dep)
        visiting.discard(name)
        ordered.append(pool[name])

    for name in pool:
        visit(name)
    return [h for h in ordered if _has_source(h)]


def _has_source(header: Path) -> bool:
    """A header with prototypes is bound only once its module source exists (att_x.h -> att_x.c)."""
    decls = re.sub(r"/\*.*?\*/", "", "".join(_CDEF.findall(header.read_text())), flags=re.S)
    if "(" not in decls:
        return True  # types and constants only
    if header.parent == CSRC:
        found = (CSRC / (header.stem + ".c")).exists()
    else:
        found = any(s.stem == header.stem for s in firmware_sources())
    if found:
        return True
    print(f"attica build: skipping {header.name}: no {header.stem}.c yet", file=sys.stderr)
    return False


def cflags() -> list[str]:
    """The strict firmware flags (firmware/cflags.txt)."""
    return shlex.split((FIRMWARE / "cflags.txt").read_text())


_CONFIG_IF = re.compile(r"^[ \t]*#[ \t]*(if|else|endif)\b[ \t]*(\w*)")
_CONFIG_DEFAULT = re.compile(r"^#define (ATT_NODE_[A-Z_]+) (\d+)$", re.M)


def config_defaults() -> dict[str, int]:
    """The numeric defaults of att_config.h's options that are not 0/1 switches (the ring sizes)."""
    text = (INCLUDE / "attica" / "att_config.h").read_text()
    return {m.group(1): int(m.group(2)) for m in _CONFIG_DEFAULT.finditer(text)}


def _default_branches(text: str) -> str:
    """Keep what the default configuration compiles of ``#if OPTION`` / ``#else`` / ``#endif`` blocks.

    Every option named in such a condition (ATT_WITH_*, ATT_NODE_WITH_FD, ATT_NODE_WITH_MAG_OFFSET) is 1
    in the default build;
    anything else in a condition is an error (cffi's parser takes no conditionals).
    """
    keep: list[bool] = []
    out = []
    for line in text.splitlines():
        m = _CONFIG_IF.match(line)
        if m is None:
            if all(keep):
                out.append(line)
            continue
        word, name = m.group(1), m.group(2)
        if word == "if":
            if not re.fullmatch(r"ATT_(?:NODE_)?WITH_[A-Z_]+", name):
                raise ValueError(f"ATT_CDEF sections: unsupported condition {line.strip()!r}")
            keep.append(True)
        elif word == "else":
            keep[-1] = not keep[-1]
        else:
            keep.pop()
    if keep:
        raise ValueError("ATT_CDEF sections: #if without #endif")
    return "\n".join(out)


def cdef_text() -> str:
    """Declarations for cffi, taken from the headers' ATT_CDEF sections.

    The binding is built with every kind and stage (att_config.h's defaults): of ``#if ATT_WITH_*``
    blocks the default branch is kept (cffi's parser takes no conditionals), and the ring sizes are
    declared with their default values.
    """
    parts = [f"#define {k} {v}" for k, v in sorted(config_defaults().items())]
    for h in headers():
        for block in _CDEF.findall(h.read_text()):
            parts.append(block)
    text = re.sub(r"/\*.*?\*/", "", "\n".join(parts), flags=re.S)
    return _default_branches(text)


def codec_header() -> Path:
    """The generated CAN codec's header (host/attica/can/gen.py) under ``FIRMWARE``.

    A private firmware header, declared to cffi as well so that tests reach every generated function
    (tests/test_can_generated.py), not only those att_can.c calls. A function, not a constant: the
    mutation snapshot points ``FIRMWARE`` at its own tree.
    """
    return FIRMWARE / "src" / "can" / "generated" / "att_can_db.h"


def include_dirs() -> list[Path]:
    """The include folders of the cffi wrapper: the public headers, the host kernels, the codec's."""
    return [INCLUDE, CSRC, codec_header().parent]


_POSITIVE_DEFINE = re.compile(r"#define (ATT_CAN_DB_\w+) \((0x[0-9a-fA-F]+|[0-9]+)u?\)")
_SKIPPED_DEFINE = re.compile(r'#define ATT_CAN_DB_\w+( \(-[0-9]+\)| "[^"]*")?')
"""What codec_cdef leaves out on purpose: negative constants, names (strings), the include guard."""


def codec_cdef() -> str:
    """The generated codec header as cffi declarations.

    Its structs and prototypes, and its non-negative integer constants (frame ids, lengths, raw limits);
    comments, includes, C++ guards, string and negative constants are left out (cffi's parser takes none
    of those).
    """
    text = re.sub(r"#ifdef __cplusplus.*?#endif", "", codec_header().read_text(), flags=re.S)
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    out = []
    for line in text.splitlines():
        if not line.lstrip().startswith("#"):
            out.append(line)
            continue
        m = _POSITIVE_DEFINE.fullmatch(line.strip())
        if m:
            out.append(f"#define {m.group(1)} {int(m.group(2), 0)}")
        elif line.startswith("#define ATT_CAN_DB_") and not _SKIPPED_DEFINE.fullmatch(line.strip()):
            raise ValueError(f"{codec_header().name}: a constant of a form codec_cdef does not know: {line}")
    return "\n".join(out)


def inputs_digest() -> str:
    """Hash over everything the extension is built from (sources, headers, flags, this file)."""
    h = hashlib.sha256()
    files = firmware_sources() + headers() + sorted(CSRC.glob("*.c")) + private_headers() + [LIVE_SOURCE]
    for f in files + [FIRMWARE / "cflags.txt", Path(__file__)]:
        h.update(f.name.encode())
        h.update(f.read_bytes())
    h.update(os.environ.get("CC", "cc").encode())
    return h.hexdigest()


def compile_objects(cc: str, opt: str = "-O2", build_dir: Path | None = None) -> list[Path]:
    """Compile firmware and host kernels with the strict flags into ``build_dir``; return the objects."""
    out_dir = build_dir if build_dir is not None else BUILD
    out_dir.mkdir(parents=True, exist_ok=True)
    objs = []
    stems = [s.stem for s in firmware_sources() + sorted(CSRC.glob("*.c"))]
    if len(stems) != len(set(stems)):
        raise RuntimeError(f"two C sources share a name (objects are named by it): {sorted(stems)}")
    for src in firmware_sources() + sorted(CSRC.glob("*.c")):
        obj = out_dir / (src.stem + ".o")
        cmd = [
            *shlex.split(cc),
            *cflags(),
            opt,
            "-fPIC",
            "-I",
            str(INCLUDE),
            "-I",
            str(CSRC),
            "-c",
            str(src),
            "-o",
            str(obj),
        ]
        subprocess.run(cmd, check=True)
        objs.append(obj)
    return objs


def make_ffi(objects: list[Path]) -> Any:
    """The cffi builder of ``attica._native``: the headers' declarations, linked with ``objects``."""
    from cffi import FFI

    ffi = FFI()
    ffi.cdef(cdef_text())
    ffi.cdef(codec_cdef())
    includes = "".join(
        f'#include "{h.name}"\n' if h.parent == CSRC else f'#include "attica/{h.name}"\n' for h in headers()
    )
    ffi.set_source(
        "attica._native",
        includes + f'#include "{codec_header().name}"\n',
        include_dirs=[str(p) for p in include_dirs()],
        extra_objects=[str(o) for o in objects],
    )
    return ffi


def copy_firmware(dest: Path) -> list[Path]:
    """Copy the firmware tree (sources, headers, cflags.txt, DBC, ports, CMake and make files) to ``dest``.

    Returns the files written. Build products (objects, archives) are left out.
    """
    if dest.exists():
        shutil.rmtree(dest)
    written = []
    for src in sorted(FIRMWARE.rglob("*")):
        if not src.is_file() or src.suffix in (".o", ".a", ".so") or "__pycache__" in src.parts:
            continue
        target = dest / src.relative_to(FIRMWARE)
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, target)
        written.append(target)
    return written


def build(verbose: bool = False) -> Path:
    """Build the extension into the checkout's package folder (editable use); return its path."""
    cc = os.environ.get("CC", "cc")
    ffi = make_ffi(compile_objects(cc))
    tmp = BUILD / "cffi"
    tmp.mkdir(parents=True, exist_ok=True)
    built = Path(ffi.compile(tmpdir=str(tmp), verbose=verbose))
    suffix = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
    target = PKG / ("_native" + suffix)
    # replace atomically: processes that already loaded the old file keep its inode
    tmp_target = target.with_name(target.name + f".{os.getpid()}.tmp")
    shutil.copy2(built, tmp_target)
    os.replace(tmp_target, target)
    build_live(cc)
    STAMP.write_text(inputs_digest() + "\n")
    return target


def build_live(cc: str) -> Path:
    """Build ``attica._live`` in place with Python's include path (what setup.py's build_ext does)."""
    suffix = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
    target = PKG / ("_live" + suffix)
    tmp_target = target.with_name(target.name + f".{os.getpid()}.tmp")
    cmd = [
        *shlex.split(cc),
        "-O2",
        "-std=c99",
        "-fPIC",
        "-shared",
        "-Wall",
        "-Werror",
        "-I",
        sysconfig.get_paths()["include"],
        str(LIVE_SOURCE),
        "-o",
        str(tmp_target),
    ]
    subprocess.run(cmd, check=True)
    os.replace(tmp_target, target)
    return target


def is_stale() -> bool:
    """True when the in-place extension is missing or was built from other inputs (checkout only)."""
    suffix = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
    if not (PKG / ("_native" + suffix)).exists() or not STAMP.exists():
        return True
    return STAMP.read_text().strip() != inputs_digest()


if __name__ == "__main__":
    path = build(verbose="-v" in sys.argv)
    print(f"built {path.relative_to(ROOT)}")

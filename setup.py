"""Build hooks of the attica package (the metadata is in pyproject.toml).

- ``build_ext`` compiles the firmware (firmware/src/**/*.c) and the host kernels (host/attica/csrc/*.c)
  with exactly the flags of firmware/cflags.txt, then builds the cffi wrapper ``attica._native``
  (Python's flags apply to the wrapper only) and links the objects into it.
- ``build_py`` copies the firmware tree into the package as ``attica/_firmware`` (sources, headers,
  cflags.txt, the DBC, ports), found at run time through importlib.resources (``attica paths``).
- The version is the one of firmware/include/attica/att_version.h.

The steps live in host/attica/_build.py and host/attica/_version.py (standard library only), loaded
here by path because the package itself is not importable in the build environment.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path
from typing import Any

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent


def _load(name: str) -> Any:
    spec = importlib.util.spec_from_file_location(f"attica_{name}", HERE / "host" / "attica" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


_build = _load("_build")
_version = _load("_version")
VERSION = "{}.{}.{}".format(*_version.parse_version_header(_build.VERSION_HEADER.read_text()))


class BuildPy(build_py):
    """Also copy the firmware tree into the package (``attica/_firmware``)."""

    def run(self) -> None:
        super().run()
        if not self.editable_mode:
            _build.copy_firmware(Path(self.build_lib) / "attica" / _build.FIRMWARE_DATA)


class BuildExt(build_ext):
    """Compile the firmware with firmware/cflags.txt, then the cffi wrapper of ``attica._native``."""

    def build_extension(self, ext: Extension) -> None:
        if ext.name != "attica._native":
            super().build_extension(ext)
            return
        temp = Path(self.build_temp) / "attica"
        objs = _build.compile_objects(os.environ.get("CC", "cc"), build_dir=temp / "objects")
        ffi = _build.make_ffi(objs)
        source = temp / "_native.c"
        ffi.emit_c_code(str(source))
        ext.sources = [str(source)]
        ext.include_dirs = [str(p) for p in _build.include_dirs()]
        ext.extra_objects = [str(o) for o in objs]
        super().build_extension(ext)


setup(
    version=VERSION,
    ext_modules=[
        Extension("attica._native", sources=["host/attica/csrc/att_host.c"]),
        # the CPython method behind Filter.update (Python's flags; it calls attica._native's step)
        Extension("attica._live", sources=["host/attica/csrc/py/att_live.c"]),
    ],
    cmdclass={"build_py": BuildPy, "build_ext": BuildExt},
)

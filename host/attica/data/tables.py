"""Text tables of dataset and phone exports: files in a folder or a zip, delimiters, decimal commas.

:class:`Bundle` lists the files of a folder (recursively) or a ``.zip`` archive and finds them by
name, case-insensitively. :func:`parse` reads one CSV text: the first non-empty line is the header
(a leading ``#``, as in EuRoC's, is dropped; names may be quoted), the delimiter is a semicolon or tab
when the header has one, else a comma; with a semicolon or tab, a comma inside a number is a decimal
comma (phyphox's and spreadsheets' "decimal comma" exports). Later lines starting with ``#`` are
comments. :class:`Table` converts columns: times exactly (int64) when every value is an integer,
values as float64 with empty cells as NaN, and a clear error naming the file, column and row for text
that is not a number.
"""

from __future__ import annotations

import csv
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

import numpy as np
from numpy.typing import NDArray

from attica.data.streams import RecordingError

_INT = re.compile(r"^[+-]?\d+$")


class Bundle:
    """The files of a folder or a zip archive (``__MACOSX`` and hidden files left out).

    Parameters
    ----------
    path : Path
        A folder, a ``.zip`` file, or a single file (a bundle of one).

    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self.zip: zipfile.ZipFile | None = None
        if path.is_dir():
            names = [str(f.relative_to(path).as_posix()) for f in path.rglob("*") if f.is_file()]
        elif zipfile.is_zipfile(path):
            self.zip = zipfile.ZipFile(path)
            names = [n for n in self.zip.namelist() if not n.endswith("/")]
        else:
            names = [path.name]
        self.names = sorted(
            n for n in names if not any(part.startswith((".", "__MACOSX")) for part in PurePosixPath(n).parts)
        )

    def close(self) -> None:
        """Close the archive."""
        if self.zip is not None:
            self.zip.close()

    def __enter__(self) -> Bundle:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def find(self, *basenames: str, under: str = "") -> list[str]:
        """Files whose name (without folder, case-insensitive) is one of ``basenames``, below ``under``."""
        wanted = {b.lower() for b in basenames}
        prefix = f"{under.strip('/')}/" if under.strip("/") else ""
        return [n for n in self.names if PurePosixPath(n).name.lower() in wanted and n.startswith(prefix)]

    def one(self, *basenames: str) -> str | None:
        """The one file named so; None when there is none, a RecordingError when there are several."""
        found = self.find(*basenames)
        if len(found) > 1:
            raise RecordingError(
                f"{self.path}: {len(found)} files named {basenames[0]} ({', '.join(found[:4])}); "
                "give the folder of one recording"
            )
        return found[0] if found else None

    def label(self, name: str) -> str:
        """How a file of the bundle is named in messages."""
        if self.path.is_file() and self.zip is None:
            return str(self.path)
        return f"{self.path.name}/{name}" if self.zip is None else f"{self.path.name}:{name}"

    def text(self, name: str) -> str:
        """The file's text (UTF-8, with or without BOM; Latin-1 when it is not UTF-8)."""
        if self.zip is not None:
            raw = self.zip.read(name)
        elif self.path.is_dir():
            raw = (self.path / name).read_bytes()
        else:
            raw = self.path.read_bytes()
        try:
            return raw.decode("utf-8-sig")
        except UnicodeDecodeError:
            return raw.decode("latin-1")

    def table(self, name: str) -> Table:
        """The file parsed by :func:`parse`."""
        return parse(self.text(name), self.label(name))


@dataclass
class Table:
    """A parsed CSV: its source, header names (stripped) and rows of cells (strings)."""

    source: str
    header: list[str]
    rows: list[list[str]]

    def __len__(self) -> int:
        return len(self.rows)

    def column(self, j: int) -> list[str]:
        """Cells of column ``j`` (empty for short rows)."""
        return [r[j] if j < len(r) else "" for r in self.rows]

    def floats(self, j: int) -> NDArray[np.float64]:
        """Column ``j`` as float64, empty cells NaN."""
        cells = [c if c else "nan" for c in self.column(j)]
        try:
            return np.array(cells, dtype=np.str_).astype(np.float64) if cells else np.zeros(0)
        except ValueError:
            for i, c in enumerate(cells):
                try:
                    float(c)
                except ValueError:
                    raise RecordingError(
                        f"{self.source}: row {i + 2}, column {self.header[j]!r}: {c!r} is not a number"
                    ) from None
            raise

    def times(self, j: int) -> NDArray[np.int64] | NDArray[np.float64]:
        """Column ``j`` as int64 when every cell is an integer (exact ns stamps), else float64."""
        cells = self.column(j)
        if cells and all(_INT.match(c) for c in cells):
            return np.array([int(c) for c in cells], dtype=np.int64)
        values = self.floats(j)
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise RecordingError(
                f"{self.source}: row {int(bad[0]) + 2}: the time {self.header[j]!r} is empty"
            )
        return values


def _delimiter(header: str) -> str:
    for d in (";", "\t"):
        if d in header:
            return d
    return ","


def parse(text: str, source: str) -> Table:
    """Parse a CSV text (the module docstring); a RecordingError for an empty one."""
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if not lines:
        raise RecordingError(f"{source}: empty file")
    delim = _delimiter(lines[0])
    header_line = lines[0].lstrip().removeprefix("#")
    body = [ln for ln in lines[1:] if not ln.lstrip().startswith("#")]
    header = [h.strip() for h in next(csv.reader([header_line], delimiter=delim))]
    rows = [[c.strip() for c in r] for r in csv.reader(body, delimiter=delim)]
    if delim != ",":
        rows = [[c.replace(",", ".") for c in r] for r in rows]
    return Table(source, header, rows)

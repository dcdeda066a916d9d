"""Loading .csv recordings (columns t, gyr_*, acc_*, mag_*, quat_*, movement; see attica.data)."""

from __future__ import annotations

import csv
import io
import math
import re
import warnings
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from attica.data import timing
from attica.data.recording import _ACC, _GYR, _MAG, _QUAT, CSV_COLUMNS, PathLike, Recording

_RATE_TOLERANCE = 0.01

_TIME_NAME = re.compile(r"^(t|time|timestamp|stamp)([ _\[(].*)?$")


def _time_column(header: list[str]) -> str | None:
    """The time column: ``t``, ``time``, ``timestamp`` or ``stamp``, with an optional unit suffix."""
    for name in header:
        if _TIME_NAME.match(name):
            return name
    return None


def _parse_bool(text: str) -> float:
    s = text.strip().lower()
    if s in ("1", "true", "t", "yes", "1.0"):
        return 1.0
    if s in ("0", "false", "f", "no", "0.0"):
        return 0.0
    raise ValueError(f"movement value {text!r} is not 0/1/true/false")


def _fast_table(body: str, ncols: int, usecols: list[int], mov_pos: int | None) -> NDArray[np.float64] | None:
    """Plain numeric CSV body through numpy's C parser; None if it needs the careful parser."""
    if not body.strip():
        return np.zeros((0, len(usecols)), np.float64)
    first = next((ln for ln in body.splitlines() if ln.strip() and not ln.lstrip().startswith("#")), "")
    if len(next(csv.reader([first]))) != ncols:
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            table = np.loadtxt(
                io.StringIO(body),
                delimiter=",",
                comments="#",
                quotechar='"',
                usecols=usecols,
                ndmin=2,
                dtype=np.float64,
            )
    except ValueError:
        return None
    if table.shape[1] != len(usecols):
        return None
    if mov_pos is not None and not np.all(np.isin(table[:, mov_pos], (0.0, 1.0))):
        return None
    return table


def _slow_table(
    p: Path, body: str, body_start: int, header: list[str], usecols: list[int], mov_j: int | None
) -> NDArray[np.float64]:
    """Row-by-row parse: empty fields become NaN, ``true``/``false`` movement, errors name the line."""
    rows: list[list[float]] = []
    for k, row in enumerate(csv.reader(io.StringIO(body))):
        lineno = body_start + k + 1
        if not row or (len(row) == 1 and not row[0].strip()) or row[0].lstrip().startswith("#"):
            continue
        if len(row) != len(header):
            raise ValueError(f"{p}:{lineno}: {len(row)} fields, header has {len(header)}")
        values: list[float] = []
        for j in usecols:
            s = row[j].strip()
            try:
                if j == mov_j:
                    values.append(_parse_bool(s))
                else:
                    values.append(float(s) if s else math.nan)
            except ValueError:
                raise ValueError(f"{p}:{lineno}: column {header[j]}: cannot parse {row[j]!r}") from None
        rows.append(values)
    return np.array(rows, dtype=np.float64).reshape(len(rows), len(usecols))


def load_csv(path: PathLike) -> Recording:
    """Load a ``.csv`` recording (columns and comment lines as in the module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        File to read.

    Returns
    -------
    Recording
        The recording; ``name`` defaults to the file stem.

    Raises
    ------
    ValueError
        No header, missing required columns, incomplete column groups, unparsable values,
        no usable rate or a ``t`` column that disagrees with the ``# rate=`` line.

    """
    p = Path(path)
    text = p.read_text(encoding="utf-8")
    meta: dict[str, str] = {}
    header: list[str] | None = None
    body_start = 0
    lines = text.splitlines()
    for i, line in enumerate(lines):
        s = line.strip()
        if not s:
            continue
        if s.startswith("#"):
            key, sep, value = s[1:].partition("=")
            if sep:
                meta[key.strip().lower()] = value.strip()
            continue
        header = [c.strip().lower() for c in next(csv.reader([s]))]
        body_start = i + 1
        break
    if header is None:
        raise ValueError(f"{p}: no header row (expected columns like {', '.join(_GYR + _ACC)})")
    dup = sorted({c for c in header if header.count(c) > 1 and c})
    if dup:
        raise ValueError(f"{p}: duplicate column(s) {', '.join(dup)}")
    col = {name: j for j, name in enumerate(header)}
    missing = [c for c in _GYR + _ACC if c not in col]
    if missing:
        raise ValueError(f"{p}: missing column(s) {', '.join(missing)}; header: {', '.join(header)}")
    for group in (_MAG, _QUAT):
        present = [c for c in group if c in col]
        if present and len(present) != len(group):
            raise ValueError(
                f"{p}: columns {', '.join(group)} must be given all together, got {', '.join(present)}"
            )

    body = "\n".join(lines[body_start:])
    tcol = _time_column(header)
    known = [c for c in CSV_COLUMNS if c in col and c != "t"]  # other columns are ignored
    if tcol is not None:
        known.insert(0, tcol)
    usecols = [col[c] for c in known]
    pos = {c: i for i, c in enumerate(known)}  # column of the table
    mov_j = col.get("movement")
    table = _fast_table(body, len(header), usecols, pos.get("movement"))
    if table is None:
        table = _slow_table(p, body, body_start, header, usecols, mov_j)

    def cols(names: tuple[str, ...]) -> NDArray[np.float64]:
        assert table is not None
        return table[:, [pos[c] for c in names]]

    f32_max = float(np.finfo(np.float32).max)
    for group in (_GYR, _ACC):
        bad = ~np.isfinite(cols(group))
        if bad.any():
            r = int(np.flatnonzero(bad.any(axis=1))[0])
            raise ValueError(f"{p}: data row {r + 1}: empty or non-finite value in {', '.join(group)}")
    for group in (_GYR, _ACC, _MAG):
        if group[0] not in col:
            continue
        with np.errstate(invalid="ignore"):
            big = np.abs(cols(group)) > f32_max  # would become Inf as float32 (NaN: absent mag, allowed)
        if big.any():
            r = int(np.flatnonzero(big.any(axis=1))[0])
            raise ValueError(f"{p}: data row {r + 1}: value beyond the float32 range in {', '.join(group)}")

    rate: float | None = None
    if "rate" in meta:
        try:
            rate = float(meta["rate"])
        except ValueError:
            raise ValueError(f"{p}: cannot parse '# rate={meta['rate']}'") from None
        if not math.isfinite(rate) or rate <= 0.0:
            raise ValueError(f"{p}: rate must be finite and > 0, got {meta['rate']}")
    time: NDArray[np.float64] | None = None
    clk: timing.Clock | None = None
    if tcol is not None:
        unit = meta.get("time_unit")
        try:
            clk = timing.clock(
                table[:, pos[tcol]],
                unit=unit,
                rate=rate,
                name=tcol,
                source=f"{p.name} {tcol}",
                default_unit="s",
            )
        except ValueError as exc:
            raise ValueError(f"{p}: {exc}") from None
        rate_t = clk.timing.rate if rate is None else 1.0 / float(np.median(np.diff(clk.time)))
        if rate is None:
            rate = rate_t
        elif abs(rate_t - rate) > _RATE_TOLERANCE * rate:
            raise ValueError(f"{p}: '# rate={meta['rate']}' disagrees with column {tcol} ({rate_t:.6g} Hz)")
        table = table[clk.keep]
        time = clk.time
    if rate is None:
        raise ValueError(f"{p}: no sampling rate: add a '# rate=<Hz>' line or a t column with >= 2 rows")

    groups = tuple(g.strip() for g in meta.get("groups", "").split(";") if g.strip())
    try:
        rec = Recording(
            gyr=cols(_GYR).astype(np.float32),
            acc=cols(_ACC).astype(np.float32),
            mag=(cols(_MAG) if _MAG[0] in col else np.full((table.shape[0], 3), np.nan)).astype(np.float32),
            rate=rate,
            quat_true=cols(_QUAT) if _QUAT[0] in col else None,
            movement=table[:, pos["movement"]].astype(np.bool_) if "movement" in pos else None,
            name=meta.get("name", p.stem),
            groups=groups,
            time=time,
            timing=clk.timing if clk is not None else None,
        )
    except ValueError as exc:
        raise ValueError(f"{p}: {exc}") from None
    if clk is not None:
        timing.report(clk.timing)
    return rec

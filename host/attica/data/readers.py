"""Which reader a recording file needs, and reading any of them with a description of its contents.

:func:`detect` names the format of a path, by suffix and, for folders, zips and ``.csv`` files, by
what is inside:

==========================================================  ============  ===============================
path                                                        format        reader
==========================================================  ============  ===============================
``.npz``                                                    ``npz``       :func:`attica.data.load_npz`
``.hdf5``, ``.h5``, ``.mat``                                ``broad``     :func:`attica.data.load_broad`
``.csv`` with attica's columns                              ``csv``       :func:`attica.data.load_csv`
``.bag``, ``.db3``, a folder with ``metadata.yaml``         ``rosbag``    :mod:`attica.data.rosbag`
``.mcap``                                                   ``mcap``      :mod:`attica.data.mcapfile`
``.ulg``                                                    ``ulog``      :mod:`attica.data.ulog`
a folder/zip with ``imu0/data.csv``, an ASL ``data.csv``    ``euroc``     :mod:`attica.data.euroc`
a folder/zip/``.csv`` with phyphox's columns                ``phyphox``   :mod:`attica.data.phyphox`
another folder/zip of per-sensor CSVs (Sensor Logger ...)   ``phone``     :mod:`attica.data.phone`
==========================================================  ============  ===============================

:func:`read_recording` returns the recording and its :class:`~attica.data.streams.Contents` (what
``attica info`` prints), without emitting warnings; :func:`load` emits them (what
:func:`attica.data.load_recording` does).
"""

from __future__ import annotations

import warnings
import zipfile
from collections.abc import Callable
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np

from attica.data.recording import PathLike, Recording
from attica.data.streams import Contents, RecordingError, Stream, median_rate, report

__all__ = ["FORMATS", "detect", "load", "read_recording"]

FORMATS = ("npz", "broad", "csv", "rosbag", "mcap", "ulog", "euroc", "phyphox", "phone")
"""The formats :func:`detect` tells apart."""

_SUFFIX = {
    ".npz": "npz",
    ".hdf5": "broad",
    ".h5": "broad",
    ".mat": "broad",
    ".bag": "rosbag",
    ".db3": "rosbag",
    ".mcap": "mcap",
    ".ulg": "ulog",
}


def _first_line(data: bytes) -> str:
    text = data[:4096].decode("utf-8-sig", errors="replace")
    return next((ln for ln in text.splitlines() if ln.strip()), "")


def _head(path: Path) -> bytes:
    with open(path, "rb") as f:
        return f.read(4096)


def _by_files(names: list[str], first_line: Callable[[str], str]) -> str:
    """euroc, phyphox or phone, from the file names of a folder or zip (and CSV headers)."""
    from attica.data.euroc import is_euroc_header
    from attica.data.phyphox import is_phyphox_header

    posix = [PurePosixPath(n) for n in names]
    if any(n.name.lower() == "data.csv" and n.parent.name == "imu0" for n in posix):
        return "euroc"
    csvs = [str(n) for n in posix if n.suffix.lower() == ".csv" and n.parts[0].lower() != "meta"]
    if not csvs:
        raise RecordingError("no CSV files")
    heads = [first_line(n) for n in csvs[:20]]
    if any(is_phyphox_header(h) for h in heads):
        return "phyphox"
    if any(is_euroc_header(h) for h in heads):
        return "euroc"
    return "phone"


def detect(path: PathLike) -> str:
    """The format of a recording path (one of :data:`FORMATS`).

    Raises
    ------
    FileNotFoundError
        If nothing is there.
    ValueError
        A suffix or folder attica does not read, or an empty file.

    """
    p = Path(path)
    if not p.exists():
        if p.suffix and p.suffix.lower() not in _SUFFIX and p.suffix.lower() not in (".zip", ".csv"):
            raise RecordingError(f"{p}: unknown suffix {p.suffix!r} (and no such file)")
        raise FileNotFoundError(f"{p}: no such file or folder")
    if p.is_dir():
        if (p / "metadata.yaml").is_file():
            return "rosbag"
        if p.name.lower() == "imu0" and (p / "data.csv").is_file():
            return "euroc"
        files = [f for f in sorted(p.rglob("*")) if f.is_file() and not f.name.startswith(".")]
        try:
            return _by_files(
                [f.relative_to(p).as_posix() for f in files], lambda n: _first_line(_head(p / n))
            )
        except RecordingError:
            raise RecordingError(
                f"{p}: a folder attica does not read (no metadata.yaml, imu0/data.csv or sensor CSV files)"
            ) from None
    suffix = p.suffix.lower()
    if p.stat().st_size == 0:
        raise RecordingError(f"{p}: empty file")
    if suffix in _SUFFIX:
        return _SUFFIX[suffix]
    if suffix == ".zip":
        try:
            with zipfile.ZipFile(p) as z:
                names = [n for n in z.namelist() if not n.endswith("/") and "__MACOSX" not in n]
                return _by_files(names, lambda n: _first_line(z.read(n)))
        except zipfile.BadZipFile:
            raise RecordingError(f"{p}: not a readable zip file") from None
        except RecordingError:
            raise RecordingError(f"{p}: a zip without imu0/data.csv or sensor CSV files") from None
    if suffix == ".csv":
        from attica.data.euroc import is_euroc_header
        from attica.data.phyphox import is_phyphox_header

        head = _first_line(_head(p))
        if is_euroc_header(head):
            return "euroc"
        if is_phyphox_header(head):
            return "phyphox"
        if "seconds_elapsed" in head:
            raise RecordingError(f"{p}: one sensor of a Sensor Logger export; give its folder or .zip")
        return "csv"
    raise RecordingError(
        f"{p}: unknown suffix {p.suffix!r}; attica reads .npz, .csv, .hdf5, .h5, .mat, .bag, .db3, .mcap, "
        ".ulg, .zip and folders (ROS 2 bags, EuRoC, phone exports)"
    )


def _readers() -> dict[str, Callable[..., tuple[Recording, Contents]]]:
    from attica.data.euroc import read_euroc
    from attica.data.mcapfile import read_mcap
    from attica.data.phone import read_phone
    from attica.data.phyphox import read_phyphox
    from attica.data.rosbag import read_rosbag
    from attica.data.ulog import read_ulog

    return {
        "rosbag": read_rosbag,
        "mcap": read_mcap,
        "ulog": read_ulog,
        "euroc": read_euroc,
        "phyphox": read_phyphox,
        "phone": read_phone,
    }


_ATTICA_FORMATS = {"npz": "attica/BROAD .npz", "broad": "BROAD (original)", "csv": "attica .csv"}


def _attica_file(p: Path, fmt: str) -> tuple[Recording, Contents]:
    from attica.data.broad import load_broad
    from attica.data.csvfile import load_csv
    from attica.data.npz import load_npz

    loader = {"npz": load_npz, "broad": load_broad, "csv": load_csv}[fmt]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rec = loader(p)
    timing_msgs = set(rec.timing.warnings()) if rec.timing is not None else set()
    warns = tuple(str(w.message) for w in caught if str(w.message) not in timing_msgs)
    t = rec.time if rec.time is not None else rec.t
    rate = median_rate(t) if rec.n > 1 else None
    streams = [
        Stream("gyr", "gyroscope", rec.n, rate, "gyr"),
        Stream("acc", "accelerometer", rec.n, rate, "acc"),
    ]
    if rec.has_mag:
        count = int(np.count_nonzero(np.isfinite(rec.mag).all(axis=1)))
        streams.append(Stream("mag", "magnetometer", count, None, "mag"))
    notes = ("units and frames as attica's (see attica.data)",)
    return rec, Contents(p, _ATTICA_FORMATS[fmt], tuple(streams), notes, warns)


def read_recording(path: PathLike, **options: Any) -> tuple[Recording, Contents]:
    """Read any recording attica knows (:func:`detect`), with a description of the file.

    Parameters
    ----------
    path : str or os.PathLike
        File or folder.
    **options
        The format's reader options (``topic=``, ``mag_topic=``, ``orientation=``, ``frd=`` for bags
        and MCAP; ``mag=``, ``attitude=`` for ULog; ``truth=`` for EuRoC). attica's own formats take
        none.

    Returns
    -------
    recording : Recording
    contents : Contents
        Format, streams, notes, warnings (the timing ones are in ``recording.timing``). Nothing is
        emitted as a warning.

    Raises
    ------
    FileNotFoundError, ValueError, ImportError, TypeError
        A missing path; an unknown, empty or corrupt file (the message names it); a missing optional
        package (the message says ``pip install 'attica[recordings]'``); an option the format does not
        take.

    """
    p = Path(path)
    fmt = detect(p)
    if fmt in _ATTICA_FORMATS:
        if options:
            raise TypeError(f"{p}: {_ATTICA_FORMATS[fmt]} files take no options (got {', '.join(options)})")
        return _attica_file(p, fmt)
    reader = _readers()[fmt]
    try:
        return reader(p, **options)
    except TypeError as exc:
        if "unexpected keyword" in str(exc):
            raise TypeError(f"{p}: the {fmt} reader takes no option {exc.args[0].split()[-1]}") from None
        raise


def load(path: PathLike, **options: Any) -> Recording:
    """:func:`read_recording`'s recording, the timing and reader problems emitted as TimingWarnings."""
    rec, contents = read_recording(path, **options)
    report(rec, contents)
    return rec

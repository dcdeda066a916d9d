"""IMU recordings: the :class:`Recording` container and its ``.npz`` / ``.csv`` loaders.

Units and frames (the whole project uses them): gyroscope in rad/s, accelerometer as specific force in
m/s^2 (reads about +g on the up axis at rest), magnetometer in uT, all in the sensor frame; quaternions
``(w, x, y, z)`` sensor-to-earth with an ENU earth frame (x east, y north, z up).

``.npz`` files use the layout of the BROAD benchmark (Laidig et al., Data 6(7), 2021), so BROAD trials
load directly and our own files round-trip:

===============  ========  ==========================================================================
key              shape     meaning
===============  ========  ==========================================================================
``gyr``          (N, 3)    angular rate, rad/s (required)
``acc``          (N, 3)    specific force, m/s^2 (required)
``mag``          (N, 3)    magnetic field, uT (optional; NaN rows = no sample)
``opt_quat``     (N, 4)    ground truth ``w, x, y, z`` sensor-to-ENU (optional; NaN rows = unknown)
``movement``     (N,)      bool, samples that count for the error metrics (optional)
``sampling_rate`` ()       Hz (required)
``name``         ()        str (optional)
``groups``       (G,)      str (optional)
===============  ========  ==========================================================================

Sensor data is stored as float64 (as in BROAD) and loaded as float32, the type the firmware eats;
``opt_quat`` stays float64. Files are read with ``allow_pickle=False``.

``.csv`` files: optional comment lines starting with ``#`` (``# rate=285.714``, ``# name=trial 1``,
``# groups=a;b``), then one header row of comma-separated column names, then one row per sample.
Columns (any order, names case-insensitive):

- ``t`` (optional): time in s; used for the rate when there is no ``# rate=`` line
  (rate = 1 / median(diff(t))); when both are given they must agree within 1 %.
- ``gyr_x, gyr_y, gyr_z`` (required), ``acc_x, acc_y, acc_z`` (required).
- ``mag_x, mag_y, mag_z`` (optional, all three or none; empty fields or ``nan`` = no sample).
- ``quat_w, quat_x, quat_y, quat_z`` (optional, all four or none; empty or ``nan`` = unknown).
- ``movement`` (optional): ``0``/``1`` or ``false``/``true``.

Other columns are ignored. :meth:`Recording.save` writes this format for a ``.csv`` path.

Original BROAD files (as downloaded from the dataset's repository, ``data_hdf5/*.hdf5`` and
``data_mat/*.mat``) load too, through optional packages (``pip install '.[eval]'``: h5py for
``.hdf5``/``.h5``, scipy for ``.mat``; a clear ImportError names the package when it is missing). Both hold
the same arrays:

================  ==========  ==============================================================================
key               shape       meaning
================  ==========  ==============================================================================
``imu_gyr``       (N, 3)      angular rate, rad/s
``imu_acc``       (N, 3)      specific force, m/s^2
``imu_mag``       (N, 3)      magnetic field, uT
``opt_quat``      (N, 4)      ground truth ``w, x, y, z`` sensor-to-ENU (NaN where tracking was lost)
``movement``      (N,)/(N,1)  1 for the samples that count for the error metrics
``sampling_rate`` scalar      Hz (285.714 for BROAD)
================  ==========  ==============================================================================

The name is the file stem. The groups come from a ``trials.json`` next to the file (BROAD ships one in
``data_mat/``) when it lists the trial, otherwise from the name (:func:`broad_groups`).
"""

from __future__ import annotations

import csv
import io
import math
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "Recording",
    "load_recording",
    "load_npz",
    "load_csv",
    "load_broad",
    "broad_groups",
    "NPZ_REQUIRED",
    "CSV_COLUMNS",
    "BROAD_KEYS",
]

PathLike = str | os.PathLike[str]

NPZ_REQUIRED = ("gyr", "acc", "sampling_rate")
"""Keys a ``.npz`` recording must have; the others (``mag``, ``opt_quat``, ...) are optional."""

_GYR = ("gyr_x", "gyr_y", "gyr_z")
_ACC = ("acc_x", "acc_y", "acc_z")
_MAG = ("mag_x", "mag_y", "mag_z")
_QUAT = ("quat_w", "quat_x", "quat_y", "quat_z")
CSV_COLUMNS = ("t", *_GYR, *_ACC, *_MAG, *_QUAT, "movement")
"""All column names the CSV loader understands (see the module docstring)."""

_RATE_TOLERANCE = 0.01


def _array(value: Any, what: str, dtype: Any, width: int | None) -> NDArray[Any]:
    try:
        arr = np.array(value, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what}: cannot convert to {np.dtype(dtype).name}: {exc}") from None
    if width is None:
        if arr.ndim != 1:
            raise ValueError(f"{what}: expected shape (N,), got {arr.shape}")
    elif arr.ndim != 2 or arr.shape[1] != width:
        raise ValueError(f"{what}: expected shape (N, {width}), got {arr.shape}")
    return arr


@dataclass
class Recording:
    """One IMU recording: sensor samples at a fixed rate, optional ground truth.

    Arrays are converted on construction (sensor data to float32, ``quat_true`` to float64,
    ``movement`` to bool) and checked for consistent shapes; a ``ValueError`` names the offending field.

    Attributes
    ----------
    gyr : ndarray, float32, shape (N, 3)
        Angular rate in rad/s, sensor frame.
    acc : ndarray, float32, shape (N, 3)
        Specific force in m/s^2, sensor frame (+g on the up axis at rest).
    mag : ndarray, float32, shape (N, 3)
        Magnetic field in uT, sensor frame; NaN rows mean no sample. ``None`` on construction gives all NaN.
    rate : float
        Sampling rate in Hz, finite and > 0.
    quat_true : ndarray, float64, shape (N, 4), or None
        Ground truth ``w, x, y, z`` sensor-to-ENU; NaN rows where unknown.
    movement : ndarray, bool, shape (N,), or None
        Samples that count for the error metrics.
    name : str
        Trial name.
    groups : tuple of str
        Group labels (BROAD: ``undisturbed``, ``rotation``, ``tapping`` ...).

    """

    gyr: NDArray[np.float32]
    acc: NDArray[np.float32]
    mag: NDArray[np.float32]
    rate: float
    quat_true: NDArray[np.float64] | None = None
    movement: NDArray[np.bool_] | None = None
    name: str = ""
    groups: tuple[str, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        self.gyr = _array(self.gyr, "gyr", np.float32, 3)
        n = self.gyr.shape[0]
        self.acc = _array(self.acc, "acc", np.float32, 3)
        if self.mag is None:
            self.mag = np.full((n, 3), np.nan, np.float32)
        self.mag = _array(self.mag, "mag", np.float32, 3)
        try:
            rate = float(self.rate)
        except (TypeError, ValueError):
            raise ValueError(f"rate: expected a number, got {self.rate!r}") from None
        if not math.isfinite(rate) or rate <= 0.0:
            raise ValueError(f"rate: must be finite and > 0, got {rate}")
        self.rate = rate
        if self.quat_true is not None:
            self.quat_true = _array(self.quat_true, "quat_true", np.float64, 4)
        if self.movement is not None:
            mov = np.asarray(self.movement)
            if mov.dtype != np.bool_:
                if mov.dtype.kind not in "iuf" or not np.all(np.isin(mov, (0, 1))):
                    raise ValueError("movement: expected booleans (or 0/1)")
            self.movement = _array(mov, "movement", np.bool_, None)
        self.name = str(self.name)
        self.groups = tuple(str(g) for g in self.groups)
        for what, arr in (("acc", self.acc), ("mag", self.mag), ("quat_true", self.quat_true)):
            if arr is not None and arr.shape[0] != n:
                raise ValueError(f"{what}: {arr.shape[0]} samples, but gyr has {n}")
        if self.movement is not None and self.movement.shape[0] != n:
            raise ValueError(f"movement: {self.movement.shape[0]} samples, but gyr has {n}")

    def __len__(self) -> int:
        return int(self.gyr.shape[0])

    @property
    def n(self) -> int:
        """Number of samples."""
        return len(self)

    @property
    def dt(self) -> float:
        """Sample period in s (``1 / rate``)."""
        return 1.0 / self.rate

    @property
    def t(self) -> NDArray[np.float64]:
        """Time of each sample in s, starting at 0 (``arange(n) / rate``)."""
        return np.arange(self.n, dtype=np.float64) / self.rate

    @property
    def has_mag(self) -> bool:
        """Whether any magnetometer sample is present (not NaN)."""
        return bool(np.any(np.isfinite(self.mag).all(axis=1)))

    def save(self, path: PathLike) -> None:
        """Write the recording to ``path``: ``.npz`` (BROAD layout) or ``.csv`` (see the module docstring).

        Parameters
        ----------
        path : str or os.PathLike
            Destination; its suffix selects the format. Parent directories must exist.

        Raises
        ------
        ValueError
            For an unknown suffix.

        """
        p = Path(path)
        suffix = p.suffix.lower()
        if suffix == ".npz":
            self._save_npz(p)
        elif suffix == ".csv":
            self._save_csv(p)
        else:
            raise ValueError(f"{p}: unknown suffix {p.suffix!r}; use .npz or .csv")

    def _save_npz(self, path: Path) -> None:
        n = self.n
        arrays: dict[str, Any] = {
            "gyr": self.gyr.astype(np.float64),
            "acc": self.acc.astype(np.float64),
            "mag": self.mag.astype(np.float64),
            "sampling_rate": np.float64(self.rate),
            "name": np.str_(self.name),
            "groups": np.array(self.groups, dtype=str) if self.groups else np.zeros(0, dtype="<U1"),
        }
        if self.quat_true is not None:
            arrays["opt_quat"] = self.quat_true
        if self.movement is not None:
            arrays["movement"] = self.movement
        assert all(np.ndim(v) == 0 or np.shape(v)[0] == n for k, v in arrays.items() if k != "groups")
        with open(path, "wb") as f:  # a file object: numpy must not append another ".npz"
            np.savez(f, **arrays)

    def _save_csv(self, path: Path) -> None:
        cols: list[NDArray[Any]] = [self.t, self.gyr, self.acc]
        names: list[str] = ["t", *_GYR, *_ACC]
        fmts: list[str] = ["%.9f"] + ["%.9g"] * 6
        if self.has_mag:
            cols.append(self.mag)
            names += _MAG
            fmts += ["%.9g"] * 3
        if self.quat_true is not None:
            cols.append(self.quat_true)
            names += _QUAT
            fmts += ["%.17g"] * 4
        if self.movement is not None:
            cols.append(self.movement.astype(np.int64))
            names.append("movement")
            fmts.append("%d")
        table = np.column_stack([np.asarray(c, dtype=np.float64) for c in cols])
        header = [f"# rate={self.rate!r}"]
        if self.name:
            header.append(f"# name={self.name}")
        if self.groups:
            header.append(f"# groups={';'.join(self.groups)}")
        with open(path, "w", encoding="utf-8", newline="\n") as f:
            f.write("\n".join(header) + "\n" + ",".join(names) + "\n")
            np.savetxt(f, table, fmt=fmts, delimiter=",")


def load_recording(path: PathLike) -> Recording:
    """Load a recording from a ``.npz`` (BROAD layout) or ``.csv`` file, chosen by suffix.

    Parameters
    ----------
    path : str or os.PathLike
        File to read.

    Returns
    -------
    Recording
        Sensor data as float32, ground truth as float64.

    Raises
    ------
    ValueError
        Unknown suffix, missing keys or columns, wrong shapes, inconsistent lengths or a bad rate.
    FileNotFoundError
        If the file does not exist.
    ImportError
        For ``.hdf5``/``.h5`` without h5py or ``.mat`` without scipy.

    """
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix == ".npz":
        return load_npz(p)
    if suffix == ".csv":
        return load_csv(p)
    if suffix in (".hdf5", ".h5", ".mat"):
        return load_broad(p)
    raise ValueError(f"{p}: unknown suffix {p.suffix!r}; expected .npz, .csv, .hdf5, .h5 or .mat")


def load_npz(path: PathLike) -> Recording:
    """Load a ``.npz`` recording in the BROAD layout (see the module docstring).

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
        Missing required keys, wrong shapes or dtypes, inconsistent lengths or a bad rate.

    """
    p = Path(path)
    try:
        with np.load(p, allow_pickle=False) as d:
            data = {k: d[k] for k in d.files}
    except ValueError as exc:
        raise ValueError(f"{p}: not a readable .npz file ({exc})") from None
    except OSError as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        raise ValueError(f"{p}: not a readable .npz file ({exc})") from None
    missing = [k for k in NPZ_REQUIRED if k not in data]
    if missing:
        raise ValueError(
            f"{p}: missing key(s) {', '.join(missing)}; found {', '.join(sorted(data)) or 'none'}"
        )
    rate_arr = data["sampling_rate"]
    if rate_arr.size != 1 or rate_arr.dtype.kind not in "iuf":
        raise ValueError(f"{p}: sampling_rate must be a single number, got {rate_arr.dtype} {rate_arr.shape}")
    name = str(data["name"].item()) if "name" in data and data["name"].size == 1 else p.stem
    groups = tuple(str(g) for g in np.atleast_1d(data["groups"])) if "groups" in data else ()
    gyr = data["gyr"]
    mag = data["mag"] if "mag" in data else np.full((gyr.shape[0] if gyr.ndim else 0, 3), np.nan)
    try:
        return Recording(
            gyr=gyr,
            acc=data["acc"],
            mag=mag,
            rate=float(rate_arr.reshape(())),
            quat_true=data.get("opt_quat"),
            movement=data.get("movement"),
            name=name,
            groups=groups,
        )
    except ValueError as exc:
        raise ValueError(f"{p}: {exc}") from None


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
    known = [c for c in CSV_COLUMNS if c in col]  # other columns are ignored
    usecols = [col[c] for c in known]
    pos = {c: i for i, c in enumerate(known)}  # column of the table
    mov_j = col.get("movement")
    table = _fast_table(body, len(header), usecols, pos.get("movement"))
    if table is None:
        table = _slow_table(p, body, body_start, header, usecols, mov_j)

    def cols(names: tuple[str, ...]) -> NDArray[np.float64]:
        return table[:, [pos[c] for c in names]]

    for group in (_GYR, _ACC):
        bad = ~np.isfinite(cols(group))
        if bad.any():
            r = int(np.flatnonzero(bad.any(axis=1))[0])
            raise ValueError(f"{p}: data row {r + 1}: empty or non-finite value in {', '.join(group)}")

    rate: float | None = None
    if "rate" in meta:
        try:
            rate = float(meta["rate"])
        except ValueError:
            raise ValueError(f"{p}: cannot parse '# rate={meta['rate']}'") from None
        if not math.isfinite(rate) or rate <= 0.0:
            raise ValueError(f"{p}: rate must be finite and > 0, got {meta['rate']}")
    if "t" in pos:
        t = table[:, pos["t"]]
        if t.size >= 2:
            dt = np.diff(t)
            if not np.all(np.isfinite(dt)) or np.any(dt <= 0.0):
                raise ValueError(f"{p}: column t must be finite and strictly increasing")
            rate_t = 1.0 / float(np.median(dt))
            if rate is None:
                rate = rate_t
            elif abs(rate_t - rate) > _RATE_TOLERANCE * rate:
                raise ValueError(f"{p}: '# rate={meta['rate']}' disagrees with column t ({rate_t:.6g} Hz)")
    if rate is None:
        raise ValueError(f"{p}: no sampling rate: add a '# rate=<Hz>' line or a t column with >= 2 rows")

    groups = tuple(g.strip() for g in meta.get("groups", "").split(";") if g.strip())
    try:
        return Recording(
            gyr=cols(_GYR).astype(np.float32),
            acc=cols(_ACC).astype(np.float32),
            mag=(cols(_MAG) if _MAG[0] in col else np.full((table.shape[0], 3), np.nan)).astype(np.float32),
            rate=rate,
            quat_true=cols(_QUAT) if _QUAT[0] in col else None,
            movement=table[:, pos["movement"]].astype(np.bool_) if "movement" in pos else None,
            name=meta.get("name", p.stem),
            groups=groups,
        )
    except ValueError as exc:
        raise ValueError(f"{p}: {exc}") from None


BROAD_KEYS = ("imu_gyr", "imu_acc", "imu_mag", "opt_quat", "movement", "sampling_rate")
"""Arrays of an original BROAD ``.hdf5``/``.mat`` trial (``imu_mag``, ``opt_quat``, ``movement`` optional)."""

_BROAD_GROUP_WORDS = (
    ("undisturbed", "undisturbed"),
    ("rotation", "rotation"),
    ("translation", "translation"),
    ("combined", "combined"),
    ("slow", "slow"),
    ("fast", "fast"),
    ("tapping", "tapping"),
    ("vibration", "vibration"),
    ("stationary_magnet", "stationary_magnet"),
    ("attached_magnet", "attached_magnet"),
    ("office", "office_environment"),
    ("mixed", "mixed"),
)


def broad_groups(name: str) -> tuple[str, ...]:
    """BROAD's groups of a trial from its name, as the dataset's ``trials.json`` lists them.

    ``07_undisturbed_fast_rotation_B`` gives all_trials, undisturbed, rotation, fast, no_breaks.
    """
    words = name.lower()
    out = ["all_trials"]
    disturbed = "_disturbed" in words or words.startswith("disturbed")
    if disturbed:
        out.append("disturbed")
    for key, group in _BROAD_GROUP_WORDS:
        if key in words and not (key == "undisturbed" and disturbed):
            if group in ("slow", "fast") and disturbed:
                continue
            out.append(group)
    if not disturbed:
        out.append("with_breaks" if "with_breaks" in words else "no_breaks")
    return tuple(out)


def _trials_json_groups(path: Path) -> tuple[str, ...] | None:
    import json

    info = path.parent / "trials.json"
    if not info.is_file():
        return None
    try:
        trials = json.loads(info.read_text(encoding="utf-8")).get("trials", {})
        groups = trials.get(path.stem, {}).get("groups")
    except (ValueError, AttributeError):
        return None
    return tuple(str(g) for g in groups) if isinstance(groups, list) else None


def _read_hdf5(path: Path) -> dict[str, Any]:
    try:
        import h5py
    except ImportError:
        raise ImportError(f"{path}: reading .hdf5 needs h5py: pip install h5py (or '.[eval]')") from None
    out: dict[str, Any] = {}
    try:
        with h5py.File(path, "r") as f:
            for k in BROAD_KEYS:
                if k in f:
                    out[k] = np.array(f[k])
    except OSError as exc:
        raise ValueError(f"{path}: not a readable HDF5 file ({exc})") from None
    return out


def _read_mat(path: Path) -> dict[str, Any]:
    try:
        import scipy.io
    except ImportError:
        raise ImportError(f"{path}: reading .mat needs scipy: pip install scipy (or '.[eval]')") from None
    try:
        d = scipy.io.loadmat(path)
    except (ValueError, NotImplementedError, OSError) as exc:
        raise ValueError(f"{path}: not a readable .mat file ({exc})") from None
    return {k: np.asarray(d[k]) for k in BROAD_KEYS if k in d}


def load_broad(path: PathLike) -> Recording:
    """Load an original BROAD trial (``.hdf5``/``.h5`` with h5py, ``.mat`` with scipy).

    Parameters
    ----------
    path : str or os.PathLike
        File to read.

    Returns
    -------
    Recording
        Sensor data as float32, ``opt_quat`` as float64, ``movement`` as bool; name = file stem; groups
        from ``trials.json`` beside the file or from the name.

    Raises
    ------
    ImportError
        When h5py (``.hdf5``) or scipy (``.mat``) is not installed.
    ValueError
        Unreadable file, missing ``imu_gyr``/``imu_acc``/``sampling_rate``, or bad shapes.

    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(p)
    data = _read_mat(p) if p.suffix.lower() == ".mat" else _read_hdf5(p)
    missing = [k for k in ("imu_gyr", "imu_acc", "sampling_rate") if k not in data]
    if missing:
        raise ValueError(
            f"{p}: missing key(s) {', '.join(missing)}; found {', '.join(sorted(data)) or 'none'}"
        )
    rate_arr = np.asarray(data["sampling_rate"])
    if rate_arr.size != 1 or rate_arr.dtype.kind not in "iuf":
        raise ValueError(f"{p}: sampling_rate must be a single number, got {rate_arr.dtype} {rate_arr.shape}")
    gyr = np.asarray(data["imu_gyr"], dtype=np.float64)
    n = gyr.shape[0] if gyr.ndim == 2 else 0
    movement = None
    if "movement" in data:
        mov = np.asarray(data["movement"]).reshape(-1)
        movement = mov.astype(np.bool_) if mov.dtype.kind in "biuf" else mov
    try:
        return Recording(
            gyr=gyr.astype(np.float32),
            acc=np.asarray(data["imu_acc"], dtype=np.float32),
            mag=np.asarray(data["imu_mag"], dtype=np.float64)
            if "imu_mag" in data
            else np.full((n, 3), np.nan),
            rate=float(rate_arr.reshape(())),
            quat_true=np.asarray(data["opt_quat"], dtype=np.float64) if "opt_quat" in data else None,
            movement=movement,
            name=p.stem,
            groups=_trials_json_groups(p) or broad_groups(p.stem),
        )
    except ValueError as exc:
        raise ValueError(f"{p}: {exc}") from None

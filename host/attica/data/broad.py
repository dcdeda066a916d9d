"""Loading the original BROAD trial files (.hdf5 with h5py, .mat with scipy) and BROAD's trial groups."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from attica.data.recording import PathLike, Recording

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

"""Loading .npz recordings in BROAD layout (the project's own format and the converted BROAD trials)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from attica.data.recording import PathLike, Recording

NPZ_REQUIRED = ("gyr", "acc", "sampling_rate")
"""Keys a ``.npz`` recording must have; the others (``mag``, ``opt_quat``, ...) are optional."""


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
            time=data.get("time"),
            name=name,
            groups=groups,
        )
    except ValueError as exc:
        raise ValueError(f"{p}: {exc}") from None

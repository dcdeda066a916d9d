"""An IMU recording in memory (:class:`Recording`) and how it is written (.npz in BROAD layout, .csv)."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.data.timing import Timing, steps_for

PathLike = str | os.PathLike[str]


_GYR = ("gyr_x", "gyr_y", "gyr_z")


_ACC = ("acc_x", "acc_y", "acc_z")


_MAG = ("mag_x", "mag_y", "mag_z")


_QUAT = ("quat_w", "quat_x", "quat_y", "quat_z")


CSV_COLUMNS = ("t", *_GYR, *_ACC, *_MAG, *_QUAT, "movement")
"""All column names the CSV loader understands (see the module docstring)."""


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
    time : ndarray, float64, shape (N,), or None
        Time of each sample in s as recorded (any origin), strictly increasing; None: a sample every
        ``1 / rate`` s. Where an interval spans n periods, n - 1 samples were lost (:attr:`steps`).
    timing : attica.data.timing.Timing or None
        What the loader found in the time column (unit, jitter, gaps, dropped rows), when it read one.

    """

    gyr: NDArray[np.float32]
    acc: NDArray[np.float32]
    mag: NDArray[np.float32]
    rate: float
    quat_true: NDArray[np.float64] | None = None
    movement: NDArray[np.bool_] | None = None
    name: str = ""
    groups: tuple[str, ...] = field(default_factory=tuple)
    time: NDArray[np.float64] | None = None
    timing: Timing | None = field(default=None, compare=False)

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
        if self.time is not None:
            self.time = _array(self.time, "time", np.float64, None)
            if self.time.shape[0] != n:
                raise ValueError(f"time: {self.time.shape[0]} samples, but gyr has {n}")
            if not np.all(np.isfinite(self.time)):
                raise ValueError("time: must be finite")
            if np.any(np.diff(self.time) <= 0.0):
                raise ValueError(
                    "time: must be strictly increasing (attica.data.timing.clock drops the rest)"
                )

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
        """Time of each sample in s, starting at 0 (``time - time[0]``, or ``arange(n) / rate``)."""
        if self.time is not None:
            return self.time - self.time[0] if self.n else self.time.copy()
        return np.arange(self.n, dtype=np.float64) / self.rate

    @property
    def steps(self) -> NDArray[np.uint32]:
        """Periods each sample advances the filter: 1, or n after n - 1 lost samples (from :attr:`time`)."""
        if self.time is None:
            return np.ones(self.n, np.uint32)
        return steps_for(self.time, self.dt)

    @property
    def lost(self) -> int:
        """Samples lost in gaps of :attr:`time` (0 without it)."""
        return int(np.sum(self.steps, dtype=np.int64)) - self.n

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
        if self.time is not None:
            arrays["time"] = self.time
        assert all(np.ndim(v) == 0 or np.shape(v)[0] == n for k, v in arrays.items() if k != "groups")
        with open(path, "wb") as f:  # a file object: numpy must not append another ".npz"
            np.savez(f, **arrays)

    def _save_csv(self, path: Path) -> None:
        cols: list[NDArray[Any]] = [self.time if self.time is not None else self.t, self.gyr, self.acc]
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

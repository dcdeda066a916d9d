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

Recordings of other tools load through readers (docs/recordings.md, "Readers"): ROS 1 bags, ROS 2 bags
(sqlite3 or MCAP storage) and bare MCAP files with ``sensor_msgs/Imu`` / ``MagneticField``
(:mod:`attica.data.rosbag`, :mod:`attica.data.mcapfile`), PX4 ULog (:mod:`attica.data.ulog`), EuRoC/ASL
folders (:mod:`attica.data.euroc`), Sensor Logger and Android-style per-sensor CSV folders
(:mod:`attica.data.phone`) and phyphox exports (:mod:`attica.data.phyphox`). Each converts units and
frames to the ones above and keeps every sample's time (``Recording.time``, ``Recording.timing``): the
gyro's clock, accel held, magnetometer placed (:mod:`attica.data.streams`). The bag, MCAP and ULog
readers need the optional packages of ``pip install 'attica[recordings]'`` (rosbags, mcap, pyulog); an
ImportError says so. :func:`read_recording` returns a recording with a description of the file
(what ``attica info`` prints).

The code: :mod:`attica.data.recording` (the :class:`Recording` and its writers),
:mod:`attica.data.npz`, :mod:`attica.data.csvfile`, :mod:`attica.data.broad` (the loaders),
:mod:`attica.data.readers` (which reader a path needs).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from attica.data.broad import BROAD_KEYS, broad_groups, load_broad
from attica.data.csvfile import load_csv
from attica.data.npz import NPZ_REQUIRED, load_npz
from attica.data.readers import FORMATS, detect, read_recording
from attica.data.recording import CSV_COLUMNS, PathLike, Recording

__all__ = [
    "BROAD_KEYS",
    "CSV_COLUMNS",
    "FORMATS",
    "NPZ_REQUIRED",
    "Recording",
    "broad_groups",
    "detect",
    "load_broad",
    "load_csv",
    "load_npz",
    "load_recording",
    "read_recording",
]


def load_recording(path: PathLike, **options: Any) -> Recording:
    """Load a recording of any format attica reads, chosen by suffix and content (:func:`detect`).

    ``.npz`` (BROAD layout), ``.csv`` (attica's columns), ``.hdf5``/``.h5``/``.mat`` (original BROAD);
    ``.bag``, ``.db3``, a ROS 2 bag folder, ``.mcap``; ``.ulg``; an EuRoC/ASL folder or zip; a Sensor
    Logger or Android-style folder or zip; a phyphox ``.zip``, folder or ``.csv``. Problems with the time
    column (gaps, dropped rows, a guessed unit) and the reader's (rows before the first accel sample
    ...) are emitted as :class:`attica.data.timing.TimingWarning`.

    Parameters
    ----------
    path : str or os.PathLike
        File or folder to read.
    **options
        The reader's options (docs/recordings.md): ``topic``, ``mag_topic``, ``stamp``, ``orientation``,
        ``frd`` for bags and MCAP; ``mag``, ``mag_instance``, ``attitude`` for ULog; ``truth`` for EuRoC.
        attica's own formats take none.

    Returns
    -------
    Recording
        Sensor data as float32 in attica's units and the sensor frame, ground truth as float64.

    Raises
    ------
    ValueError
        An unknown suffix or folder, an empty or corrupt file, missing keys, columns or topics (the
        message names the file and lists the candidates), wrong shapes, inconsistent lengths or a bad
        rate.
    FileNotFoundError
        If the path does not exist.
    ImportError
        For ``.hdf5``/``.h5`` without h5py or ``.mat`` without scipy; for bags, MCAP and ULog without
        the packages of ``pip install 'attica[recordings]'``.
    TypeError
        An option the format does not take.

    """
    from attica.data import readers
    from attica.data.streams import report

    p = Path(path)
    suffix = p.suffix.lower()
    if p.is_file() and suffix in (".npz", ".hdf5", ".h5", ".mat"):
        if options:
            raise TypeError(f"{p}: {suffix} files take no options (got {', '.join(options)})")
        return load_npz(p) if suffix == ".npz" else load_broad(p)
    if p.is_file() and suffix == ".csv" and readers.detect(p) == "csv":
        if options:
            raise TypeError(f"{p}: attica .csv files take no options (got {', '.join(options)})")
        return load_csv(p)
    rec, contents = readers.read_recording(p, **options)
    report(rec, contents)  # the warnings point at the caller
    return rec

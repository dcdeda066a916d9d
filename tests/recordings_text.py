"""Test helpers for the text formats: EuRoC/ASL folders, Sensor Logger and Android-style exports, phyphox.

Each writer makes the files of its format from a known recording (attica.sim), as the tool that makes
them would: names, columns, units, sign conventions and time stamps of the format's documentation.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
from recordings_support import G

from attica.data import Recording
from attica.sim.rotations import quat_rotate_inv

T0 = 1_403_636_579_758_555_392
IMU_HEADER = (
    "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
    "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]"
)
GT_HEADER = (
    "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z [], "
    "v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1]"
)


def write_euroc(root: Path, rec: Recording, skip: range = range(0), truth: bool = True) -> Path:
    """A sequence folder: mav0/imu0/{data.csv, sensor.yaml}, and the ground truth from 0.2 s to 2.7 s,
    stamped 1 ms after the IMU rows."""
    imu = root / "mav0" / "imu0"
    imu.mkdir(parents=True)
    period = round(1e9 / rec.rate)
    lines = [IMU_HEADER]
    for i in range(rec.n):
        if i not in skip:
            values = ",".join(f"{v:.9g}" for v in (*rec.gyr[i], *rec.acc[i]))
            lines.append(f"{T0 + i * period},{values}")
    (imu / "data.csv").write_text("\r\n".join(lines) + "\r\n")
    (imu / "sensor.yaml").write_text(f"sensor_type: imu\ncomment: test\nrate_hz: {rec.rate:g}\n")
    if truth:
        gt = root / "mav0" / "state_groundtruth_estimate0"
        gt.mkdir()
        rows = [GT_HEADER]
        for i in range(20, 270):
            q = ",".join(f"{v:.17g}" for v in rec.quat_true[i])
            rows.append(f"{T0 + i * period + 1_000_000},1.0,2.0,0.5,{q},0.0,0.0,0.0")
        (gt / "data.csv").write_text("\n".join(rows) + "\n")
    return root


# --- phones ------------------------------------------------------------------------------------------

EPOCH_NS = 1_698_501_144_401_773_000


def sl_file(path: Path, t_ns: np.ndarray, xyz: np.ndarray) -> None:
    """A Sensor Logger CSV: time (ns epoch), seconds_elapsed, z, y, x."""
    lines = ["time,seconds_elapsed,z,y,x"]
    for t, (x, y, z) in zip(t_ns, xyz):
        lines.append(f"{t},{(t - EPOCH_NS) * 1e-9:.9f},{z:.9g},{y:.9g},{x:.9g}")
    path.write_text("\n".join(lines) + "\n")


def gravity(rec: Recording) -> np.ndarray:
    """Gravity as Android's Gravity sensor reports it (specific-force sense: +g up), sensor frame."""
    return quat_rotate_inv(rec.quat_true, np.tile([0.0, 0.0, G], (rec.n, 1)))


def write_sensor_logger(
    root: Path, rec: Recording, platform: str = "Android", standard: bool = False, metadata: bool = True
) -> Path:
    """Gyroscope at the recording's rate; accelerometer files 3 ms after each gyro sample; the
    magnetometer at a quarter of the rate. Android: TotalAcceleration.csv (+ Accelerometer.csv without
    gravity); iOS: Accelerometer.csv + Gravity.csv, negated unless standardised."""
    root.mkdir()
    period = round(1e9 / rec.rate)
    t = EPOCH_NS + np.arange(rec.n, dtype=np.int64) * period
    sl_file(root / "Gyroscope.csv", t, rec.gyr)
    grav = gravity(rec)
    user = rec.acc - grav
    if platform == "Android":
        sl_file(root / "TotalAcceleration.csv", t + 3_000_000, rec.acc)
        sl_file(root / "Accelerometer.csv", t + 3_000_000, user)
    else:
        sign = 1.0 if standard else -1.0
        sl_file(root / "Accelerometer.csv", t + 3_000_000, sign * user)
        sl_file(root / "Gravity.csv", t + 3_000_000, sign * grav)
    sl_file(root / "Magnetometer.csv", t[::4] + 1_000_000, rec.mag[::4])
    sl_file(root / "GyroscopeUncalibrated.csv", t, rec.gyr + 0.1)
    if metadata:
        (root / "Metadata.csv").write_text(
            "version,device name,recording time,platform,appVersion,standardisation\n"
            f"3,test phone,2024-01-01_12-00-00,{platform},1.40.1,{'true' if standard else 'false'}\n"
        )
    return root


def android_file(path: Path, t: np.ndarray, xyz: np.ndarray, time_name: str = "timestamp") -> None:
    lines = [f"{time_name},x,y,z,accuracy"] + [
        f"{a},{x:.9g},{y:.9g},{z:.9g},3" for a, (x, y, z) in zip(t, xyz)
    ]
    path.write_text("\n".join(lines) + "\n")


# --- phyphox -----------------------------------------------------------------------------------------

VARIANTS = [(",", "."), ("\t", "."), (";", "."), ("\t", ","), (";", ",")]


def _num(v: float, decimal: str) -> str:
    return f"{v:.9E}".replace(".", decimal)


def phyphox_table(columns: list[tuple[str, np.ndarray]], sep: str, decimal: str) -> str:
    """phyphox's layout: quoted header, one row per sample, empty cells where a column is shorter."""
    n = max(len(c) for _, c in columns)
    lines = [sep.join(f'"{name}"' for name, _ in columns)]
    for i in range(n):
        lines.append(sep.join(_num(float(c[i]), decimal) if i < len(c) else "" for _, c in columns))
    return "\n".join(lines) + "\n"


def phyphox_sensor(
    label: str, unit: str, t: np.ndarray, xyz: np.ndarray, time: str = "Time (s)"
) -> list[tuple[str, np.ndarray]]:
    cols = [(time, t)] + [(f"{label} {a} ({unit})", xyz[:, k]) for k, a in enumerate("xyz")]
    return cols + [(f"Absolute ({unit})", np.linalg.norm(xyz, axis=1))]


def phyphox_sets(rec: Recording) -> dict[str, list[tuple[str, np.ndarray]]]:
    t = np.arange(rec.n) / rec.rate
    return {
        "Gyroscope.csv": phyphox_sensor("Gyroscope", "rad/s", t, rec.gyr),
        "Accelerometer.csv": phyphox_sensor("Acceleration", "m/s^2", t + 0.002, rec.acc),
        "Magnetometer.csv": phyphox_sensor("Magnetic field", "µT", t[::2] + 0.001, rec.mag[::2]),
        "Linear Acceleration.csv": phyphox_sensor("Linear Acceleration", "m/s^2", t, rec.acc * 0.0),
    }


def write_phyphox_zip(path: Path, rec: Recording, sep: str = ",", decimal: str = ".") -> Path:
    with zipfile.ZipFile(path, "w") as z:
        for name, cols in phyphox_sets(rec).items():
            z.writestr(name, phyphox_table(cols, sep, decimal))
        z.writestr("meta/device.csv", '"property","value"\n"deviceModel","test"\n')
        z.writestr("meta/time.csv", '"event","experiment time","system time"\n"START",0.0,1700000000.0\n')
    return path

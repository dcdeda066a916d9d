"""What to simulate (:class:`SimConfig`) and the noise-free truth behind a simulation (:class:`SimTruth`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np
from numpy.typing import NDArray

from attica.calibration.model import Calibration
from attica.sim.errors import ErrorSizes
from attica.sim.rotations import F64

Vec3 = tuple[float, float, float]
"""Three floats: a vector."""


@dataclass
class SimConfig:
    """Simulation parameters; every random quantity derives from ``seed``.

    Attributes
    ----------
    duration : float
        Length in s; the recording has ``round(duration * rate)`` samples.
    rate : float
        Sampling rate in Hz.
    seed : int
        Seed of all random draws.
    gravity : float
        Gravity magnitude in m/s^2.
    rest_start, rest_end : float
        Still time at the start and end in s.
    rest_breaks : int
        Number of still pauses inside the motion.
    rotation_rms : float
        RMS per axis (before the envelope) of the random angular velocity in rad/s.
    rotation_bandwidth : float
        Highest frequency of the angular velocity in Hz.
    translation_rms : float
        RMS per axis (before the envelope) of the earth-frame linear acceleration in m/s^2.
    taps : int
        Number of acceleration taps.
    gyro_noise : float
        White gyro noise std per sample in rad/s.
    gyro_bias : float
        Initial gyro bias drawn per axis uniform in ``[-gyro_bias, gyro_bias]`` rad/s.
    gyro_bias_drift : float
        Random-walk intensity of the bias in rad/s/sqrt(s).
    accel_noise : float
        White accelerometer noise std per sample in m/s^2.
    mag_field : float
        Magnitude of the earth magnetic field in uT.
    mag_dip : float
        Inclination of the field below the horizon in rad.
    mag_declination : float
        Azimuth of the field's horizontal part east of true north in rad (the truth's yaw is relative
        to true north), in [-pi, pi]; 0: the field points north.
    mag_noise : float
        White magnetometer noise std per sample in uT.
    mag_disturbances : tuple of (t_start, t_end, (x, y, z))
        Extra earth-frame fields in uT, present for ``t_start <= t < t_end``.
    initial_attitude : tuple of 4 floats or None
        Initial ``w, x, y, z`` (normalised); None draws a uniformly random attitude from the seed.
    translation_bandwidth : float
        Highest frequency of the linear motion in Hz.
    break_duration : float
        Length of each still pause in s.
    ramp : float
        Length of the smooth ramp at each end of a motion segment in s (at most half the segment).
    tap_amplitude : float
        Peak acceleration of a tap in m/s^2.
    tap_duration : float
        Length of a tap in s.
    components : int
        Number of sinusoids per axis in the random rotation and translation.
    substeps : int
        Integrator steps per sample; 0 picks ``max(2, ceil(1 ms * rate))``.
    name : str
        Recording name; empty gives ``sim-seed<seed>``.
    gyro_clip : float
        Measurement range of the gyro in rad/s: each axis of the measured rate (after bias, noise and
        ``sensor_errors``) is clipped to ``[-gyro_clip, gyro_clip]``, as a saturated MEMS gyro reads
        its full scale; :attr:`SimTruth.gyr_clipped` records where. 0: no clipping.
    vibration_accel : float
        Amplitude per axis in m/s^2 of a sinusoidal linear vibration of the sensor at
        ``vibration_frequency`` (sensor frame, a seeded phase per axis; part of the true linear
        acceleration :attr:`SimTruth.acc_lin`). 0: none. Sampled without an anti-aliasing filter.
    vibration_gyro : float
        Amplitude per axis in rad/s of a sinusoidal angular vibration at ``vibration_frequency`` (sensor
        frame, a seeded phase per axis); it is real motion, integrated into ``quat_true``. 0: none.
    vibration_frequency : float
        Frequency of the vibration in Hz; must be > 0 when a vibration amplitude is.
    mag_dipoles : tuple of (t_start, t_end, (x, y, z), (x, y, z), (mx, my, mz))
        Moving magnets: a magnetic dipole of moment ``(mx, my, mz)`` A m^2 (earth frame) that moves in a
        straight line from the first position to the second (m, earth frame, relative to the sensor)
        during ``t_start <= t < t_end`` and is absent otherwise; its field
        ``mu0 / (4 pi) (3 r (r . m) - m) / |r|^3`` (in uT) is added to the earth field, so the
        disturbance changes in time and direction as the magnet passes. The path must keep >= 1 cm
        from the sensor.
    spins : tuple of (t_start, duration, peak, (x, y, z))
        Fast turns added to the body rate: ``peak * sin^2(pi (t - t_start) / duration)`` rad/s about
        the sensor-frame axis ``(x, y, z)`` (normalised) for ``t_start <= t < t_start + duration``
        (``peak * duration / 2`` rad in all); counted as movement.
    sensor_errors : ErrorSizes or None
        Scale, misalignment, offset and hard/soft-iron errors drawn from the seed
        (:func:`attica.sim.errors.draw_errors`) and applied to the measured samples before the
        clipping, as :func:`attica.sim.errors.apply_errors` does; :attr:`SimTruth.errors` is the
        calibration that corrects them. None: no such errors.

    """

    duration: float = 60.0
    rate: float = 285.714
    seed: int = 0
    gravity: float = 9.80665
    rest_start: float = 3.0
    rest_end: float = 2.0
    rest_breaks: int = 2
    rotation_rms: float = 0.8
    rotation_bandwidth: float = 0.5
    translation_rms: float = 0.5
    taps: int = 0
    gyro_noise: float = 0.005
    gyro_bias: float = 0.02
    gyro_bias_drift: float = 0.0005
    accel_noise: float = 0.05
    mag_field: float = 49.0
    mag_dip: float = 1.1
    mag_declination: float = 0.0
    mag_noise: float = 0.3
    mag_disturbances: tuple[tuple[float, float, tuple[float, float, float]], ...] = ()
    initial_attitude: tuple[float, float, float, float] | None = None
    translation_bandwidth: float = 1.0
    break_duration: float = 2.0
    ramp: float = 1.0
    tap_amplitude: float = 30.0
    tap_duration: float = 0.01
    components: int = 8
    substeps: int = 0
    name: str = ""
    gyro_clip: float = 0.0
    vibration_accel: float = 0.0
    vibration_gyro: float = 0.0
    vibration_frequency: float = 0.0
    mag_dipoles: tuple[tuple[float, float, Vec3, Vec3, Vec3], ...] = ()
    spins: tuple[tuple[float, float, float, Vec3], ...] = ()
    sensor_errors: ErrorSizes | None = None

    def validate(self) -> None:
        """Raise ValueError naming the first invalid field."""
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, float | int) and not isinstance(v, bool) and not math.isfinite(v):
                raise ValueError(f"SimConfig.{f.name} must be finite, got {v}")
        positive = ("duration", "rate", "rotation_bandwidth", "translation_bandwidth", "tap_duration")
        for name in positive:
            if getattr(self, name) <= 0:
                raise ValueError(f"SimConfig.{name} must be > 0, got {getattr(self, name)}")
        nonneg = (
            "rest_start", "rest_end", "rest_breaks", "rotation_rms", "translation_rms", "taps",
            "gyro_noise", "gyro_bias", "gyro_bias_drift", "accel_noise", "mag_field", "mag_noise",
            "break_duration", "ramp", "substeps", "gyro_clip", "vibration_accel", "vibration_gyro",
            "vibration_frequency",
        )  # fmt: skip
        for name in nonneg:
            if getattr(self, name) < 0:
                raise ValueError(f"SimConfig.{name} must be >= 0, got {getattr(self, name)}")
        if not -math.pi <= self.mag_declination <= math.pi:
            raise ValueError(f"SimConfig.mag_declination must be in [-pi, pi], got {self.mag_declination}")
        if self.components < 1:
            raise ValueError(f"SimConfig.components must be >= 1, got {self.components}")
        for i, dist in enumerate(self.mag_disturbances):
            if len(dist) != 3 or len(dist[2]) != 3:
                raise ValueError(f"SimConfig.mag_disturbances[{i}] must be (t_start, t_end, (x, y, z))")
            if not np.all(np.isfinite(np.array([dist[0], dist[1], *dist[2]], dtype=np.float64))):
                raise ValueError(f"SimConfig.mag_disturbances[{i}] must be finite")
        if (self.vibration_accel > 0 or self.vibration_gyro > 0) and not self.vibration_frequency > 0:
            raise ValueError("SimConfig.vibration_frequency must be > 0 when a vibration amplitude is")
        for i, dip in enumerate(self.mag_dipoles):
            _check_dipole(i, dip)
        for i, spin in enumerate(self.spins):
            if len(spin) != 4 or len(spin[3]) != 3:
                raise ValueError(f"SimConfig.spins[{i}] must be (t_start, duration, peak, (x, y, z))")
            vals = np.array([spin[0], spin[1], spin[2], *spin[3]], dtype=np.float64)
            if not np.all(np.isfinite(vals)) or not spin[1] > 0 or not np.linalg.norm(vals[3:]) > 0:
                raise ValueError(
                    f"SimConfig.spins[{i}]: finite numbers, duration > 0 and an axis not all 0; got {spin}"
                )
        if self.sensor_errors is not None and not isinstance(self.sensor_errors, ErrorSizes):
            raise ValueError(
                f"SimConfig.sensor_errors must be ErrorSizes or None, got {self.sensor_errors!r}"
            )
        if self.initial_attitude is not None:
            q = np.asarray(self.initial_attitude, dtype=np.float64)
            if q.shape != (4,) or not np.all(np.isfinite(q)) or not np.linalg.norm(q) > 0:
                raise ValueError(f"SimConfig.initial_attitude must be 4 finite numbers, not all 0; got {q}")

    @property
    def n(self) -> int:
        """Number of samples, ``round(duration * rate)``."""
        return int(round(self.duration * self.rate))


def _check_dipole(i: int, dip: tuple[float, float, Vec3, Vec3, Vec3]) -> None:
    """Raise ValueError unless ``mag_dipoles[i]`` is well formed and keeps >= 1 cm from the sensor."""
    what = f"SimConfig.mag_dipoles[{i}]"
    if len(dip) != 5 or any(len(v) != 3 for v in dip[2:]):
        raise ValueError(f"{what} must be (t_start, t_end, (x, y, z), (x, y, z), (mx, my, mz))")
    vals = np.array([dip[0], dip[1], *dip[2], *dip[3], *dip[4]], dtype=np.float64)
    if not np.all(np.isfinite(vals)) or not dip[1] > dip[0]:
        raise ValueError(f"{what} must be finite with t_end > t_start")
    p0, p1 = vals[2:5], vals[5:8]
    d = p1 - p0
    u = float(np.clip(-np.dot(p0, d) / max(float(np.dot(d, d)), 1e-300), 0.0, 1.0))
    if np.linalg.norm(p0 + u * d) < DIPOLE_MIN_DISTANCE:
        raise ValueError(f"{what}: the path passes closer than {DIPOLE_MIN_DISTANCE} m to the sensor")


DIPOLE_MIN_DISTANCE = 0.01
"""m: how close a moving magnet's path may come to the sensor (:attr:`SimConfig.mag_dipoles`)."""


@dataclass
class SimTruth:
    """Noise-free quantities behind a simulated :class:`~attica.data.Recording` (all float64).

    Attributes
    ----------
    gyr : ndarray, shape (N, 3)
        True body rate in rad/s, sensor frame (what a perfect gyro reads).
    gyr_bias : ndarray, shape (N, 3)
        Gyro bias in rad/s added to each sample.
    acc_lin : ndarray, shape (N, 3)
        Linear acceleration in m/s^2, earth frame (taps included).
    mag_earth : ndarray, shape (N, 3)
        Magnetic field in uT, earth frame (disturbances included).
    envelope : ndarray, shape (N,)
        Motion envelope in [0, 1]; 0 during the still periods.
    segments : tuple of (start, end)
        Motion segments in s.
    tap_times : ndarray, shape (T,)
        Start time of each tap in s.
    tap_dirs : ndarray, shape (T, 3)
        Earth-frame unit direction of each tap.
    substeps : int
        Integrator steps per sample used for ``quat_true``.
    gyr_clipped : ndarray of bool, shape (N, 3)
        Where the measured gyro was clipped at :attr:`SimConfig.gyro_clip` (per axis).
    errors : Calibration or None
        The calibration that corrects :attr:`SimConfig.sensor_errors` (None without them).

    """

    gyr: F64
    gyr_bias: F64
    acc_lin: F64
    mag_earth: F64
    envelope: F64
    segments: tuple[tuple[float, float], ...]
    tap_times: F64
    tap_dirs: F64
    substeps: int
    gyr_clipped: NDArray[np.bool_] = field(default_factory=lambda: np.zeros((0, 3), np.bool_))
    errors: Calibration | None = None

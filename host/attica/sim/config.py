"""What to simulate (:class:`SimConfig`) and the noise-free truth behind a simulation (:class:`SimTruth`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from attica.sim.rotations import F64


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
            "break_duration", "ramp", "substeps",
        )  # fmt: skip
        for name in nonneg:
            if getattr(self, name) < 0:
                raise ValueError(f"SimConfig.{name} must be >= 0, got {getattr(self, name)}")
        if self.components < 1:
            raise ValueError(f"SimConfig.components must be >= 1, got {self.components}")
        for i, dist in enumerate(self.mag_disturbances):
            if len(dist) != 3 or len(dist[2]) != 3:
                raise ValueError(f"SimConfig.mag_disturbances[{i}] must be (t_start, t_end, (x, y, z))")
            if not np.all(np.isfinite(np.array([dist[0], dist[1], *dist[2]], dtype=np.float64))):
                raise ValueError(f"SimConfig.mag_disturbances[{i}] must be finite")
        if self.initial_attitude is not None:
            q = np.asarray(self.initial_attitude, dtype=np.float64)
            if q.shape != (4,) or not np.all(np.isfinite(q)) or not np.linalg.norm(q) > 0:
                raise ValueError(f"SimConfig.initial_attitude must be 4 finite numbers, not all 0; got {q}")

    @property
    def n(self) -> int:
        """Number of samples, ``round(duration * rate)``."""
        return int(round(self.duration * self.rate))


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

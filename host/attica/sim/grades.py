"""Sensor grades for the simulator: the noise, bias and calibration errors of a class of IMU.

A :class:`SensorGrade` sets a :class:`~attica.sim.SimConfig`'s white noise from noise densities (so the
same sensor gives the same angle random walk at every sample rate: per-sample std ``density *
sqrt(rate)``), the gyro's initial bias and its random walk, and the scale, misalignment, offset and
hard/soft-iron errors left after the maker's calibration (:class:`~attica.sim.errors.ErrorSizes`,
drawn from the seed and applied by the simulator: :attr:`~attica.sim.SimConfig.sensor_errors`).

:data:`GRADES` holds two, with figures typical of their data sheets:

- ``consumer``: a phone or hobby MEMS IMU with its factory trim, the magnetometer calibrated once by the
  user (a few uT of hard iron left);
- ``industrial``: a calibrated industrial MEMS IMU (bias, scale and offsets an order of magnitude smaller,
  noise and iron about a quarter).
"""

from __future__ import annotations

import dataclasses
import math

from attica.sim.config import SimConfig
from attica.sim.errors import ErrorSizes

__all__ = ["GRADES", "SensorGrade"]


@dataclasses.dataclass(frozen=True)
class SensorGrade:
    """Noise, bias and calibration errors of a class of IMU.

    Attributes
    ----------
    name : str
        Label (``consumer``, ``industrial``).
    gyro_noise_density : float
        Gyro white noise density in rad/s/sqrt(Hz) (= angle random walk in rad/sqrt(s)).
    gyro_bias : float
        Initial gyro bias bound per axis in rad/s (:attr:`SimConfig.gyro_bias`).
    gyro_bias_drift : float
        Bias random walk in rad/s/sqrt(s) (:attr:`SimConfig.gyro_bias_drift`).
    accel_noise_density : float
        Accelerometer white noise density in m/s^2/sqrt(Hz).
    mag_noise : float
        Magnetometer white noise std per sample in uT.
    errors : ErrorSizes
        Bounds of the scale, misalignment, offset and hard/soft-iron errors (the gyro's offset is
        ``gyro_bias``, so ``errors.gyro_offset`` is 0 in :data:`GRADES`).

    """

    name: str
    gyro_noise_density: float
    gyro_bias: float
    gyro_bias_drift: float
    accel_noise_density: float
    mag_noise: float
    errors: ErrorSizes

    def config(self, cfg: SimConfig) -> SimConfig:
        """``cfg`` with this grade's noise (per-sample std from the densities at ``cfg.rate``) and errors.

        Parameters
        ----------
        cfg : SimConfig
            The simulation (its rate sets the per-sample noise).

        Returns
        -------
        SimConfig
            A copy with ``gyro_noise``, ``gyro_bias``, ``gyro_bias_drift``, ``accel_noise``,
            ``mag_noise`` and ``sensor_errors`` set.

        """
        root = math.sqrt(cfg.rate)
        return dataclasses.replace(
            cfg,
            gyro_noise=self.gyro_noise_density * root,
            gyro_bias=self.gyro_bias,
            gyro_bias_drift=self.gyro_bias_drift,
            accel_noise=self.accel_noise_density * root,
            mag_noise=self.mag_noise,
            sensor_errors=self.errors,
        )


GRADES: dict[str, SensorGrade] = {
    "consumer": SensorGrade(
        "consumer",
        gyro_noise_density=2.6e-4,  # 0.015 deg/s/sqrt(Hz)
        gyro_bias=0.035,  # 2 deg/s
        gyro_bias_drift=5e-4,
        accel_noise_density=2.9e-3,  # 300 ug/sqrt(Hz)
        mag_noise=0.4,
        errors=ErrorSizes(
            gyro_offset=0.0,
            gyro_scale=0.02,
            gyro_misalignment=0.01,
            accel_offset=0.1,  # 10 mg
            accel_scale=0.01,
            accel_misalignment=0.01,
            hard_iron=2.0,
            soft_iron_scale=0.02,
            soft_iron_coupling=0.01,
        ),
    ),
    "industrial": SensorGrade(
        "industrial",
        gyro_noise_density=7e-5,  # 0.004 deg/s/sqrt(Hz)
        gyro_bias=0.0035,  # 0.2 deg/s
        gyro_bias_drift=5e-5,
        accel_noise_density=6e-4,  # 60 ug/sqrt(Hz)
        mag_noise=0.1,
        errors=ErrorSizes(
            gyro_offset=0.0,
            gyro_scale=0.002,
            gyro_misalignment=0.001,
            accel_offset=0.01,  # 1 mg
            accel_scale=0.001,
            accel_misalignment=0.001,
            hard_iron=0.5,
            soft_iron_scale=0.005,
            soft_iron_coupling=0.002,
        ),
    ),
}
"""The sensor grades of the generalisation suite (:mod:`attica.evaluate.suite`)."""

"""Deterministic IMU simulator with ground truth.

Conventions (those of the whole project): quaternions ``(w, x, y, z)`` sensor-to-earth,
``v_earth = q * v_sensor * conj(q)``, earth frame ENU (x east, y north, z up); body-rate kinematics
``q_dot = 0.5 * q * (0, w_sensor)``.

Sensor models (sample ``k`` at ``t_k = k / rate``, ``R_k`` the rotation matrix of ``quat_true[k]``):

- gyroscope ``gyr = w(t_k) + bias_k + noise``, the *instantaneous* true body rate in rad/s; the bias
  starts uniform in ``[-gyro_bias, gyro_bias]`` per axis and random-walks with ``gyro_bias_drift``
  rad/s/sqrt(s);
- accelerometer (specific force, m/s^2) ``acc = R_k^T (a_lin(t_k) + [0, 0, g]) + noise``, i.e. +g on the
  up axis at rest;
- magnetometer (uT) ``mag = R_k^T (m_earth + disturbance(t_k)) + noise`` with
  ``m_earth = B * (0, cos(dip), -sin(dip))`` (northern hemisphere, dip positive = pointing down) and the
  disturbances of :attr:`SimConfig.mag_disturbances` added in the earth frame on ``t_start <= t < t_end``
  and the field of the moving magnets of :attr:`SimConfig.mag_dipoles` (dipoles on straight paths);
- optional: sensor errors (:attr:`SimConfig.sensor_errors`: scale, misalignment, offsets, hard and soft
  iron drawn by :func:`attica.sim.errors.draw_errors`, applied to the readings), then the gyro clipped
  per axis at :attr:`SimConfig.gyro_clip` (:attr:`SimTruth.gyr_clipped`); a sinusoidal vibration
  (:attr:`SimConfig.vibration_accel`, ``vibration_gyro``, ``vibration_frequency``) that is real
  motion (in ``quat_true`` and :attr:`SimTruth.acc_lin`); sensor grades (consumer, industrial:
  noise densities, bias, drift and errors per grade) in :mod:`attica.sim.grades`.

Motion: the recording starts with ``rest_start`` s and ends with ``rest_end`` s of stillness;
``rest_breaks`` still pauses of ``break_duration`` s are spread (with seeded jitter) over the motion in
between. Each motion segment is shaped by a smooth envelope (quintic "smootherstep" ramps of ``ramp`` s,
zero with its first two derivatives at the segment ends). The body rate is the envelope times a sum of
``components`` random sinusoids per axis with frequencies in ``[0.1, 1] * rotation_bandwidth`` and an RMS
of ``rotation_rms`` (before the envelope). The linear acceleration (earth frame) is the time derivative
of a velocity built the same way (``v = envelope * sum of sinusoids``, frequencies in
``[0.2, 1] * translation_bandwidth``, acceleration RMS ``translation_rms``), so velocity is bounded and zero
whenever the sensor is still. Taps are bipolar pulses ``A sin(2 pi tau / T)`` of amplitude
``tap_amplitude`` and duration ``tap_duration`` (zero net velocity change) in a random earth-frame
direction, placed inside the motion segments. :attr:`SimConfig.spins` add fast turns about a sensor axis
(``peak * sin^2`` over their duration) to the body rate.

Ground truth integrates the analytic body rate with a 4th-order Magnus (two-point Gauss) exponential map
in float64, ``substeps`` steps per sample; the per-sample increments are composed with a vectorised
prefix product, so long recordings are fast. Gyro-only integration of the noise- and bias-free rate
(:attr:`SimTruth.gyr`) therefore tracks ``quat_true`` to the accuracy of the integrator used.

Determinism: every random quantity comes from ``numpy.random.default_rng`` seeded with children of
``SeedSequence(seed)``, one independent stream per part (attitude, schedule, rotation, translation,
taps, gyro, accelerometer, magnetometer, vibration, sensor errors). The same config gives identical
arrays; changing, say, the number of taps does not change the rotation, and a config without the
optional conditions gives the arrays it gave before they existed.

The simulator is *not* part of the bit-exact contract; only its float32 outputs are fed to the firmware.

The code: :mod:`attica.sim.config` (what to simulate, the truth), :mod:`attica.sim.motion` (phases,
random rotation and translation, taps, the earth's field), :mod:`attica.sim.rotations` (quaternion
helpers), :mod:`attica.sim.engine` (the integration and the sensor models), :mod:`attica.sim.errors`
(sensor errors), :mod:`attica.sim.grades` (sensor grades).
"""

from __future__ import annotations

from attica.sim.config import SimConfig, SimTruth
from attica.sim.engine import sim_to_npz, simulate, simulate_with_truth
from attica.sim.grades import GRADES, SensorGrade
from attica.sim.motion import mag_field_earth
from attica.sim.rotations import quat_exp, quat_rotate, quat_rotate_inv

__all__ = [
    "GRADES",
    "SensorGrade",
    "SimConfig",
    "SimTruth",
    "mag_field_earth",
    "quat_exp",
    "quat_rotate",
    "quat_rotate_inv",
    "sim_to_npz",
    "simulate",
    "simulate_with_truth",
]

"""The filter output record, laid out exactly like ``att_output_t`` (64 bytes)."""

from __future__ import annotations

import numpy as np

OUTPUT_DTYPE = np.dtype(
    [
        ("q", "<f4", (4,)),  # w, x, y, z, sensor-to-earth (ENU)
        ("euler", "<f4", (3,)),  # ZYX roll, pitch, yaw, rad
        ("gyro_bias", "<f4", (3,)),  # rad/s, sensor frame
        ("cov", "<f4", (4,)),  # covariance diagonal (KF: q; EKF: phi, theta, psi)
        ("flags", "<u4"),
        ("steps", "<u4"),
    ]
)
"""numpy dtype of one ``att_output_t``."""

FLOAT_FIELDS = ("q", "euler", "gyro_bias", "cov")
"""Float fields of an output record, compared bit for bit between C and the reference."""

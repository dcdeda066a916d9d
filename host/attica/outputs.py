"""The filter output record, laid out exactly like ``att_output_t`` (68 bytes), and ``att_mag_offset_t``."""

from __future__ import annotations

import numpy as np

OUTPUT_DTYPE = np.dtype(
    [
        ("q", "<f4", (4,)),  # w, x, y, z, sensor-to-earth (ENU, or the calibration's convention)
        ("euler", "<f4", (3,)),  # ZYX roll, pitch, yaw, rad
        ("gyro_bias", "<f4", (3,)),  # rad/s, sensor frame
        ("cov", "<f4", (4,)),  # covariance diagonal (KF: q; EKF: phi, theta, psi, mean bias variance)
        ("flags", "<u4"),
        ("steps", "<u4"),
        ("valid", "<u4"),  # ATT_OUT_* bits of the fields written
    ]
)
"""numpy dtype of one ``att_output_t``."""

MAG_OFFSET_DTYPE = np.dtype(
    {
        "names": ["offset", "on", "estimated"],
        "formats": [("<f4", (3,)), "?", "?"],
        "offsets": [0, 12, 13],
        "itemsize": 16,
    }
)
"""numpy dtype of one ``att_mag_offset_t`` (16 bytes): the hard-iron ``offset`` (uT, the frame of the
samples the filter sees; 0 until estimated), whether the estimate runs (``on``) and whether the rotations
have made it observable (``estimated``)."""

FLOAT_FIELDS = ("q", "euler", "gyro_bias", "cov")
"""Float fields of an output record, compared bit for bit between C and the reference."""

OUT_Q = 0x1
"""``ATT_OUT_Q``: the record's q holds a value."""
OUT_EULER = 0x2
"""``ATT_OUT_EULER``."""
OUT_BIAS = 0x4
"""``ATT_OUT_BIAS``."""
OUT_COV = 0x8
"""``ATT_OUT_COV``."""
OUT_ALL = 0xF
"""``ATT_OUT_ALL``: every field (att_filter_output)."""

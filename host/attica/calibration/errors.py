"""The error a calibration fit raises when the data cannot determine the parameters."""

from __future__ import annotations

__all__ = ["CalibrationError"]


class CalibrationError(ValueError):
    """The recording does not determine the calibration (too little coverage, too few positions, ...).

    The message says what was measured, what is needed and what to record instead.
    """

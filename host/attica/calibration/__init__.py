"""Sensor calibration, mounting and output convention (:mod:`attica.calibration.model`)."""

from attica.calibration.model import (
    CONVENTIONS,
    REMAPS,
    Calibration,
    InertialModel,
    MagModel,
    Mounting,
)

__all__ = ["CONVENTIONS", "REMAPS", "Calibration", "InertialModel", "MagModel", "Mounting"]

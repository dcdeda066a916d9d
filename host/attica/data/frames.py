"""Axis conventions of recordings and their conversion to attica's (earth ENU, body/sensor FLU-like).

attica's earth frame is ENU (x east, y north, z up), the convention of ROS (REP-103: earth ENU, body
FLU: x forward, y left, z up). Aerospace sources (PX4, ArduPilot, many INS) use earth NED (x north,
y east, z down) and body FRD (x forward, y right, z down). The two body conventions differ by a
rotation of 180 deg about x, the two earth frames by 180 deg about the horizontal axis halfway between
north and east:

- vectors in FRD (rate, specific force, field) to FLU: ``(x, -y, -z)`` (:func:`frd_to_flu`);
- an attitude ``q_NED<-FRD`` to ``q_ENU<-FLU = q_ENU<-NED * q_NED<-FRD * q_FRD<-FLU``
  (:func:`ned_frd_to_enu_flu`), with ``q_ENU<-NED = (0, 1/sqrt2, 1/sqrt2, 0)`` and
  ``q_FRD<-FLU = (0, 1, 0, 0)``.

A converted recording is the same motion seen by a sensor whose axes are FLU: a filter estimating
attitude in ENU from it gives the converted reference attitude. A sensor at rest, level, reads
``(0, 0, -g)`` in FRD (specific force points up, z points down) and ``(0, 0, +g)`` after conversion.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from attica.metrics import quat_mul

Q_ENU_FROM_NED = np.array([0.0, math.sqrt(0.5), math.sqrt(0.5), 0.0])
"""Rotation taking NED coordinates to ENU (swap x and y, negate z)."""

Q_FRD_FROM_FLU = np.array([0.0, 1.0, 0.0, 0.0])
"""Rotation taking FLU coordinates to FRD (negate y and z); its own inverse up to sign."""

_FLIP = np.array([1.0, -1.0, -1.0])


def frd_to_flu(v: ArrayLike) -> NDArray[np.float64]:
    """Vectors in FRD axes (shape (..., 3)) in FLU axes: ``(x, -y, -z)``."""
    out: NDArray[np.float64] = np.asarray(v, np.float64) * _FLIP
    return out


def ned_frd_to_enu_flu(q: ArrayLike) -> NDArray[np.float64]:
    """Attitudes ``w, x, y, z`` body(FRD)-to-NED (shape (..., 4)) as body(FLU)-to-ENU."""
    return quat_mul(quat_mul(Q_ENU_FROM_NED, np.asarray(q, np.float64)), Q_FRD_FROM_FLU)

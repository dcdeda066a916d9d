"""numpy float32 reference of the attica firmware, bit for bit.

Every function and filter mirrors its C counterpart operation by operation; run many instances in
lockstep by giving arrays. See :mod:`attica.reference.detmath` for the rules.
"""

from attica.reference import detmath
from attica.reference.ars import Ars
from attica.reference.filter import Filter
from attica.reference.gyro import Gyro
from attica.reference.tilt import Tilt

__all__ = ["Ars", "Filter", "Gyro", "Tilt", "detmath"]

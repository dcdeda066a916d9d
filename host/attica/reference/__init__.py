"""numpy float32 reference of the attica firmware, bit for bit.

Every function and filter mirrors its C counterpart operation by operation; run many instances in
lockstep by giving arrays. See :mod:`attica.reference.detmath` for the rules.
"""

from attica.reference import detmath
from attica.reference.ars import Ars

__all__ = ["Ars", "detmath"]

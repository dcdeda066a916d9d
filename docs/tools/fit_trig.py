"""Derive the float32 polynomial coefficients used by att_math.c / detmath.py.

Near-minimax fits (iteratively reweighted least squares, Lawson's algorithm) of the *final*
absolute error, in float64, rounded to float32 and printed as hex floats.
Run: ``python docs/tools/fit_trig.py``. The printed constants are the ones committed in
firmware/src/math/att_math.c and host/attica/reference/detmath.py.

- sin(x) = x + x*z*(s0 + z*(s1 + z*s2)),            z = x^2, |x| <= pi/4 (+0.2 %)
- cos(x) = 1 - z/2 + z*z*(c0 + z*(c1 + z*c2)),       same range
- atan(u) = u + u*z*(a0 + z*(a1 + ... + z*a4)),       z = u^2, |u| <= tan(pi/8) (+0.2 %)
"""

from __future__ import annotations

import numpy as np


def lawson(design: np.ndarray, target: np.ndarray, iters: int = 400) -> np.ndarray:
    """Approximate the L-infinity fit design @ c ~ target by Lawson's reweighted least squares."""
    w = np.full(len(target), 1.0 / len(target))
    c = np.zeros(design.shape[1])
    for _ in range(iters):
        sw = np.sqrt(w)
        c = np.linalg.lstsq(design * sw[:, None], target * sw, rcond=None)[0]
        err = np.abs(design @ c - target)
        w = w * err
        w = w / w.sum()
    return c


def main() -> None:
    x = np.linspace(1e-4, np.pi / 4 * 1.002, 20001)
    z = x * x
    sin_c = lawson(np.column_stack([x * z * z**i for i in range(3)]), np.sin(x) - x)
    cos_c = lawson(np.column_stack([z * z * z**i for i in range(3)]), np.cos(x) - 1.0 + 0.5 * z)
    u = np.linspace(1e-4, np.tan(np.pi / 8) * 1.002, 20001)
    zu = u * u
    atan_c = lawson(np.column_stack([u * zu * zu**i for i in range(5)]), np.arctan(u) - u)
    for name, c in (("sin", sin_c), ("cos", cos_c), ("atan", atan_c)):
        c32 = [float(np.float32(v)) for v in c]
        print(name, [v.hex() for v in c32])


if __name__ == "__main__":
    main()

"""attica from Python in a minute: simulate an IMU, run a C filter, check it against the reference.

Run it from anywhere once attica is installed (``pip install .`` or the wheel)::

    python examples/python/quickstart.py

tests/test_examples.py runs it as a test (its assertions are the point of the example too).
"""

from __future__ import annotations

import numpy as np

import attica
from attica.metrics import evaluate
from attica.reference import Filter as ReferenceFilter


def main() -> None:
    """Simulate 20 s at 100 Hz, filter in C (6-axis ARS and 9-axis MARS), compare with the truth."""
    rec = attica.simulate(attica.SimConfig(duration=20.0, rate=100.0, seed=1))  # rad/s, m/s^2, uT
    dt = 1.0 / rec.rate  # the sample period in s: the second argument of every filter

    ars = attica.Filter("ars", dt)
    out = ars.run(rec.gyr, rec.acc)  # one output record per sample (q, euler, gyro_bias, flags ...)
    print(out[-3:])  # a labelled table
    print("last flags:", attica.describe_flags(int(out["flags"][-1])))

    # the numpy reference gives the same float32 bits (compare the bits, not a tolerance)
    ref = ReferenceFilter("ars", dt).run(rec.gyr, rec.acc)
    assert (out["q"].view(np.uint32) == ref["q"].view(np.uint32)).all(), "C and reference differ"
    print(f"ars: {len(out)} steps, C and numpy reference bit-identical")

    # accuracy against the simulator's ground truth (BROAD metrics, degrees)
    e = evaluate(out["q"].astype(np.float64), rec.quat_true, rec.movement)
    print(f"ars: inclination RMSE {e.inclination:.2f} deg (6-axis: no heading)")
    mars = attica.Filter("mars", dt).run(rec.gyr, rec.acc, rec.mag)
    e9 = evaluate(mars["q"].astype(np.float64), rec.quat_true, rec.movement)
    print(f"mars: total RMSE {e9.total:.2f} deg, heading {e9.heading:.2f} deg")
    assert e.inclination < 2.0 and e9.total < 3.0

    # tuning: a settings field by keyword; a time constant replaces the per-sample gain
    slow = attica.Filter("ars", dt, tau=2.0).run(rec.gyr, rec.acc)
    print(f"ars tau=2 s: final q {np.round(slow['q'][-1], 4)}")


if __name__ == "__main__":
    main()

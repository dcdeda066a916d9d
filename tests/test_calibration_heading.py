"""mars heading with a distorted magnetometer: no calibration, the fitted one, the true one.

The motion: :func:`attica.sim.simulate` (120 s, random rotation with still breaks, default noise) with
the magnetometer distorted by :func:`attica.sim.errors.draw_errors` (hard iron up to 25 uT, soft iron
1 +- 0.15 with coupling +- 0.08; gyro and accelerometer left ideal: this is the magnetometer's test).
The calibration is fitted from a separate 60 s :func:`attica.sim.calib_motion.mag_sweep` at 100 Hz of
the same sensor. The fitted calibration must give a heading RMSE within 10 % of the true one's.

How the calibration reaches the filter: through ``native.Filter(..., calibration=...)`` (the
firmware's input stage) when the binding has that parameter; until then the calibration is applied in
float64 numpy (``MagModel.apply``) and the corrected samples, rounded to float32, are fed to the filter.
``APPLIED_BY`` says which path ran.
"""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from attica import native
from attica.calibration import Calibration
from attica.calibration.magfit import fit_mag
from attica.data import Recording
from attica.metrics import evaluate
from attica.settings import FilterKind, make_settings
from attica.sim import SimConfig, simulate
from attica.sim.calib_motion import mag_sweep
from attica.sim.errors import apply_errors, draw_errors, mag_only

MAG_ONLY = mag_only()

APPLIED_BY = "firmware" if "calibration" in inspect.signature(native.Filter).parameters else "numpy"


def _heading_rmse(raw: Recording, truth: Recording, cal: Calibration | None) -> float:
    settings = make_settings(FilterKind.MARS, dt=1.0 / raw.rate)
    mag = raw.mag
    if cal is not None and APPLIED_BY == "firmware":
        f = native.Filter(FilterKind.MARS, settings=settings, calibration=cal)
    else:
        f = native.Filter(FilterKind.MARS, settings=settings)
        if cal is not None:
            mag = cal.mag.apply(raw.mag).astype(np.float32)
    out = f.run(raw.gyr, raw.acc, mag, check_units=False)
    assert truth.quat_true is not None
    return float(evaluate(out["q"].astype(np.float64), truth.quat_true, truth.movement).heading)


@pytest.mark.parametrize("seed", [1, 3])
def test_fitted_mag_calibration_heading_within_10_percent_of_true(seed: int) -> None:
    truth = Calibration(mag=draw_errors(seed, MAG_ONLY).mag)
    rec = simulate(SimConfig(duration=120.0, seed=seed))
    raw = apply_errors(rec, truth)
    fit = fit_mag(mag_sweep(SimConfig(duration=60.0, rate=100.0, seed=seed + 10), truth).mag, 49.0)
    fitted = Calibration(mag=fit.model)
    none, got, ideal = (_heading_rmse(raw, rec, c) for c in (None, fitted, truth))
    print(
        f"seed {seed} ({APPLIED_BY}): mars heading RMSE without calibration {none:.2f} deg, fitted "
        f"{got:.3f} deg, true {ideal:.3f} deg (fit coverage {fit.coverage:.0%})"
    )
    assert abs(got - ideal) <= 0.1 * ideal
    assert none > 3.0 * ideal  # the distortion matters

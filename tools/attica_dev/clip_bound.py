"""What a recovery that takes its tilt from the accel after a clip can reach (issue 23).

``python -m attica_dev.clip_bound`` runs the suite's ``clipped`` condition (seeds 1-10) and builds, for
every clipping episode, an ideal recovery from the simulator's truth. From the first sample after the
clip, its up direction is the running mean of the true specific force since that sample (gravity plus
the true linear acceleration, earth frame): what the recovery's running mean of the accel gives with a
perfect gyro, no noise and no sensor error. Its heading comes from the true field at each sample, seen
through that tilt, in two ways:

- ``horizontal``: the field's horizontal projection turned onto the reference's, as the heading
  corrections of mars and the mekf do it (a tilt about the field's horizontal direction tilts the
  field's vertical part into the horizontal plane: a heading error of about ``tan(dip)`` times the
  tilt);
- ``field exact``: the field's direction kept exact and the up direction brought as near the mean as
  a turn about the field allows (what a 3-D magnetometer correction trusted fully can give).

Each ideal's error is scored as the suite scores a filter (:func:`attica.evaluate.suite.recovery_times`:
back within 2 deg, staying there for 1 s, within 2 s of the clip's end), beside the kinds' own counts.
It is not a strict bound: a filter weights the same samples differently (its mean starts at the last
clipped sample, its gyro carries noise and bias), which can bring it back within 2 s where the ideal
is not (mars in three episodes) or sooner (ars by 0.7 s in one). It is the yardstick of what the
accel's mean since the clip gives. docs/accuracy.md quotes the output (the clip section of issue 23).
It takes a second.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from attica.evaluate.estimate import as_estimate
from attica.evaluate.suite import _episodes, condition, recovery_times, suite_methods
from attica.metrics import error_angles
from attica.sim import simulate_with_truth

KINDS = ("ars", "kf", "ekf", "mekf6", "mars", "mekf")
IDEALS = ("tilt", "horizontal", "field exact")
"""The ideal recoveries: the 6-axis one (inclination) and the two 9-axis ones (total error)."""

F64 = NDArray[np.float64]


def running_up(force: F64) -> F64:
    """The unit direction of the running mean of ``force`` (N, 3) from its first row on."""
    s = np.cumsum(force, axis=0)
    up: F64 = s / np.linalg.norm(s, axis=1, keepdims=True)
    return up


def tilt_error(up: F64) -> F64:
    """The inclination error (rad) of an estimate that takes the unit vector ``up`` (N, 3) for up."""
    return np.arctan2(np.hypot(up[:, 0], up[:, 1]), up[:, 2])


def horizontal_error(up: F64, field: F64) -> F64:
    """The total error (rad) with ``up`` taken for the vertical and the heading from ``field``'s projection.

    The estimate's earth frame is turned by the shortest arc E that takes ``up`` to z; the field (earth
    frame, N x 3) seen in it, ``E field``, has its horizontal part turned back onto ``field``'s own (the
    reference) by a turn ``-h`` about z. The error is the angle of ``Rz(-h) E``: with E's quaternion
    ``(w, x, y, 0)``, the product's scalar part is ``cos(h / 2) w``.
    """
    w = np.sqrt((1.0 + up[:, 2]) / 2.0)
    # E = shortest arc up -> z, about the axis up x z (horizontal): quaternion (w, v), v = (up x z) / (2 w)
    vx = up[:, 1] / (2.0 * w)
    vy = -up[:, 0] / (2.0 * w)
    m = field
    # E m = m + 2 w (v x m) + 2 v x (v x m), v = (vx, vy, 0)
    cx = vy * m[:, 2]
    cy = -vx * m[:, 2]
    cz = vx * m[:, 1] - vy * m[:, 0]
    ex = m[:, 0] + 2.0 * w * cx + 2.0 * (vy * cz)
    ey = m[:, 1] + 2.0 * w * cy + 2.0 * (-vx * cz)
    h = np.arctan2(ex * m[:, 1] - ey * m[:, 0], ex * m[:, 0] + ey * m[:, 1])  # E m's azimuth east of m's
    err: F64 = 2.0 * np.arccos(np.clip(np.abs(np.cos(h / 2.0) * w), 0.0, 1.0))
    return err


def field_exact_error(up: F64, field: F64) -> F64:
    """The total error (rad) of the turn about ``field`` that brings ``up`` nearest to z.

    For a unit axis m, ``(R(m, t) u)_z = m_z (m . u) + cos t (u_z - m_z (m . u)) + sin t (m x u)_z``
    (Rodrigues), largest at ``t = atan2((m x u)_z, u_z - m_z (m . u))``; the error is ``|t|``.
    """
    m = field / np.linalg.norm(field, axis=1, keepdims=True)
    mu = np.sum(m * up, axis=1)
    cross_z = m[:, 0] * up[:, 1] - m[:, 1] * up[:, 0]
    err: F64 = np.abs(np.arctan2(cross_z, up[:, 2] - m[:, 2] * mu))
    return err


def ideal_errors(acc_lin: F64, field: F64, gravity: float) -> dict[str, F64]:
    """The ideals' errors (deg) over a stretch that starts with the first sample after a clip.

    Parameters
    ----------
    acc_lin : ndarray, shape (N, 3)
        The true linear acceleration, m/s^2, earth frame (ENU).
    field : ndarray, shape (N, 3)
        The true magnetic field, uT, earth frame.
    gravity : float
        m/s^2.

    Returns
    -------
    dict
        Per name of :data:`IDEALS` the error per sample in degrees.

    """
    up = running_up(acc_lin + np.array([0.0, 0.0, gravity]))
    return {
        "tilt": np.degrees(tilt_error(up)),
        "horizontal": np.degrees(horizontal_error(up, field)),
        "field exact": np.degrees(field_exact_error(up, field)),
    }


def measure(seeds: Sequence[int], kinds: Sequence[str] = KINDS) -> dict[str, list[float]]:
    """Per ideal and per kind: the recovery time of every episode over ``seeds`` (s; NaN: not back)."""
    cond = condition("clipped")
    out: dict[str, list[float]] = {}
    for seed in seeds:
        cfg = cond.config(seed, None)
        rec, truth = simulate_with_truth(cfg)
        assert rec.quat_true is not None
        episodes = _episodes(np.asarray(truth.gyr_clipped.any(axis=1), np.bool_), rec.rate)
        ideal = {name: np.full(len(rec), np.nan) for name in IDEALS}
        for k, (_, last) in enumerate(episodes):
            first = last + 1
            stop = episodes[k + 1][0] if k + 1 < len(episodes) else len(rec)
            errs = ideal_errors(truth.acc_lin[first:stop], truth.mag_earth[first:stop], cfg.gravity)
            for name in IDEALS:
                ideal[name][first:stop] = errs[name]
        for name in IDEALS:
            out.setdefault(name, []).extend(recovery_times(ideal[name], episodes, rec.rate))
        for m in suite_methods(kinds, [], cond.gyro_range):
            est = as_estimate(m.outcome(rec), len(rec), m.name)
            total, _, incl = error_angles(est.q, rec.quat_true)
            err = np.degrees(total if m.nine_axis else incl)
            out.setdefault(m.name, []).extend(recovery_times(err, episodes, rec.rate))
    return out


def within(times: Sequence[float], limit: float = 2.0) -> int:
    """How many recovery times are at most ``limit`` s (NaN: never)."""
    return int(np.sum(np.asarray(times) <= limit))


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: print the episodes back within 2 s, the ideals beside the kinds."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("--seeds", type=int, default=10, help="seeds 1 .. N of the suite's clipped condition")
    ap.add_argument("--episodes", action="store_true", help="also print each episode's recovery times")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    res = measure(range(1, args.seeds + 1))
    names = list(IDEALS) + list(KINDS)
    n = len(res[KINDS[0]])
    print(f"episodes back within 2 deg in 2 s (of {n}); ideals from the truth, kinds on their defaults")
    rows = (
        ("6-axis (inclination)", ("tilt", "ars", "kf", "ekf", "mekf6")),
        ("9-axis (total)", ("horizontal", "field exact", "mars", "mekf")),
    )
    for label, keys in rows:
        print(
            f"{label}: " + ", ".join(f"{'ideal ' if k in IDEALS else ''}{k} {within(res[k])}" for k in keys)
        )
    if args.episodes:
        print("episode " + " ".join(f"{name:>12s}" for name in names) + "   (s until back; nan: not back)")
        for i in range(n):
            print(f"{i:7d} " + " ".join(f"{res[name][i]:12.2f}" for name in names))
    print(f"{args.seeds} seeds in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

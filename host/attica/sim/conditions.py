"""The conditions of the generalisation suite: simulations of sensors and motions beyond BROAD's.

Each :class:`Condition` is a :class:`~attica.sim.SimConfig` over the simulator's defaults (sample rate,
sensor grade, magnetic disturbances, rest, fast turns, a clipping gyro, vibration); :data:`CONDITIONS`
holds the suite's, in the order of its tables. ``attica eval --suite`` scores methods on them
(:mod:`attica.evaluate.suite`); ``attica sim / run / demo / view --condition NAME`` simulate one.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

from attica.sim.config import SimConfig
from attica.sim.grades import GRADES

__all__ = ["BASE_RATE", "CLIP", "CONDITIONS", "CONVERGENCE", "Condition", "condition"]


BASE_RATE = 285.714
"""Hz: the rate of the conditions that do not set one (BROAD's)."""

CONVERGENCE = 5.0
"""s: not scored at the start of every recording (the filters' initial convergence)."""

CLIP = math.radians(500.0)
"""rad/s: the gyro range of the clipping conditions (500 deg/s, a common consumer full scale)."""

_SPIN_AXIS = (0.8, -0.36, 0.48)
_SPIN_TIMES = (12.0, 24.0, 36.0, 48.0)


def _spins(peak: float, length: float) -> tuple[tuple[float, float, float, tuple[float, float, float]], ...]:
    return tuple((t, length, peak, _SPIN_AXIS) for t in _SPIN_TIMES)


@dataclass(frozen=True)
class Condition:
    """One condition of the suite.

    Attributes
    ----------
    name : str
        Label (``baseline``, ``rate-50`` ...).
    what : str
        What it is, in a line.
    sim : dict
        :class:`~attica.sim.SimConfig` fields over the defaults (60 s at 285.714 Hz). A ``rate``
        without a ``grade`` keeps the default noise densities (per-sample noise times
        ``sqrt(rate / 285.714)``).
    grade : str
        A sensor grade of :data:`attica.sim.GRADES` (its noise, bias and errors), or ``""``.
    score_from : float
        Scored from this time in s (:data:`CONVERGENCE`, or later where no method can know the
        attitude before: while the field is disturbed from the start).
    magnetic : bool
        Only the magnetometer differs from the baseline, so the 6-axis methods' figures are the
        baseline's: they are not reported for it (tables, comparison with VQF).

    """

    name: str
    what: str
    sim: dict[str, Any] = field(default_factory=dict)
    grade: str = ""
    score_from: float = CONVERGENCE
    magnetic: bool = False

    @property
    def gyro_range(self) -> float:
        """The sensor's gyro range in rad/s given to the methods (0: their default, 2000 deg/s)."""
        return float(self.sim.get("gyro_clip", 0.0))

    def config(self, seed: int, duration: float | None = None) -> SimConfig:
        """The simulation of this condition for ``seed`` (``duration`` overrides the condition's)."""
        over = dict(self.sim)
        if duration is not None:
            over["duration"] = min(duration, float(over.get("duration", 60.0)))
        cfg = SimConfig(duration=60.0, rate=BASE_RATE, seed=seed, name=f"{self.name}-{seed}")
        cfg = dataclasses.replace(cfg, **over)
        if self.grade:
            return GRADES[self.grade].config(cfg)
        k = math.sqrt(cfg.rate / BASE_RATE)
        return dataclasses.replace(cfg, gyro_noise=cfg.gyro_noise * k, accel_noise=cfg.accel_noise * k)


CONDITIONS: tuple[Condition, ...] = (
    Condition("baseline", "the simulator's defaults: 285.714 Hz, random rotation and translation, 2 breaks"),
    Condition("rate-50", "the baseline at 50 Hz (same gyro and accel noise densities)", {"rate": 50.0}),
    Condition("rate-100", "the baseline at 100 Hz", {"rate": 100.0}),
    Condition("rate-1000", "the baseline at 1000 Hz", {"rate": 1000.0}),
    Condition(
        "consumer", "consumer-grade IMU: noise, 2 deg/s bias, 2 % gyro scale, errors", grade="consumer"
    ),
    Condition(
        "industrial",
        "industrial-grade IMU: a tenth of the consumer bias and scale, a quarter of the noise",
        grade="industrial",
    ),
    Condition(
        "mag-start",
        "field disturbed by 16 uT (40 deg of heading) for the first 15 s; scored from 15 s",
        {"mag_disturbances": ((0.0, 15.0, (12.0, -8.0, 6.0)),)},
        score_from=15.0,
        magnetic=True,
    ),
    Condition(
        "moving-magnet",
        "two magnets (3 A m^2) pass 25-32 cm away in 20 s each: up to 30 uT, turning",
        {
            "mag_dipoles": (
                (8.0, 28.0, (-1.5, 0.25, 0.1), (1.5, 0.25, 0.1), (0.0, 2.0, 2.2)),
                (32.0, 52.0, (0.3, 1.5, -0.1), (0.3, -1.5, -0.1), (2.5, 0.0, -1.5)),
            )
        },
        magnetic=True,
    ),
    Condition(
        "long-rest",
        "120 s: motion, 60 s still in the middle, motion",
        {"duration": 120.0, "rest_breaks": 1, "break_duration": 60.0},
    ),
    Condition(
        "near-clip",
        "4 turns to 8 rad/s (1.5 s each): 0.72-0.97 of the 500 deg/s range on an axis, no clipping",
        {"gyro_clip": CLIP, "spins": _spins(8.0, 1.5)},
    ),
    Condition(
        "clipped",
        "4 turns to 14 rad/s (1 s each): gyro clipped at 500 deg/s for 0.2-0.45 s, 9-74 deg lost",
        {"gyro_clip": CLIP, "spins": _spins(14.0, 1.0)},
    ),
    Condition(
        "vibration",
        "40 Hz vibration: 3 m/s^2 (0.3 g) and 0.05 rad/s per axis",
        {"vibration_accel": 3.0, "vibration_gyro": 0.05, "vibration_frequency": 40.0},
    ),
)
"""The suite's conditions, in the order of its tables."""


def condition(name: str) -> Condition:
    """A condition of :data:`CONDITIONS` by name (KeyError listing the names)."""
    for c in CONDITIONS:
        if c.name == name:
            return c
    raise KeyError(f"unknown condition {name!r}; conditions: {', '.join(c.name for c in CONDITIONS)}")

"""The generalisation suite: attica's filters, VQF and Fusion on a fixed set of simulated conditions.

BROAD's trials are one lab's sensor and motions; the suite asks whether a lead holds elsewhere. Each
:class:`Condition` of :data:`CONDITIONS` is a :class:`~attica.sim.SimConfig` (sample rate, sensor grade,
magnetic disturbances, rest, fast turns, a clipping gyro, vibration) simulated with each seed of
:data:`SEEDS`. Every method runs on its defaults over the whole recording; the errors are BROAD's
(:mod:`attica.metrics`) over every sample after the first :data:`CONVERGENCE` seconds (the
``movement`` mask is not used: rest counts too). A method's figure for a condition is the mean over the
seeds of its RMSE: 6-axis methods by the inclination, 9-axis methods by the total error.

The sensor's gyro range is part of a condition (:attr:`Condition.gyro_range`): where it is not the
default 2000 deg/s it is given to every method that takes one (attica's ``gyro_range``, Fusion's
``gyroscope_range``; VQF has none), as a user would configure the sensor. Fusion's rejection timeout
is 5 s at every rate (its README's; :data:`attica.peers.FUSION_DEFAULT`, in seconds).

Clip recovery (conditions whose gyro clips): for each clipping episode (clipped samples less than
:data:`EPISODE_GAP` apart are one), the time from the first unclipped sample until the method's judged
error is within :data:`RECOVERY_DEG` for :data:`RECOVERY_HOLD` s, looked for until the next episode
(NaN: not within that window).

Deterministic: the same figures on every run and whatever ``jobs`` is (each (condition, seed) case is
one task, simulated and scored where it runs; results are put back in order). The figures:
:mod:`attica.evaluate.suite_result`; the tables: :mod:`attica.evaluate.suite_tables`.
"""

from __future__ import annotations

import dataclasses
import math
import multiprocessing
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import numpy as np

from attica.data import Recording
from attica.evaluate.core import VARIANTS, Method, attica_method, method_kind
from attica.evaluate.estimate import Estimate, as_estimate
from attica.evaluate.parallel import START_METHOD
from attica.evaluate.suite_result import CaseScore, MethodInfo, SuiteResult, recovery_stats
from attica.metrics import Errors, error_angles, evaluate
from attica.settings import make_settings
from attica.sim import GRADES, SimConfig, simulate_with_truth

__all__ = [
    "CONDITIONS",
    "CONVERGENCE",
    "KINDS",
    "PEERS",
    "QUICK",
    "SEEDS",
    "CaseScore",
    "Condition",
    "MethodInfo",
    "SuiteResult",
    "condition",
    "recovery_stats",
    "recovery_times",
    "run_case",
    "run_suite",
    "score_method",
    "suite_methods",
]

BASE_RATE = 285.714
"""Hz: the rate of the conditions that do not set one (BROAD's)."""

CONVERGENCE = 5.0
"""s: not scored at the start of every recording (the filters' initial convergence)."""

RECOVERY_DEG = 2.0
"""deg: the error a method must be back within after a clipping episode."""

RECOVERY_HOLD = 1.0
"""s: how long the error must stay within :data:`RECOVERY_DEG` to count as recovered."""

EPISODE_GAP = 0.25
"""s: clipped samples closer than this belong to one clipping episode."""

SEEDS = tuple(range(1, 11))
"""The seeds every condition is simulated with."""

QUICK = ("baseline", "rate-50", "mag-start", "clipped")
"""The conditions of the quick suite (``attica eval --suite --quick``: one seed, 20 s each)."""

QUICK_SEEDS = (1,)
QUICK_DURATION = 20.0

KINDS = ("ars", "kf", "ekf", "mekf6", "mars", "mekf")
"""attica's methods the suite runs by default (kinds and variants of :data:`attica.evaluate.VARIANTS`)."""

PEERS = ("vqf6", "vqf9", "fusion6", "fusion9")
"""The peers the suite runs by default (their library defaults)."""

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


# --- methods -----------------------------------------------------------------------------------------


def suite_methods(kinds: Sequence[str], peers: Sequence[str], gyro_range: float = 0.0) -> list[Method]:
    """The methods of a suite run: attica's kinds and variants, then the peers (exact names).

    Parameters
    ----------
    kinds : sequence of str
        attica kinds or variants (``ars``, ``mekf6`` ...), each on its default settings.
    peers : sequence of str
        Names of :data:`attica.peers.PEERS` (``vqf9``, ``fusion6@tuned`` ...).
    gyro_range : float
        The sensor's gyro range in rad/s (0: leave the methods' default), given to attica's filters
        (``gyro_range``) and Fusion (``gyroscope_range``).

    Returns
    -------
    list of Method
        Named as in ``attica eval`` (the range is not part of the name).

    """
    from attica.peers import FUSION_DEFAULT, TUNED, _run_fusion, peer_by_name

    out: list[Method] = []
    for name in kinds:
        kind = method_kind(name)
        # the sensor's range, to the kinds that have one (tilt, accel only, has none)
        has_range = hasattr(make_settings(kind, None, 0.01), "gyro_range")
        over = {"gyro_range": gyro_range} if gyro_range > 0 and has_range else None
        if name in VARIANTS:
            m = attica_method(kind, overrides=over, variant=name)
        else:
            m = attica_method(kind, overrides=over)
        out.append(dataclasses.replace(m, name=name))
    for name in peers:
        p = peer_by_name(name)
        if p.library == "imufusion" and gyro_range > 0:
            params = FUSION_DEFAULT if p.setting == "default" else {**FUSION_DEFAULT, **TUNED["fusion"][0]}
            params = {**params, "gyroscope_range": math.degrees(gyro_range)}
            p = dataclasses.replace(p, runner=partial(_run_fusion, nine=p.nine_axis, params=params))
        out.append(Method(p.name, p.library, p.nine_axis, p.setting, p.run, p.note, p.estimate))
    return out


# --- one case ------------------------------------------------------------------------------------------


def _episodes(clipped: np.ndarray, rate: float) -> list[tuple[int, int]]:
    """(first, last) sample of each clipping episode (runs less than :data:`EPISODE_GAP` apart merged)."""
    idx = np.flatnonzero(clipped)
    if idx.size == 0:
        return []
    gap = max(1, int(round(EPISODE_GAP * rate)))
    cuts = np.flatnonzero(np.diff(idx) > gap)
    starts = np.concatenate([[idx[0]], idx[cuts + 1]])
    ends = np.concatenate([idx[cuts], [idx[-1]]])
    return [(int(a), int(b)) for a, b in zip(starts, ends)]


def recovery_times(
    err_deg: np.ndarray, episodes: Sequence[tuple[int, int]], rate: float
) -> tuple[float, ...]:
    """Seconds from each episode's first unclipped sample until ``err_deg`` stays within the bound.

    Parameters
    ----------
    err_deg : ndarray, shape (N,)
        The judged error per sample in degrees (NaN counts as outside).
    episodes : sequence of (first, last)
        Clipping episodes (sample indices), in order.
    rate : float
        Sample rate in Hz.

    Returns
    -------
    tuple of float
        Per episode the time until the error is within :data:`RECOVERY_DEG` for :data:`RECOVERY_HOLD` s,
        looked for before the next episode starts (or the recording ends); NaN when it is not.

    """
    hold = max(1, int(round(RECOVERY_HOLD * rate)))
    bad = np.concatenate([[0], np.cumsum(~(err_deg <= RECOVERY_DEG))])
    out = []
    for k, (_, last) in enumerate(episodes):
        first = last + 1
        stop = episodes[k + 1][0] if k + 1 < len(episodes) else len(err_deg)
        i = np.arange(first, stop - hold + 1)
        ok = i[bad[i + hold] == bad[i]]
        out.append(float((ok[0] - first) / rate) if ok.size else math.nan)
    return tuple(out)


def score_method(m: Method, rec: Recording, score_from: float) -> tuple[Errors, Estimate]:
    """One method on one simulated recording, scored as the suite scores it.

    Parameters
    ----------
    m : Method
        The method (:func:`suite_methods`, or :func:`~attica.evaluate.core.attica_method` with overrides).
    rec : Recording
        The simulation (with ``quat_true``).
    score_from : float
        Scored from this time in s (the condition's ``score_from``), and only the rows the method scores.

    Returns
    -------
    tuple of Errors and Estimate
        The BROAD RMSEs and the method's estimate.

    """
    assert rec.quat_true is not None
    est = as_estimate(m.outcome(rec), len(rec), f"{m.name} on {rec.name}")
    mask = rec.t >= score_from
    if est.scored is not None:
        mask = mask & np.asarray(est.scored, np.bool_)
    return evaluate(est.q, rec.quat_true, mask), est


def run_case(
    cond: Condition, seed: int, kinds: Sequence[str], peers: Sequence[str], duration: float | None = None
) -> CaseScore:
    """Simulate one condition with one seed and score every method on it.

    Parameters
    ----------
    cond : Condition
        The condition.
    seed : int
        The seed of the simulation.
    kinds, peers : sequence of str
        The methods (:func:`suite_methods`).
    duration : float, optional
        Shorter recordings (the quick suite).

    Returns
    -------
    CaseScore
        The errors after :data:`CONVERGENCE` and the clip recovery times per method.

    """
    rec, truth = simulate_with_truth(cond.config(seed, duration))
    assert rec.quat_true is not None
    clipped = np.asarray(truth.gyr_clipped.any(axis=1), np.bool_)
    episodes = _episodes(clipped, rec.rate)
    errors: dict[str, Errors] = {}
    recovery: dict[str, tuple[float, ...]] = {}
    for m in suite_methods(kinds, peers, cond.gyro_range):
        errors[m.name], est = score_method(m, rec, cond.score_from)
        rec_times: tuple[float, ...] = ()
        if episodes:
            total, _, incl = error_angles(est.q, rec.quat_true)
            rec_times = recovery_times(np.degrees(total if m.nine_axis else incl), episodes, rec.rate)
        recovery[m.name] = rec_times
    return CaseScore(cond.name, seed, errors, recovery, int(np.count_nonzero(clipped)))


# --- the suite -----------------------------------------------------------------------------------------


def run_suite(
    kinds: Sequence[str] = KINDS,
    peers: Sequence[str] = PEERS,
    conditions: Sequence[Condition] = CONDITIONS,
    seeds: Sequence[int] = SEEDS,
    duration: float | None = None,
    jobs: int = 1,
    done: Callable[[int], None] | None = None,
) -> SuiteResult:
    """Run the suite: every condition with every seed, every method on each.

    Parameters
    ----------
    kinds, peers : sequence of str
        attica kinds/variants and peer names (:func:`suite_methods`).
    conditions : sequence of Condition
        The conditions (:data:`CONDITIONS` by default).
    seeds : sequence of int
        The seeds (:data:`SEEDS`).
    duration : float, optional
        Shorten every recording to this many seconds (the quick suite).
    jobs : int
        Worker processes (``spawn``, as :mod:`attica.evaluate.parallel`); 1 runs in this process. The
        figures do not depend on it.
    done : callable, optional
        Called with the number of cases finished so far (a progress bar).

    Returns
    -------
    SuiteResult
        Every case, in (condition, seed) order.

    Raises
    ------
    ValueError
        For jobs < 1 or an empty selection.

    """
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    if not conditions or not seeds or not (kinds or peers):
        raise ValueError("the suite needs at least one condition, one seed and one method")
    tasks = [(c, s) for c in conditions for s in seeds]
    infos = [MethodInfo(m.name, m.family, m.nine_axis) for m in suite_methods(kinds, peers)]
    cases: list[CaseScore] = []
    if jobs == 1:
        for c, s in tasks:
            cases.append(run_case(c, s, kinds, peers, duration))
            if done is not None:
                done(len(cases))
    else:
        ctx = multiprocessing.get_context(START_METHOD)
        with ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as ex:
            futures = [ex.submit(run_case, c, s, tuple(kinds), tuple(peers), duration) for c, s in tasks]
            for f in futures:
                cases.append(f.result())
                if done is not None:
                    done(len(cases))
    return SuiteResult(list(conditions), tuple(seeds), infos, cases, duration, CONVERGENCE)

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
from functools import partial

import numpy as np

from attica.data import Recording
from attica.evaluate.core import VARIANTS, Method, attica_method, method_kind
from attica.evaluate.estimate import Estimate, as_estimate
from attica.evaluate.parallel import START_METHOD
from attica.evaluate.suite_result import CaseScore, MethodInfo, SuiteResult, recovery_stats
from attica.metrics import Errors, error_angles, evaluate
from attica.settings import make_settings
from attica.sim import simulate_with_truth
from attica.sim.conditions import BASE_RATE, CLIP, CONDITIONS, CONVERGENCE, Condition, condition

__all__ = [
    "BASE_RATE",
    "CLIP",
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

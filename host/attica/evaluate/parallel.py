"""Scoring trials in parallel: in this process, on worker processes, or on a Dask cluster.

Every (method, trial) pair is one task: :func:`score_trial` runs the method on the recording and scores
it (and keeps a :class:`~attica.evaluate.trace.Trace` for the plots when asked). The same function runs
wherever the task goes, on the same inputs, so the numbers are the serial run's bit for bit; the
results are put back in (method, trial) order whatever order the tasks finish in. Only the measured run
time (``seconds``) differs from one run to the next.

- ``jobs=1``: in this process, one task after the other.
- ``jobs=N``: a :class:`concurrent.futures.ProcessPoolExecutor` of N processes started with the
  ``spawn`` method (the same on Linux, macOS and Windows; nothing of this process's state is inherited).
  The recordings are sent to each worker once, when it starts; a task then sends the method (which must
  pickle: attica's filters and the peers do, a function defined inside another function does not) and
  the trial's index. As always with ``spawn``, a script that starts workers must do its work under
  ``if __name__ == "__main__":`` (the workers import the main module again); ``attica eval`` does.
- ``scheduler="tcp://host:port"``: a ``dask.distributed`` client of that scheduler (``pip install
  'attica[dask]'``); the recordings are scattered to the cluster once, the tasks go by ``client.submit``
  and are collected with ``as_completed``. The workers must run the same attica (checked on connecting)
  for the numbers to be the same as here.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import time
import uuid
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from types import TracebackType
from typing import TYPE_CHECKING, Any

import numpy as np

from attica.data import Recording
from attica.evaluate.estimate import as_estimate
from attica.evaluate.trace import Trace, make_trace
from attica.metrics import Errors, Stated, evaluate, stated

if TYPE_CHECKING:
    from attica.evaluate.core import Method

__all__ = ["DASK_HINT", "DaskMissingError", "Outcome", "TrialPool", "default_jobs", "score_trial"]

DASK_HINT = "pip install 'attica[dask]'"
"""How to install the Dask client."""

START_METHOD = "spawn"
"""How worker processes start (see the module docstring)."""

DASK_TIMEOUT = "10s"
"""How long to try to reach a Dask scheduler."""


class DaskMissingError(RuntimeError):
    """``dask.distributed`` is not installed here."""


def default_jobs() -> int:
    """Worker processes by default: every core (``os.cpu_count()``)."""
    return os.cpu_count() or 1


@dataclass(frozen=True)
class Outcome:
    """One method on one trial: the BROAD errors, run time, notes, plot trace and stated covariance.

    The trace only when asked for; the stated covariance against the errors for a method that states one.
    """

    errors: Errors
    seconds: float
    notes: tuple[str, ...] = ()
    trace: Trace | None = None
    stated: Stated | None = None


def score_trial(method: Method, rec: Recording, curves: bool = False) -> Outcome:
    """Run ``method`` on ``rec`` and score it against the truth (over ``movement`` and the rows it scores).

    Raises
    ------
    ValueError
        When the recording has no ground truth or the method returns the wrong shape.

    """
    if rec.quat_true is None:
        raise ValueError(f"{rec.name}: no ground truth (opt_quat / quat_* columns)")
    t0 = time.perf_counter()
    est = as_estimate(method.outcome(rec), len(rec), f"{method.name} on {rec.name}")
    seconds = time.perf_counter() - t0
    scored = rec.movement
    if est.scored is not None:
        scored = np.asarray(est.scored, dtype=np.bool_) & (True if scored is None else scored)
    errors = evaluate(est.q, rec.quat_true, scored)
    st = None if est.cov is None else stated(est.q, rec.quat_true, est.cov, scored)
    return Outcome(errors, seconds, tuple(est.notes), make_trace(est, rec) if curves else None, st)


# --- worker processes ----------------------------------------------------------------------------------

_WORKER_RECS: list[Recording] = []
"""The recordings of a worker process (set once by :func:`_init_worker`)."""


def _init_worker(recs: list[Recording]) -> None:
    _WORKER_RECS[:] = recs


def _score_index(method: Method, index: int, curves: bool) -> Outcome:
    return score_trial(method, _WORKER_RECS[index], curves)


def _attica_version() -> str:
    from attica import __version__

    return str(__version__)


def _check_picklable(methods: Sequence[Method]) -> None:
    for m in methods:
        try:
            pickle.dumps(m)
        except (pickle.PicklingError, AttributeError, TypeError) as exc:
            raise ValueError(
                f"method {m.name!r} cannot be sent to worker processes ({exc}); give it a run function "
                "defined at module level (or a functools.partial of one), or run with jobs=1"
            ) from None


def _dask() -> Any:
    try:
        import distributed
    except ImportError:
        raise DaskMissingError(f"a Dask scheduler needs dask.distributed: {DASK_HINT}") from None
    return distributed


Done = Callable[[int, int], None]
"""Called as ``done(method_index, trial_index)`` in this process when a task has finished."""


class TrialPool:
    """Where :func:`attica.evaluate.run_methods` runs its tasks; a context manager.

    Parameters
    ----------
    jobs : int or None
        Worker processes (None: :func:`default_jobs`); 1 runs everything in this process.
    scheduler : str or None
        Address of a Dask scheduler (``tcp://host:8786``); overrides ``jobs``.

    Raises
    ------
    ValueError
        When ``jobs`` < 1.
    DaskMissingError
        When a scheduler is given and ``dask.distributed`` is not installed.

    """

    def __init__(self, jobs: int | None = 1, scheduler: str | None = None) -> None:
        self.jobs = default_jobs() if jobs is None else int(jobs)
        if self.jobs < 1:
            raise ValueError(f"jobs must be >= 1, got {self.jobs}")
        self.scheduler = scheduler
        if scheduler is not None:
            _dask()
        self._executor: ProcessPoolExecutor | None = None
        self._client: Any = None
        self._in_process = False
        self._shipped: list[Recording] = []
        """The recordings the workers hold (kept alive, so that identity comparisons stay sound)."""
        self._remote: list[Any] = []

    def __enter__(self) -> TrialPool:
        if self.scheduler is not None and self._client is None:
            self._connect()
        return self

    def __exit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def close(self) -> None:
        """Stop the worker processes / leave the Dask cluster (the cluster itself keeps running)."""
        if self._executor is not None:
            self._executor.shutdown(wait=True, cancel_futures=True)
            self._executor = None
        if self._client is not None:
            self._remote = []
            self._client.close()
            self._client = None
        self._shipped = []

    def _holds(self, recs: Sequence[Recording]) -> bool:
        return len(recs) == len(self._shipped) and all(a is b for a, b in zip(recs, self._shipped))

    def _connect(self) -> None:
        distributed = _dask()
        try:
            client = distributed.Client(self.scheduler, timeout=DASK_TIMEOUT, set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            raise ConnectionError(f"cannot reach the Dask scheduler at {self.scheduler}: {exc}") from None
        try:
            versions = client.run(_attica_version)
        except Exception as exc:  # whatever the workers raise: they cannot run attica
            client.close()
            raise RuntimeError(f"the Dask workers at {self.scheduler} cannot run attica: {exc}") from None
        here = _attica_version()
        other = sorted({v for v in versions.values() if v != here})
        if other:
            client.close()
            raise RuntimeError(
                f"the Dask workers at {self.scheduler} run attica {', '.join(other)}, this is {here}: "
                "their numbers would not be this version's"
            )
        self._client = client

    def describe(self) -> str:
        """Where the tasks of the last :meth:`run` ran, for the command's summary line."""
        if self.scheduler is not None:
            workers = len(self._client.scheduler_info().get("workers", {})) if self._client else 0
            return f"on the Dask cluster at {self.scheduler} ({workers} workers)"
        if self.jobs == 1 or self._in_process:
            return "in one process"
        return f"on {self.jobs} processes"

    def run(
        self, methods: Sequence[Method], recs: Sequence[Recording], curves: bool, done: Done
    ) -> list[list[Outcome]]:
        """Every method on every recording: ``outcomes[method][trial]``, whatever order they finish in."""
        tasks = [(i, j) for i in range(len(methods)) for j in range(len(recs))]
        out: list[list[Outcome | None]] = [[None] * len(recs) for _ in methods]
        if self.scheduler is not None:
            self._run_dask(methods, recs, curves, tasks, out, done)
        elif self.jobs == 1 or len(tasks) <= 1:  # one task: starting a worker would only cost time
            self._in_process = True
            for i, j in tasks:
                out[i][j] = score_trial(methods[i], recs[j], curves)
                done(i, j)
        else:
            self._in_process = False
            self._run_processes(methods, recs, curves, tasks, out, done)
        return [[o for o in row if o is not None] for row in out]

    def _run_processes(
        self,
        methods: Sequence[Method],
        recs: Sequence[Recording],
        curves: bool,
        tasks: list[tuple[int, int]],
        out: list[list[Outcome | None]],
        done: Done,
    ) -> None:
        _check_picklable(methods)
        if self._executor is None or not self._holds(recs):
            if self._executor is not None:
                self._executor.shutdown(wait=True)
            self._executor = ProcessPoolExecutor(
                max_workers=self.jobs,
                mp_context=multiprocessing.get_context(START_METHOD),
                initializer=_init_worker,
                initargs=(list(recs),),
            )
            self._shipped = list(recs)
        futures: dict[Future[Outcome], tuple[int, int]] = {
            self._executor.submit(_score_index, methods[i], j, curves): (i, j) for i, j in tasks
        }
        try:
            for fut in as_completed(futures):
                i, j = futures[fut]
                out[i][j] = fut.result()
                done(i, j)
        except BaseException:
            for fut in futures:
                fut.cancel()
            raise

    def _run_dask(
        self,
        methods: Sequence[Method],
        recs: Sequence[Recording],
        curves: bool,
        tasks: list[tuple[int, int]],
        out: list[list[Outcome | None]],
        done: Done,
    ) -> None:
        distributed = _dask()
        if self._client is None:
            self._connect()
        client = self._client
        if not self._holds(recs):
            self._remote = client.scatter(list(recs), hash=False)
            self._shipped = list(recs)
        run = uuid.uuid4().hex[:12]
        futures: list[Any] = []
        where: dict[str, tuple[int, int]] = {}
        for i, j in tasks:
            key = f"attica-eval-{run}-{i}-{j}"
            fut = client.submit(score_trial, methods[i], self._remote[j], curves, key=key, pure=False)
            futures.append(fut)
            where[key] = (i, j)
        try:
            for fut in distributed.as_completed(futures, loop=client.loop):
                i, j = where[fut.key]
                out[i][j] = fut.result()
                done(i, j)
        except BaseException:
            client.cancel(futures)
            raise

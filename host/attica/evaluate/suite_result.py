"""The figures of a generalisation suite run (:mod:`attica.evaluate.suite`).

Per case (condition and seed), per condition (the mean over the seeds), attica's best against VQF, the
clip recovery, and all of it as JSON-able data.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from attica.metrics import Errors

if TYPE_CHECKING:
    from attica.evaluate.suite import Condition

__all__ = ["CaseScore", "MethodInfo", "SuiteResult", "recovery_stats"]


@dataclass(frozen=True)
class CaseScore:
    """Every method on one condition and seed.

    Attributes
    ----------
    condition : str
        The condition's name.
    seed : int
        The seed.
    errors : dict of str to Errors
        Per method the BROAD RMSEs after the condition's ``score_from``.
    recovery : dict of str to tuple of float
        Per method the clip recovery time in s of each clipping episode (NaN: not recovered before the
        next episode or the end); empty tuples when the gyro did not clip.
    clipped : int
        Samples with a clipped gyro axis.

    """

    condition: str
    seed: int
    errors: dict[str, Errors]
    recovery: dict[str, tuple[float, ...]]
    clipped: int


@dataclass(frozen=True)
class MethodInfo:
    """What the tables need of a method: its name, whether it is attica's, how it is judged."""

    name: str
    family: str
    nine_axis: bool


@dataclass
class SuiteResult:
    """Every case of a suite run, with the per-condition figures and the comparison with VQF."""

    conditions: list[Condition]
    seeds: tuple[int, ...]
    methods: list[MethodInfo]
    cases: list[CaseScore]
    duration: float | None = None
    """The quick suite's recording length (None: each condition's own)."""
    convergence: float = 5.0
    """s not scored at the start of each recording (:data:`attica.evaluate.suite.CONVERGENCE`)."""

    def _cases(self, cond: str) -> list[CaseScore]:
        return [c for c in self.cases if c.condition == cond]

    def mean(self, method: str, cond: str, metric: str | None = None) -> float:
        """Mean over the seeds of a method's RMSE on a condition (``metric``: the judged one by default)."""
        info = next(m for m in self.methods if m.name == method)
        key = metric or ("total" if info.nine_axis else "inclination")
        return float(np.mean([getattr(c.errors[method], key) for c in self._cases(cond)]))

    def recovery(self, method: str, cond: str) -> list[float]:
        """Every clip recovery time of a method on a condition (all seeds), in s (NaN: not recovered)."""
        return [t for c in self._cases(cond) for t in c.recovery[method]]

    def clipped(self, cond: str) -> bool:
        """Whether the gyro clipped in a condition."""
        return any(c.clipped for c in self._cases(cond))

    def best(self, cond: str, nine: bool) -> tuple[str, float, float]:
        """The best of attica's methods of one kind of axes on a condition, its RMSE, its ratio to VQF's.

        The ratio is NaN when VQF (``vqf6``/``vqf9``) did not run; the name is empty when no attica
        method of that kind ran.
        """
        ours = [m.name for m in self.methods if m.family == "attica" and m.nine_axis == nine]
        if not ours:
            return "", math.nan, math.nan
        vals = [self.mean(n, cond) for n in ours]
        i = int(np.nanargmin(vals)) if not np.all(np.isnan(vals)) else 0
        vqf = "vqf9" if nine else "vqf6"
        ratio = vals[i] / self.mean(vqf, cond) if any(m.name == vqf for m in self.methods) else math.nan
        return ours[i], vals[i], ratio

    def comparisons(self, nine: bool, method: str | None = None) -> list[tuple[str, float]]:
        """(condition, attica / VQF) for attica's best (or one ``method``) against VQF of the same axes."""
        out = []
        vqf = "vqf9" if nine else "vqf6"
        for c in self.conditions:
            if c.magnetic and not nine:
                continue
            if method is None:
                ratio = self.best(c.name, nine)[2]
            else:
                ratio = self.mean(method, c.name) / self.mean(vqf, c.name)
            out.append((c.name, ratio))
        return out

    def summary(self) -> dict[str, Any]:
        """Share of comparisons where attica's best is ahead of VQF, the worst ratio, clip recovery.

        A comparison whose ratio is not finite (VQF's figure or every attica method's NaN: a method that
        failed on every seed) counts in ``of``, never as ahead, and is listed under ``failed``; the worst
        ratio is the worst finite one (absent when none is).
        """
        out: dict[str, Any] = {}
        both: list[tuple[str, str, float]] = []
        failed: list[str] = []
        total = 0
        for nine, label in ((False, "6-axis"), (True, "9-axis")):
            vqf = "vqf9" if nine else "vqf6"
            ran = {m.name for m in self.methods if m.nine_axis == nine and m.family == "attica"}
            if not ran or not any(m.name == vqf for m in self.methods):
                continue  # nothing to compare on these axes
            comp = self.comparisons(nine)
            ok = [(c, r) for c, r in comp if np.isfinite(r)]
            bad = [c for c, r in comp if not np.isfinite(r)]
            both += [(label, c, r) for c, r in ok]
            failed += [f"{label} {c}" for c in bad]
            total += len(comp)
            if comp:
                out[label] = {"ahead": sum(r < 1.0 for _, r in ok), "of": len(comp)}
                if bad:
                    out[label]["failed"] = bad
        if total:
            out["ahead"] = sum(r < 1.0 for _, _, r in both)
            out["of"] = total
            if both:
                worst = max(both, key=lambda x: x[2])
                out["worst_ratio"] = {"ratio": round(worst[2], 4), "axes": worst[0], "condition": worst[1]}
            if failed:
                out["failed"] = failed
        per_kind: dict[str, Any] = {}
        for m in self.methods:
            vqf = "vqf9" if m.nine_axis else "vqf6"
            if m.family != "attica" or not any(x.name == vqf for x in self.methods):
                continue
            comp = self.comparisons(m.nine_axis, m.name)
            finite = [r for _, r in comp if np.isfinite(r)]
            per_kind[m.name] = {
                "ahead": sum(r < 1.0 for r in finite),
                "of": len(comp),
                "worst_ratio": round(max(finite), 4) if finite else math.nan,
            }
            if len(finite) < len(comp):
                per_kind[m.name]["failed"] = [c for c, r in comp if not np.isfinite(r)]
        out["per_method"] = per_kind
        clip = [c.name for c in self.conditions if self.clipped(c.name)]
        if clip:
            out["clip_recovery"] = {
                m.name: recovery_stats([t for c in clip for t in self.recovery(m.name, c)])
                for m in self.methods
            }
        return out

    def as_dict(self) -> dict[str, Any]:
        """Every figure as JSON-able data (no timings: the same on every run)."""

        def clean(x: float) -> float | None:
            return round(float(x), 4) if np.isfinite(x) else None

        conds: dict[str, Any] = {}
        for c in self.conditions:
            cases = self._cases(c.name)
            entry: dict[str, Any] = {"what": c.what, "sim": _jsonable(c.sim), "grade": c.grade}
            entry["score_from_s"] = c.score_from
            entry["methods"] = {
                m.name: {
                    "rmse": clean(self.mean(m.name, c.name)),
                    **{k: clean(self.mean(m.name, c.name, k)) for k in ("total", "heading", "inclination")},
                    "per_seed": [clean(getattr(s.errors[m.name], "total" if m.nine_axis else "inclination"))
                                 for s in cases],
                    **({"recovery_s": [clean(t) for t in self.recovery(m.name, c.name)]}
                       if self.clipped(c.name) else {}),
                }
                for m in self.methods
            }  # fmt: skip
            for nine, label in ((False, "best_6axis"), (True, "best_9axis")):
                name, val, ratio = self.best(c.name, nine)
                if name and (nine or not c.magnetic):
                    entry[label] = {"method": name, "rmse": clean(val), "ratio_to_vqf": clean(ratio)}
            entry["clipped_samples"] = sum(s.clipped for s in cases)
            conds[c.name] = entry
        return {
            "convergence_s": self.convergence,
            "seeds": list(self.seeds),
            "duration_s": self.duration,
            "methods": {m.name: {"family": m.family, "nine_axis": m.nine_axis} for m in self.methods},
            "conditions": conds,
            "summary": _jsonable(self.summary()),
        }


def recovery_stats(times: Sequence[float]) -> dict[str, Any]:
    """Worst and median clip recovery time in s (NaN: "never" is among them), and how many met the target.

    Parameters
    ----------
    times : sequence of float
        Recovery times of episodes (NaN: not recovered).

    Returns
    -------
    dict
        ``worst``, ``median`` (NaN when that many did not recover), ``within_2s`` (episodes recovered
        within 2 s, issue 23's target) and ``episodes``.

    """
    t = np.sort(np.where(np.isnan(np.asarray(times, np.float64)), np.inf, times))
    worst = float(t[-1]) if t.size else 0.0
    median = float(t[(t.size - 1) // 2] + t[t.size // 2]) / 2.0 if t.size else 0.0
    return {
        "worst": worst if math.isfinite(worst) else math.nan,
        "median": median if math.isfinite(median) else math.nan,
        "within_2s": int(np.count_nonzero(t <= 2.0)),
        "episodes": int(t.size),
    }


def _jsonable(x: Any) -> Any:
    """Tuples as lists, non-finite floats as None."""
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x

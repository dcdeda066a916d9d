"""Stage B of the oracle: the library as ``attica._native`` in a fresh Python process.

The worker is started as ``python -m attica_dev.mutate --binding-worker`` with the snapshot's
``host`` and ``tools`` on ``PYTHONPATH``; the checks live in the ``checks_*`` modules beside this one.
"""

from __future__ import annotations

import functools
import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from attica_dev.mutation.checks_can import _can_check, _node_sessions
from attica_dev.mutation.checks_contracts import _calib_check, _contract_check, _node_check
from attica_dev.mutation.checks_edges_euler import (
    _ekf_bounds_check,
    _ekf_recover_check,
    _ekf_repair_check,
    _ekf_trig_check,
    _gyro_edges_check,
)
from attica_dev.mutation.checks_edges_io import (
    _accel_limit_check,
    _can_null_check,
    _node_calib_rules_check,
    _node_parts_check,
    _node_select_gain_check,
    _step_n_flags_check,
)
from attica_dev.mutation.checks_edges_quat import (
    _mars_bias_mag_check,
    _mars_candidate_check,
    _mars_fast_check,
    _mekf_edges_check,
    _mekf_pd_check,
    _mekf_recovery_check,
    _wrap_pi_check,
)
from attica_dev.mutation.checks_filter import (
    _names_check,
    _outputs_check,
    _retune_check,
    _sensor_check,
    _stages_check,
    _steps_check,
)


def _binding_run(
    tree: Path, so: Path, expect: dict[str, str] | None, hint: str, timeout: float
) -> tuple[str, dict[str, str]]:
    """Run the binding checks on ``so`` with the Python of ``tree`` (a base's snapshot).

    Returns ("ok" | "differs: CHECK" | "!reason", the digests computed).
    """
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(tree / "host"), str(tree / "tools")])
    with tempfile.TemporaryDirectory(prefix="att_mut_") as tmp:
        exp = Path(tmp) / "expect.json"
        res = Path(tmp) / "result.json"
        exp.write_text(json.dumps(expect or {}))
        cmd = [
            sys.executable,
            "-m",
            "attica_dev.mutate",
            "--binding-worker",
            str(so),
            str(exp),
            str(res),
            hint,
        ]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
        except subprocess.TimeoutExpired:
            return "!timeout", {}
        if proc.returncode != 0 or not res.exists():
            return (
                f"!exit {proc.returncode}: {proc.stderr.strip().splitlines()[-1:] if proc.stderr else ''}",
                {},
            )
        data = json.loads(res.read_text())
    return str(data["status"]), dict(data["digests"])


def _binding_worker(so: str, expect_path: str, result_path: str, hint: str) -> int:
    """Stage B inside the worker process: load ``so`` as attica._native and run every check."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("attica._native", so)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    sys.modules["attica._native"] = mod
    import attica
    from attica import _build

    attica._native = mod
    _build.is_stale = lambda: False  # the checkout's stamp says nothing about this library
    from attica import native

    assert native.lib is mod.lib
    expect: dict[str, str] = json.loads(Path(expect_path).read_text())
    out: dict[str, str] = {}
    status = "ok"
    for name, check in _ordered(list(_binding_checks()), hint):
        import numpy as np

        with np.errstate(all="ignore"):
            out[name] = check()
        if expect and expect.get(name) != out[name]:
            status = f"differs: {name}"
            break
    Path(result_path).write_text(json.dumps({"status": status, "digests": out}))
    return 0


def _ordered(items: list[tuple[str, Any]], hint: str) -> list[tuple[str, Any]]:
    """Items whose name mentions a word of ``hint`` first (the checks of the mutated file's kind)."""
    words = [w for w in hint.split(",") if w]
    return sorted(items, key=lambda it: 0 if any(w in it[0] for w in words) else 1)


def _binding_checks() -> Iterator[tuple[str, Callable[[], str]]]:
    """The stage B checks: name -> a function returning the digest of what it saw."""
    from attica.settings import implemented_kinds
    from attica_dev import digests

    sim = functools.cache(digests.sim_stream)
    digests.sim_stream = lambda: tuple(x.copy() for x in sim())  # type: ignore[assignment,return-value]
    for c in digests.cases():
        if not c.name.startswith("input."):
            yield f"digest:{c.name}", c.compute
    for kind in implemented_kinds():
        yield f"steps:{kind.label}", functools.partial(_steps_check, kind)
        yield f"contract:{kind.label}", functools.partial(_contract_check, kind)
        yield f"outputs:{kind.label}", functools.partial(_outputs_check, kind)
        yield f"retune:{kind.label}", functools.partial(_retune_check, kind)
    yield "contract:calib", _calib_check
    yield "calib:stages", _stages_check
    yield "contract:node", _node_check
    for kind in implemented_kinds():
        yield f"node:{kind.label}:sessions", functools.partial(_node_sessions, kind)
    yield "can:codec", _can_check
    yield "names", _names_check
    yield "sensor", _sensor_check
    yield "edges:ekf:bounds", _ekf_bounds_check
    yield "edges:ekf:trig", _ekf_trig_check
    yield "edges:ekf:repair", _ekf_repair_check
    yield "edges:ekf:recover", _ekf_recover_check
    yield "edges:gyro:edges", _gyro_edges_check
    yield "edges:mars:fast", _mars_fast_check
    yield "edges:mars:bias_mag", _mars_bias_mag_check
    yield "edges:mars:candidate", _mars_candidate_check
    yield "edges:mekf:recovery", _mekf_recovery_check
    yield "edges:mekf:edges", _mekf_edges_check
    yield "edges:mekf:pd", _mekf_pd_check
    yield "edges:math:wrap_pi", _wrap_pi_check
    yield "edges:sensor:accel_limit", _accel_limit_check
    yield "edges:filter:step_n_flags", _step_n_flags_check
    yield "edges:node:calib_rules", _node_calib_rules_check
    yield "edges:node:select_gain", _node_select_gain_check
    yield "edges:node:parts", _node_parts_check
    yield "edges:can:null", _can_null_check  # last: a mutant may crash on it

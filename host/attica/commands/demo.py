"""``attica demo``: what ``make run`` shows.

Simulates (the same data as ``attica run`` with the same options), runs the ARS in C and in the numpy
reference, proves bit-exact agreement and prints the attitude error and the gyro bias estimate.
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from attica.commands._common import (
    add_sim_arguments,
    check_data_or_sim,
    filter_settings,
    fit_to_simulation,
    sim_config,
)
from attica.commands.run import crosscheck_line, error_line, run_native
from attica.settings import FilterKind, Flag

NAME = "demo"
HELP = "simulate, run the ARS in C and in the numpy reference, prove the bits agree, print the error"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``attica demo`` (the simulation options of ``attica run``, same defaults)."""
    add_sim_arguments(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    """``attica demo``."""
    from attica.commands._common import CliError
    from attica.sim import simulate_with_truth

    check_data_or_sim(args)
    cfg = sim_config(args)
    try:
        rec, truth = simulate_with_truth(cfg)
    except ValueError as exc:
        raise CliError(f"simulation: {exc} (use a longer --duration or fewer --breaks)") from None
    print(
        f"simulated {cfg.duration:g} s of IMU data at {cfg.rate:g} Hz (seed {cfg.seed}): "
        f"{len(rec.gyr)} samples, gyro bias up to {cfg.gyro_bias} rad/s, {cfg.taps} taps"
    )
    kind = FilterKind.ARS
    overrides: dict[FilterKind, dict[str, Any]] = {kind: {}}
    fit_to_simulation(args, overrides)
    settings = filter_settings(kind, rec.rate, overrides[kind])
    out = run_native(kind, rec, settings, not args.quiet)
    ok, lines = crosscheck_line(kind, rec, settings, not args.quiet)
    print("\n".join(lines))
    print(error_line(kind, rec, out, settings))
    learnt = np.nonzero(out["flags"] & Flag.BIAS_UPDATED)[0]
    if learnt.size:
        i = int(learnt[-1])  # the estimate changes only at rest: compare where it was last updated
        print(
            f"        gyro bias estimate {np.round(out['gyro_bias'][i], 4)} rad/s "
            f"at t = {i / rec.rate:.1f} s (true {np.round(truth.gyr_bias[i], 4)}; "
            f"it drifts {cfg.gyro_bias_drift} rad/s/sqrt(s))"
        )
    return 0 if ok else 1

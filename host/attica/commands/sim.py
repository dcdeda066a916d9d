"""``attica sim``: write a simulated IMU recording with ground truth (.npz, BROAD layout)."""

from __future__ import annotations

import argparse
from pathlib import Path

from attica.commands._common import (
    CliError,
    add_sim_arguments,
    check_data_or_sim,
    check_output_file,
    simulate,
)

NAME = "sim"
HELP = "write a simulated IMU recording with ground truth (.npz in BROAD layout)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``attica sim``."""
    add_sim_arguments(p)
    p.add_argument(
        "-o", "--output", required=True, help="output path: .npz (BROAD layout) or .csv; no suffix: .npz"
    )


def run(args: argparse.Namespace) -> int:
    """``attica sim``."""
    check_data_or_sim(args)
    out = Path(args.output)
    if out.is_dir():
        raise CliError(f"output {out} is a directory (give a file name, e.g. {out / 'sim.npz'})")
    if out.suffix == "":
        out = out.with_name(out.name + ".npz")
    if out.suffix.lower() not in (".npz", ".csv"):
        raise CliError(f"cannot write {out}: the output must be .npz or .csv")
    check_output_file(out)
    rec = simulate(args)
    rec.save(out)
    print(f"wrote {out}: {len(rec.gyr)} samples at {rec.rate:g} Hz ({len(rec.gyr) / rec.rate:.1f} s)")
    return 0

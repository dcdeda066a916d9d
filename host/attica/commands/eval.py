"""``attica eval``: accuracy on recorded trials with the BROAD metrics, peers side by side.

Runs attica's C filters (and with ``--peers`` other people's filters) over every recording of a
directory, prints the RMSE per trial, per group and on average (6-axis methods by inclination, 9-axis
methods by total error, in tables that fit 110 columns; ``--wide`` for one table each), and with
``--out`` writes results.json and PNG plots. ``--grid`` runs the grid search that chose the defaults.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from attica.commands._common import (
    CliError,
    add_unit_check_argument,
    check_units,
    parse_kinds,
    prepare_output_dir,
    warn,
)
from attica.settings import FilterKind, Preset, implemented_kinds

NAME = "eval"
HELP = "accuracy on recorded trials (BROAD metrics): tables, plots, JSON, peers side by side"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``attica eval``."""
    choices = ", ".join(k.label for k in FilterKind)
    p.add_argument("--filter", default="all", help=f"'all' or comma-separated kinds ({choices})")
    p.add_argument("--data", required=True, help="directory of trials (.npz/.csv/.hdf5/.mat) or one file")
    p.add_argument(
        "--preset",
        default="default",
        choices=["default", "seed", "both"],
        help="settings preset of attica's filters (default: default)",
    )
    p.add_argument("--out", help="directory for results.json and the PNG plots (created if missing)")
    p.add_argument(
        "--peers",
        nargs="?",
        const="all",
        help="also run other people's filters: all installed ones, or comma-separated names (vqf9,fusion9)",
    )
    p.add_argument("--grid", action="store_true", help="run the grid search of the defaults instead")
    p.add_argument("--limit", type=int, help="only the first N trials")
    p.add_argument("--wide", action="store_true", help="one table per kind of method, however wide")
    p.add_argument("--no-plots", action="store_true", help="write no PNGs")
    add_unit_check_argument(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


def _peers(spec: str | None) -> list[Any]:
    """The peer methods asked for; unknown or missing names are CliErrors (before any work)."""
    from attica.evaluate import peer_methods
    from attica.peers import PEERS

    if spec is None:
        return []
    if spec in ("", "all"):
        methods = peer_methods(None)
        if not methods:
            raise CliError("--peers: no peer library is installed (pip install '.[peers]')")
        return methods
    names = [n.strip() for n in spec.split(",") if n.strip()]
    if not names:
        raise CliError("--peers: empty selection; give all or names such as vqf9,fusion9")
    known = {p.name: p for p in PEERS}
    bases = {p.name.split("@")[0] for p in PEERS}
    unknown = [n for n in names if n not in known and n not in bases]
    if unknown:
        raise CliError(f"--peers: unknown peer(s) {', '.join(unknown)}; peers: {', '.join(sorted(known))}")
    missing = sorted(
        {p.library for p in PEERS if (p.name in names or p.name.split("@")[0] in names) and not p.installed}
    )
    if missing:
        raise CliError(f"--peers: {', '.join(missing)} not installed (pip install '.[peers]')")
    return peer_methods(names)


def run(args: argparse.Namespace) -> int:
    """``attica eval``."""
    from attica.evaluate import GRIDS, attica_method, format_summary, format_tables, load_trials, run_methods

    if args.limit is not None and args.limit < 1:
        raise CliError("--limit must be >= 1")
    if args.grid:
        allowed = [k for k in implemented_kinds() if k in GRIDS]
        kinds = allowed if args.filter == "all" else parse_kinds(args.filter, allowed)
        methods: list[Any] = []
    else:
        kinds = parse_kinds(args.filter)
        presets = [Preset.DEFAULT, Preset.SEED] if args.preset == "both" else [Preset.parse(args.preset)]
        methods = [attica_method(k, p) for p in presets for k in kinds] + _peers(args.peers)
    out = prepare_output_dir(Path(args.out)) if args.out else None
    plots = out is not None and not args.no_plots and not args.grid
    if plots:
        from attica.evaluate.plots import _pyplot

        try:
            _pyplot()
        except RuntimeError as exc:
            raise CliError(str(exc)) from None
    try:
        recs = load_trials(args.data, args.limit)
    except (FileNotFoundError, ValueError, RuntimeError) as exc:
        raise CliError(str(exc)) from None
    missing_truth = [r.name for r in recs if r.quat_true is None]
    if missing_truth:
        raise CliError(f"no ground truth (opt_quat / quat_* columns) in: {', '.join(missing_truth)}")
    print(f"{args.data}: {len(recs)} trials, {sum(len(r) for r in recs)} samples")
    for rec in recs:
        check_units(rec, args)
    if args.grid:
        return _grid(args, kinds, recs, out)
    t0 = time.perf_counter()
    report = run_methods(methods, recs, progress=not args.quiet, curves=plots)
    print(f"{len(methods)} methods x {len(recs)} trials in {time.perf_counter() - t0:.1f} s\n")
    print(format_tables(report, wide=args.wide))
    print(format_summary(report))
    if out is not None:
        data = {
            "command": " ".join(["attica", *sys.argv[1:]]) if sys.argv[1:2] == ["eval"] else "attica eval"
        }
        data.update(report.as_dict())
        (out / "results.json").write_text(json.dumps(data, indent=1))
        print(f"\nwrote {out / 'results.json'}")
        if plots:
            from attica.evaluate.plots import write_plots

            written = write_plots(report, recs, out)
            print(f"wrote {len(written)} plots to {out} (error_*.png, groups*.png)")
    return 0


def _grid(args: argparse.Namespace, kinds: list[FilterKind], recs: list[Any], out: Path | None) -> int:
    from attica.evaluate import GRIDS, METRICS, NINE_AXIS, grid_search

    if args.peers is not None:
        warn("--peers is ignored by --grid (it searches attica's settings only)")
    grids: dict[str, Any] = {}
    for kind in kinds:
        rows = grid_search(kind, recs, progress=not args.quiet)
        metric = "total" if kind in NINE_AXIS else "inclination"
        print(f"\ngrid {kind.label} ({len(rows)} points, ranked by mean {metric} RMSE); best 5:")
        for over, e in rows[:5]:
            print(f"  {e.total:7.2f} {e.heading:7.2f} {e.inclination:7.2f}  {over}")
        grids[kind.label] = {
            "grid": GRIDS[kind],
            "ranked": [{"settings": o, **{k: getattr(e, k) for k in METRICS}} for o, e in rows],
        }
    if out is not None:
        (out / "grid.json").write_text(json.dumps(grids, indent=1, default=str))
        print(f"wrote {out / 'grid.json'}")
    return 0

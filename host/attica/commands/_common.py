"""What several subcommands share: the error type, simulation options, recordings, settings."""

from __future__ import annotations

import argparse
import dataclasses
import enum
import math
import os
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from attica.checks import implied_gains, unit_problems
from attica.settings import FilterKind, make_settings


class CliError(Exception):
    """A user error: printed as ``attica: error: <message>`` without a traceback, exit status 2."""


def warn(message: str) -> None:
    """Print ``attica: warning: <message>`` on stderr."""
    print(f"attica: warning: {message}", file=sys.stderr, flush=True)


def note(message: str) -> None:
    """Print ``attica: note: <message>`` on stderr."""
    print(f"attica: note: {message}", file=sys.stderr, flush=True)


def progress(total: int, desc: str, enabled: bool, unit: str = "step") -> Any:
    """A tqdm bar on stderr, shown only on a terminal."""
    from tqdm import tqdm

    return tqdm(
        total=total,
        desc=desc,
        unit=unit,
        unit_scale=True,
        disable=not (enabled and sys.stderr.isatty()),
        leave=False,
        file=sys.stderr,
        mininterval=0.2,
    )


# --- simulation options ---------------------------------------------------------------------------

SIM_DEFAULTS: dict[str, Any] = {"duration": 60.0, "rate": 285.714, "seed": 0, "taps": 3, "breaks": 2}
"""The simulation every command makes when given no recording (``demo`` and ``run`` see the same data)."""


def add_sim_arguments(p: argparse.ArgumentParser, duration: float | None = None) -> None:
    """The simulation options (their None defaults: :func:`sim_config` fills them in).

    ``--duration --rate --seed --taps --breaks --condition --grade --declination``.
    """
    d = {**SIM_DEFAULTS, **({"duration": duration} if duration is not None else {})}
    g = p.add_argument_group("simulation (without --data)")
    g.add_argument(
        "--duration", type=float, help=f"seconds to simulate (default {d['duration']:g}; a --condition's own)"
    )
    g.add_argument(
        "--rate", type=float, help=f"sample rate in Hz (default {d['rate']:g}; a --condition's own)"
    )
    g.add_argument("--seed", type=int, help=f"random seed (default {d['seed']})")
    g.add_argument(
        "--taps", type=int, help=f"number of taps, short acceleration impulses (default {d['taps']})"
    )
    g.add_argument("--breaks", type=int, help=f"still pauses inside the motion (default {d['breaks']})")
    g.add_argument(
        "--condition",
        metavar="NAME",
        help=f"a condition of the generalisation suite ({', '.join(CONDITION_NAMES)}; docs/accuracy.md): "
        "its sensor, motion and disturbances, the same recording as the suite's for a --seed of 1-10; "
        "its own length and rate unless --duration / --rate are given",
    )
    g.add_argument(
        "--grade",
        choices=GRADE_NAMES,
        help="a sensor grade: its noise densities, gyro bias and calibration errors (default: the "
        "simulator's, or the condition's)",
    )
    g.add_argument(
        "--declination",
        type=float,
        metavar="DEG",
        help="the field's declination, deg east of true north (default 0: magnetic north is true north)",
    )
    p.set_defaults(_sim_defaults=d)


CONDITION_NAMES = (
    "baseline", "rate-50", "rate-100", "rate-1000", "consumer", "industrial", "mag-start", "moving-magnet",
    "long-rest", "near-clip", "clipped", "vibration",
)  # fmt: skip
"""The names of :data:`attica.sim.conditions.CONDITIONS` (for the help, without importing the simulator;
tests/test_cli_sim.py checks them)."""

GRADE_NAMES = ("consumer", "industrial")
"""The names of :data:`attica.sim.GRADES` (checked as CONDITION_NAMES)."""

SIM_OPTIONS = ("duration", "rate", "seed", "taps", "breaks", "condition", "grade", "declination")
_SIM_FIELDS = {"duration": "duration", "rate": "rate", "taps": "taps", "breaks": "rest_breaks"}


def sim_options_given(args: argparse.Namespace) -> list[str]:
    """The simulation options given explicitly on the command line."""
    return [f"--{k}" for k in SIM_OPTIONS if getattr(args, k, None) is not None]


def _condition(args: argparse.Namespace) -> Any:
    """The suite condition of ``--condition`` (None without it; a CliError naming the conditions)."""
    name = getattr(args, "condition", None)
    if name is None:
        return None
    if name not in CONDITION_NAMES:
        raise CliError(f"--condition {name!r}: unknown; the conditions are: {', '.join(CONDITION_NAMES)}")
    from attica.sim.conditions import condition

    return condition(name)


def sim_value(args: argparse.Namespace, name: str) -> Any:
    """A simulation option's value (its default when not given: the condition's, else the command's)."""
    v = getattr(args, name, None)
    if v is not None:
        return v
    cond = _condition(args) if name in _SIM_FIELDS else None
    if cond is not None:
        return getattr(cond.config(0), _SIM_FIELDS[name])
    return args._sim_defaults.get(name)


def _fit_breaks(cfg: Any) -> Any:
    """``cfg`` with as many of its still pauses as fit in its motion (a short simulation)."""
    motion = cfg.duration - cfg.rest_start - cfg.rest_end
    if motion > 0:
        # nb pauses of break_duration need motion left between them
        fit = max(0, math.ceil(motion / cfg.break_duration) - 1)
        cfg = dataclasses.replace(cfg, rest_breaks=min(cfg.rest_breaks, fit))
    return cfg


def sim_config(args: argparse.Namespace) -> Any:
    """The :class:`attica.sim.SimConfig` of the simulation options.

    Without ``--breaks``, a short simulation gets as many of the default still pauses as fit in it.
    ``--condition`` starts from the suite's condition (:meth:`attica.sim.conditions.Condition.config`:
    the options given replace its fields, a rate without a grade keeps its noise densities); ``--grade``
    sets the sensor grade's noise and errors; ``--declination`` (deg) the field's declination.
    """
    from attica.sim import GRADES, SimConfig

    cond = _condition(args)
    grade = getattr(args, "grade", None)
    seed = sim_value(args, "seed")
    if cond is not None:
        over = {f: getattr(args, o) for o, f in _SIM_FIELDS.items() if getattr(args, o, None) is not None}
        cond = dataclasses.replace(cond, sim={**cond.sim, **over}, grade=grade or cond.grade)
        cfg = cond.config(seed)
    else:
        cfg = SimConfig(
            duration=sim_value(args, "duration"),
            rate=sim_value(args, "rate"),
            seed=seed,
            taps=sim_value(args, "taps"),
            rest_breaks=sim_value(args, "breaks"),
        )
        if grade is not None:
            cfg = GRADES[grade].config(cfg)
    if getattr(args, "breaks", None) is None:
        cfg = _fit_breaks(cfg)
    deg = getattr(args, "declination", None)
    if deg is not None:
        if not (math.isfinite(deg) and -180.0 <= deg <= 180.0):
            raise CliError(f"--declination must be in [-180, 180] deg, got {deg:g}")
        cfg = dataclasses.replace(cfg, mag_declination=math.radians(deg))
    return cfg


def simulate(args: argparse.Namespace) -> Any:
    """Simulate with the command's options (a configuration that does not fit is a CliError)."""
    from attica.sim import simulate_with_truth

    try:
        rec, _ = simulate_with_truth(sim_config(args))
    except ValueError as exc:
        raise CliError(f"simulation: {exc} (use a longer --duration or fewer --breaks)") from None
    return rec


def describe_source(args: argparse.Namespace) -> str:
    """``<file>`` or ``simulation (seed S, D s at R Hz, ...)``."""
    if getattr(args, "data", None):
        return str(args.data)
    extra = [f"{o} {getattr(args, o)}" for o in ("condition", "grade") if getattr(args, o, None) is not None]
    if getattr(args, "declination", None) is not None:
        extra.append(f"declination {args.declination:g} deg")
    return (
        f"simulation (seed {sim_value(args, 'seed')}, {sim_value(args, 'duration'):g} s at "
        f"{sim_value(args, 'rate'):g} Hz, {sim_value(args, 'taps')} taps{''.join(', ' + e for e in extra)})"
    )


def check_data_or_sim(args: argparse.Namespace) -> None:
    """Refuse simulation options together with ``--data`` (a recording has its own rate and length)."""
    given = sim_options_given(args)
    if getattr(args, "data", None) and given:
        verb = "describes" if len(given) == 1 else "describe"
        raise CliError(
            f"{', '.join(given)} {verb} a simulation, but --data gives a recording (with its own sample "
            "rate and length); drop them or drop --data"
        )
    if not getattr(args, "data", None):
        for name in ("duration", "rate"):
            v = getattr(args, name, None)
            if v is not None and not v > 0:
                raise CliError(f"--{name} must be > 0, got {v:g}")


def load_data(args: argparse.Namespace) -> Any:
    """The recording of ``--data`` or the simulation of the options."""
    from attica.data import load_recording
    from attica.data.timing import TimingWarning

    if getattr(args, "data", None):
        path = Path(args.data)
        if not path.exists():
            raise CliError(f"no such recording: {path}")
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", TimingWarning)
            try:
                rec = load_recording(path)
            except (ValueError, ImportError) as exc:
                msg = str(exc)
                raise CliError(msg if str(path) in msg or path.name in msg else f"{path}: {msg}") from None
        for w in caught:  # the time report's problems (gaps, dropped rows, a guessed unit) as CLI warnings
            if issubclass(w.category, TimingWarning):
                warn(str(w.message))
            else:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        hz = getattr(args, "resample", None)
        if hz is not None:
            from attica.data.resample import resample

            try:
                rec = resample(rec, hz)
            except ValueError as exc:
                raise CliError(f"--resample: {exc}") from None
        return rec
    return simulate(args)


def add_resample_argument(p: argparse.ArgumentParser) -> None:
    """``--resample HZ``: a log without a usable clock onto a uniform grid (attica.data.resample)."""
    p.add_argument(
        "--resample",
        type=float,
        metavar="HZ",
        help="put a recording that is not clocked onto a uniform HZ grid (gyro/accel linear interpolation, "
        "mag placed once, truth nearest; docs/recordings.md); a clocked log with gaps is better stepped",
    )


def check_units(rec: Any, args: argparse.Namespace, what: str = "") -> None:
    """Print a warning when the recording's units look wrong (unless ``--no-unit-check``)."""
    if getattr(args, "no_unit_check", False):
        return
    problems = unit_problems(rec.gyr, rec.acc, rec.mag)
    if problems:
        warn(f"{what or rec.name}: {'; '.join(problems)} (--no-unit-check silences this)")


def add_unit_check_argument(p: argparse.ArgumentParser) -> None:
    """``--no-unit-check``."""
    p.add_argument(
        "--no-unit-check",
        action="store_true",
        help="do not warn when the inputs look like deg/s, g, gauss or nT instead of rad/s, m/s^2, uT",
    )


# --- output paths ---------------------------------------------------------------------------------


def check_output_file(path: Path, what: str = "output") -> Path:
    """Refuse an output file that cannot be written (checked before the work); returns the path."""
    if path.is_dir():
        raise CliError(f"{what} {path} is a directory")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise CliError(f"cannot write {what} {path}: directory {parent} does not exist")
    if not os.access(parent, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise CliError(f"cannot write {what} {path}: permission denied")
    return path


def prepare_output_dir(path: Path, what: str = "output directory") -> Path:
    """Create an output directory (parents too) or refuse it, before the work; returns the path."""
    if path.exists() and not path.is_dir():
        raise CliError(f"{what} {path} exists and is not a directory")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CliError(f"cannot create {what} {path}: {exc.strerror or exc}") from None
    if not os.access(path, os.W_OK):
        raise CliError(f"cannot write into {what} {path}: permission denied")
    return path


# --- filters and settings -------------------------------------------------------------------------


def parse_kinds(text: str, allowed: Sequence[FilterKind] | None = None) -> list[FilterKind]:
    """``all`` or comma-separated kind names; an empty or unknown selection is a CliError."""
    from attica.settings import implemented_kinds

    choices = list(allowed) if allowed is not None else implemented_kinds()
    if text.strip() == "all":
        return choices
    names = [t.strip() for t in text.split(",") if t.strip()]
    if not names:
        raise CliError(
            f"empty filter selection {text!r}; choose all or some of: {', '.join(k.label for k in choices)}"
        )
    out = []
    for name in names:
        try:
            k = FilterKind.parse(name)
        except ValueError as exc:
            raise CliError(str(exc)) from None
        if k not in choices:
            raise CliError(
                f"{k.label} is not available here; choose from: {', '.join(c.label for c in choices)}"
            )
        if k not in out:
            out.append(k)
    return out


def _parse_value(text: str, current: Any) -> Any:
    if isinstance(current, bool):
        if text.lower() in ("1", "true", "yes", "on"):
            return True
        if text.lower() in ("0", "false", "no", "off"):
            return False
        raise ValueError(f"expected true/false, got {text!r}")
    if isinstance(current, enum.Enum):
        cls = type(current)
        try:
            return cls[text.upper()]
        except KeyError:
            try:
                return cls(int(text))
            except ValueError:
                names = ", ".join(m.name.lower() for m in cls)
                raise ValueError(f"expected one of {names}, got {text!r}") from None
    if isinstance(current, int):
        return int(text)
    if isinstance(current, tuple):
        parts = [float(p) for p in text.split(",")]
        if len(parts) != len(current):
            raise ValueError(f"expected {len(current)} comma-separated numbers, got {text!r}")
        return tuple(parts)
    return float(text)


def _fields(kind: FilterKind) -> dict[str, Any]:
    defaults = make_settings(kind)
    return {f.name: getattr(defaults, f.name) for f in dataclasses.fields(defaults)}


def parse_overrides(kind: FilterKind, items: Sequence[str]) -> dict[str, Any]:
    """``name=value`` strings to typed settings overrides for ``kind`` (every name must exist)."""
    return plan_overrides([kind], items)[kind]


GYRO_RANGE_MAX = 70.0
"""rad/s (about 4,000 deg/s, the widest MEMS gyros): a larger ``--set gyro_range`` is warned about as
probably given in deg/s."""


def plan_overrides(kinds: Sequence[FilterKind], items: Sequence[str]) -> dict[FilterKind, dict[str, Any]]:
    """``--set name=value`` for several kinds: each setting goes to the kinds that have it.

    A setting that no selected kind has is a CliError; one that only some have is applied there, and a
    note on stderr says where (before anything runs). ``dt`` is refused: it is the data's sample period.
    """
    fields = {k: _fields(k) for k in kinds}
    out: dict[FilterKind, dict[str, Any]] = {k: {} for k in kinds}
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep:
            raise CliError(f"--set expects name=value, got {item!r}")
        if name == "dt":
            raise CliError("dt is the recording's sample period (1 / rate); use --rate for simulations")
        having = [k for k in kinds if name in fields[k]]
        if not having:
            known = sorted(set().union(*(fields[k] for k in kinds)))
            which = kinds[0].label if len(kinds) == 1 else "none of " + ", ".join(k.label for k in kinds)
            raise CliError(f"{which} has no setting {name!r}; settings: {', '.join(known)}")
        for k in having:
            try:
                out[k][name] = _parse_value(value, fields[k][name])
            except ValueError as exc:
                raise CliError(f"--set {name}: {exc}") from None
        w = out[having[0]][name]
        if name == "gyro_range" and isinstance(w, float) and GYRO_RANGE_MAX < w <= 1e3:  # (above: refused)
            warn(
                f"gyro_range {w:g} rad/s is {math.degrees(w):,.0f} deg/s, beyond any MEMS gyro: attica takes "
                f"rad/s ({w:g} deg/s would be {math.radians(w):.4g} rad/s); a range above the sensor's "
                "full scale turns the recovery after a clipping gyro off"
            )
        missing = [k.label for k in kinds if k not in having]
        if missing:
            note(
                f"--set {item} applies to {', '.join(k.label for k in having)} only "
                f"({', '.join(missing)} {'has' if len(missing) == 1 else 'have'} no setting {name!r})"
            )
    return out


def note_node_defaults(args: argparse.Namespace) -> None:
    """A note where a simulation's clipping gyro or declination does not reach a node's settings.

    ``attica view --demo`` and the CAN stream commands send the simulation to a node on its init settings:
    a clipping condition's range and a declined field are the user's to give it (``--set``).
    """
    if getattr(args, "data", None):
        return
    cfg = sim_config(args)
    given = {item.partition("=")[0].strip() for item in getattr(args, "set", None) or []}
    if cfg.gyro_clip > 0.0 and "gyro_range" not in given:
        note(
            f"the simulated gyro clips at {cfg.gyro_clip:.6g} rad/s, but the node keeps its own gyro_range "
            "(default 2000 deg/s), so it does not see the clipping (give the node --set gyro_range=...)"
        )
    if cfg.mag_declination != 0.0 and "declination" not in given:
        note(
            f"the simulated field is declined by {math.degrees(cfg.mag_declination):g} deg; the node's "
            "heading is magnetic unless its declination setting (rad) says so"
        )


def fit_to_simulation(args: argparse.Namespace, overrides: dict[FilterKind, dict[str, Any]]) -> None:
    """What a simulation means for the filters of ``attica run`` / ``demo`` (nothing for a recording).

    - A gyro that clips (``--condition near-clip / clipped``): as the suite does (and as a user
      configures the sensor), ``gyro_range`` becomes the sensor's full scale for every kind in
      ``overrides`` that has the setting and was not given one with ``--set``, with a note.
    - ``--declination`` without ``--set declination``: a note that those kinds' heading stays magnetic.
    - A condition the suite scores from later than its start (mag-start: 15 s): a note.
    """
    if getattr(args, "data", None):
        return
    cfg = sim_config(args)
    clip = float(cfg.gyro_clip)
    having = {
        name: [k for k in overrides if name in _fields(k) and name not in overrides[k]]
        for name in ("gyro_range", "declination")
    }
    if clip > 0.0 and having["gyro_range"]:
        for k in having["gyro_range"]:
            overrides[k]["gyro_range"] = clip
        note(
            f"the simulated gyro clips at {clip:.6g} rad/s ({math.degrees(clip):g} deg/s): "
            f"gyro_range={clip:.6g} for {', '.join(k.label for k in having['gyro_range'])}, as the suite "
            "gives it (--set gyro_range=... to choose)"
        )
    deg = getattr(args, "declination", None)
    missing = having["declination"]
    if deg and missing:
        note(
            f"the simulated field is declined by {deg:g} deg, and {', '.join(k.label for k in missing)} "
            f"{'keeps' if len(missing) == 1 else 'keep'} a magnetic heading (0 declination): "
            f"--set declination={math.radians(deg):.6g} (rad) for true north"
        )
    cond = _condition(args)
    from attica.sim.conditions import CONVERGENCE

    if cond is not None and cond.score_from > CONVERGENCE:
        note(
            f"the suite scores {cond.name} from {cond.score_from:g} s (no method can know the attitude "
            "before); the figures here are over every moving sample"
        )


def filter_settings(kind: FilterKind, rate: float, overrides: dict[str, Any], base: Any = None) -> Any:
    """Settings of ``kind`` at ``rate`` with the overrides, checked (a C refusal: CliError naming it)."""
    try:
        s = make_settings(kind, base, dt=1.0 / rate, **implied_gains(kind, base, overrides))
    except (TypeError, ValueError) as exc:
        raise CliError(str(exc)) from None
    from attica import native

    problem = native.settings_problem(kind, s, f"{kind.label} settings")  # the C library's own checks
    if problem is not None:
        raise CliError(str(problem))
    try:
        native.Filter(kind, settings=s)  # anything else the C library refuses, before any work
    except native.NativeError as exc:
        raise CliError(f"{kind.label}: {exc}") from None
    return s


# --- calibration ----------------------------------------------------------------------------------


def add_calibration_argument(p: argparse.ArgumentParser, what: str = "the filters") -> None:
    """``--calibration FILE``: a calibration file (JSON, ``attica calibrate``) applied to ``what``."""
    p.add_argument(
        "--calibration",
        metavar="FILE",
        help=f"calibration file (JSON from attica calibrate) applied to {what}: sensor models, mounting, "
        "output convention",
    )


def load_calibration(args: argparse.Namespace) -> Any:
    """The :class:`~attica.calibration.Calibration` of ``--calibration`` (None without it).

    A missing, unreadable or invalid file is a CliError (call it before any work).
    """
    from attica.calibration import Calibration

    name = getattr(args, "calibration", None)
    if not name:
        return None
    path = Path(name)
    if not path.exists():
        raise CliError(f"--calibration {path}: no such calibration file")
    if path.is_dir():
        raise CliError(f"--calibration {path}: is a directory")
    try:
        cal = Calibration.load(path)
    except (ValueError, OSError, UnicodeDecodeError) as exc:
        raise CliError(f"--calibration: {exc}") from None
    from attica import native

    try:  # the firmware's own checks (att_calib_settings_check), before any work
        native.Filter("ars", dt=0.01, calibration=cal)
    except native.NativeError as exc:
        raise CliError(f"--calibration {path}: refused by the firmware: {exc}") from None
    return cal


def warn_calibrated_truth(cal: Any) -> None:
    """Warn that errors against ground truth (sensor frame, ENU) mean little with a mounting or NED/NWU."""
    if cal is not None and (not cal.mounting.identity or cal.convention != "enu"):
        warn(
            "the ground truth is the sensor's attitude in ENU; with this calibration's mounting or "
            "convention the outputs are another frame's, so the errors against it are not accuracy figures"
        )


def describe_calibration(cal: Any, path: str) -> str:
    """``calibration FILE applied: gyro, mag, mounting +x-z+y, convention ned`` (or nothing changed)."""
    parts = [name for name in ("gyro", "accel", "mag") if not getattr(cal, name).identity]
    if not cal.mounting.identity:
        m = cal.mounting
        parts.append(f"mounting {m.remap}" if m.remap is not None else "mounting quaternion")
    if cal.convention != "enu":
        parts.append(f"convention {cal.convention}")
    what = ", ".join(parts) if parts else "identity (changes nothing)"
    return f"calibration {path} applied: {what}"

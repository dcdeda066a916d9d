"""The attica command: sim, run, demo and their error messages."""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from attica import kinds
from attica.cli import build_parser, main
from attica.data import load_recording

from helpers import ROOT, need


def test_demo_reports_bit_exact(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["demo", "--duration", "10", "-q"]) == 0
    out = capsys.readouterr().out
    assert "steps compared, 0 differ: bit-exact" in out
    assert "RMSE inclination" in out


def test_sim_then_run_every_filter(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "sim.npz"
    assert main(["sim", "--duration", "12", "--seed", "3", "-o", str(path)]) == 0
    rec = load_recording(path)
    assert rec.quat_true is not None and len(rec.gyr) == round(12 * 285.714)
    out_path = tmp_path / "out.npz"
    assert main(["run", "--filter", "all", "--data", str(path), "-q", "--check", "-o", str(out_path)]) == 0
    out = capsys.readouterr().out
    for k in kinds.KINDS:
        line = next(x for x in out.splitlines() if x.strip().startswith(f"{k.label}:"))
        if k.uses_mag():  # 9-axis: judged by total and heading too
            assert "RMSE total" in line and "heading" in line, line
        else:
            assert "RMSE inclination" in line and f"({k.axes()}-axis: heading not observable)" in line, line
        assert np.load(tmp_path / f"out_{k.label}.npz")["q"].shape == (len(rec.gyr), 4)
    assert out.count("0 differ: bit-exact") == len(kinds.KINDS)


def test_run_judges_by_the_magnetometer_in_use(capsys: pytest.CaptureFixture[str]) -> None:
    """The MEKF uses the mag (total and heading errors) unless use_mag is off (6-axis, inclination only);
    it was once labelled 6-axis whatever its settings."""
    assert main(["run", "--filter", "mekf", "--duration", "6", "-q"]) == 0
    out = capsys.readouterr().out
    assert "mekf: RMSE total" in out and "not observable" not in out
    assert main(["run", "--filter", "mekf", "--duration", "6", "-q", "--set", "use_mag=0"]) == 0
    out = capsys.readouterr().out
    assert "mekf: RMSE inclination" in out and "(6-axis: heading not observable)" in out


def test_run_with_settings(capsys: pytest.CaptureFixture[str]) -> None:
    args = ["run", "--filter", "ars", "--duration", "12", "-q", "--set", "tau=0.5", "--set", "gain=0"]
    args += ["--set", "bias_mode=frozen"]
    assert main(args) == 0
    assert "ars:" in capsys.readouterr().out


@pytest.mark.parametrize(
    "args,message",
    [
        (["run", "--filter", "ars", "--set", "gian=0.2"], "has no setting 'gian'"),
        (["run", "--filter", "ars", "--set", "tau"], "expects name=value"),
        (["run", "--filter", "ars", "--set", "tau=fast"], "--set tau"),
        (["run", "--filter", "ars", "--set", "bias_init=1,2"], "3 comma-separated numbers"),
        (["run", "--data", "/nonexistent/x.npz"], "no such recording"),
        (["run", "--filter", "ars", "--set", "dt=-1"], "dt is the recording's sample period"),
        (["run", "--filter", "ars", "--set", "tau=0", "--set", "gain=5"], "out of range"),
        (
            ["run", "--filter", "ars", "--set", "tau_acc_lp=-1"],
            "ars.tau_acc_lp = -1.0 is out of range: allowed",
        ),
        (
            ["sim", "--duration", "6", "--breaks", "2", "-o", "/tmp/never.npz"],
            "use a longer --duration or fewer",
        ),
    ],
)
def test_errors_are_clear(args: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([*args, "-q"] if args[0] == "run" else args) == 2
    assert message in capsys.readouterr().err


# --- every rough edge of the command line ---------------------------------------------------------


def _walk(parser: argparse.ArgumentParser, path: str = "attica") -> list[tuple[str, argparse.Action]]:
    out = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                assert choice.help, f"{path} {choice.dest}: no one-line description"
            for name, sub in action.choices.items():
                assert sub.description, f"{path} {name}: no description"
                out += _walk(sub, f"{path} {name}")
        else:
            out.append((path, action))
    return out


def test_every_subcommand_and_option_has_help() -> None:
    from attica.commands import COMMANDS

    parser = build_parser()
    actions = _walk(parser)
    assert {p.split()[1] for p, _ in actions if " " in p} == set(COMMANDS)
    for path, action in actions:
        assert action.help and action.help != argparse.SUPPRESS, f"{path} {action.option_strings}: no help"


def test_version_and_paths(capsys: pytest.CaptureFixture[str]) -> None:
    import attica

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.startswith(f"attica {attica.__version__} (")
    assert main(["paths"]) == 0
    out = capsys.readouterr().out
    for key in ("firmware", "include", "src", "cflags file", "dbc", "version header", "cflags", "extension"):
        assert re.search(rf"^{key}\s", out, re.M), key
    assert main(["paths", "--dbc"]) == 0
    assert Path(capsys.readouterr().out.strip()).name == "attica.dbc"
    assert main(["paths", "--sources"]) == 0
    assert all(Path(s).suffix == ".c" and Path(s).is_file() for s in capsys.readouterr().out.split())
    assert main(["paths", "--cflags"]) == 0
    assert "-ffp-contract=off" in capsys.readouterr().out.split()


def _paths_cflags(capsys: pytest.CaptureFixture[str]) -> list[str]:
    assert main(["paths", "--cflags"]) == 0
    return capsys.readouterr().out.split()


def test_paths_cflags_are_those_of_attica_mk(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``attica paths --cflags`` prints exactly what firmware/attica.mk compiles attica's sources with,
    ``$(ATTICA_CFLAGS) $(ATTICA_WARNINGS)``, in that order: -fno-lto included (it once printed only
    cflags.txt, without -fno-lto), and the section flags."""
    need(shutil.which("make") is not None, "make is not installed")
    flags = _paths_cflags(capsys)
    mk = tmp_path / "print.mk"
    mk.write_text(
        f"include {ROOT / 'firmware' / 'attica.mk'}\n"
        "print:\n\t$(info $(ATTICA_CFLAGS) $(ATTICA_WARNINGS))@:\n"
    )
    proc = subprocess.run(
        ["make", "--no-print-directory", "-s", "-f", str(mk), "print"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        check=True,
    )
    assert flags == proc.stdout.split(), (flags, proc.stdout)
    assert "-fno-lto" in flags and "-Werror" in flags
    assert main(["paths", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["cflags"].split() == flags


def test_documented_paths_compile_lines_name_every_source(tmp_path: Path) -> None:
    """The ``cc $(attica paths --cflags) ...`` lines of the docs and docstrings, run by bash with a ``cc``
    that records its arguments: the flags are --cflags's and the files are every firmware source (a
    glob of ``$(attica paths --src)``/att_*.c once matched nothing: the sources are in sub-folders)."""
    from attica import resources

    need(shutil.which("bash") is not None, "bash is not installed")
    bin_dir = Path(sys.executable).parent
    need((bin_dir / "attica").exists(), f"no attica command beside {sys.executable}")
    places = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    places += [ROOT / "host" / "attica" / "resources.py", ROOT / "host" / "attica" / "commands" / "paths.py"]
    lines = [
        (path.name, ln.strip())
        for path in places
        for ln in path.read_text().splitlines()
        if ln.strip().startswith("cc $(attica paths --cflags)")
    ]
    assert {name for name, _ in lines} >= {"integration.md", "python.md", "resources.py", "paths.py"}, lines
    record = tmp_path / "args"
    for name, line in lines:
        script = f'cc() {{ printf "%s\\n" "$@" > {record}; }}\n{line}\n'
        env = {**os.environ, "PATH": f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}"}
        subprocess.run(["bash", "-e", "-c", script], cwd=tmp_path, env=env, check=True)
        args = record.read_text().splitlines()
        files = [a for a in args if not a.startswith("-")]
        assert sorted(files) == sorted(str(s) for s in resources.sources()), (name, line)
        assert args[: len(resources.compile_flags())] == resources.compile_flags(), (name, line)


def test_paths_cflags_are_on_cmakes_compile_lines(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """CMake (firmware/CMakeLists.txt) compiles every attica source with the same flags, in one run."""
    need(shutil.which("cmake") is not None and shutil.which("cc") is not None, "cmake or cc is not installed")
    flags = _paths_cflags(capsys)
    subprocess.run(
        [
            "cmake",
            "-S",
            str(ROOT / "firmware"),
            "-B",
            str(tmp_path),
            "-DCMAKE_C_COMPILER=cc",
            "-DCMAKE_EXPORT_COMPILE_COMMANDS=ON",
        ],
        check=True,
        capture_output=True,
    )
    commands = json.loads((tmp_path / "compile_commands.json").read_text())
    sources = {Path(c["file"]).name for c in commands}
    assert {p.name for p in (ROOT / "firmware" / "src").rglob("*.c")} <= sources
    for c in commands:
        words = c["command"].split()
        starts = [i for i, w in enumerate(words) if w == flags[0]]
        assert any(words[i : i + len(flags)] == flags for i in starts), (c["file"], c["command"])


def test_run_and_demo_agree(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["demo", "--duration", "15", "-q"]) == 0
    demo = capsys.readouterr().out
    assert main(["run", "--duration", "15", "-q"]) == 0
    run = capsys.readouterr().out
    line = [ln for ln in demo.splitlines() if "RMSE" in ln]
    assert line and line[0] in run.splitlines()
    assert "3 taps" in demo and "3 taps" in run


@pytest.mark.parametrize(
    "args,message",
    [
        (
            ["run", "--data", "{rec}", "--rate", "100"],
            "--rate describes a simulation, but --data gives a recording",
        ),
        (
            ["run", "--data", "{rec}", "--duration", "5", "--seed", "2"],
            "--duration, --seed describe a simulation",
        ),
        (["run", "-o", "/nonexistent/dir/out.npz"], "directory /nonexistent/dir does not exist"),
        (["run", "-o", "{tmp}"], "is a directory"),
        (
            ["run", "--filter", "all", "--set", "nosuch=1"],
            f"none of {', '.join(kinds.labels())} has no setting",
        ),
        (["run", "--filter", "ars,"], None),
        (["run", "--filter", ",", "-q"], "empty filter selection"),
        (["run", "--filter", "madgwick"], "unknown filter 'madgwick'"),
        (["sim", "-o", "{tmp}/x.txt"], "must be .npz or .csv"),
        (["eval", "--data", "{tmp}", "--peers", "nosuch"], "unknown peer(s) nosuch"),
        (["eval", "--data", "{tmp}", "--filter", ","], "empty filter selection"),
        (["eval", "--data", "{tmp}", "--limit", "0"], "--limit must be >= 1"),
        (["eval", "--data", "{rec}", "--out", "{rec}"], "exists and is not a directory"),
        (["eval", "--data", "{tmp}/nothing"], "no such file or directory"),
        (["replay", "--count", "0"], "--count must be > 0"),
        (["replay", "-w", "/nonexistent/bus.log"], "directory /nonexistent does not exist"),
        (["replay", "-w", "{tmp}/bus.xyz"], "unknown log format"),
        (["verify", "--data", "{rec}", "--rate", "100"], "--rate describes a simulation"),
        (["monitor", "--log", "{tmp}/missing.log"], "no such log file"),
        (["sim", "-o", "{tmp}"], "is a directory"),
        (["sim", "-o", "/nonexistent/dir/x.npz"], "directory /nonexistent/dir does not exist"),
        (["monitor", "--log", "{tmp}/a.log", "-w", "{tmp}/a.log"], "is the --log being read"),
        (["monitor", "--log", "{tmp}/a.log", "--duration", "5"], "with --log the whole log is read"),
        (["monitor", "--duration", "0"], "--duration must be > 0"),
        (["monitor", "--max-lines", "-1"], "--max-lines must be >= 0"),
        (["monitor", "-w", "{tmp}/dir.log"], "is a directory"),
        (["verify", "--with-node", "-w", "/nonexistent/bus.log"], "directory /nonexistent does not exist"),
        (["verify", "--log", "{tmp}/a.log", "-w", "{tmp}/b.log"], "nothing new to write"),
    ],
)
def test_user_errors_before_any_work(
    args: list[str], message: str | None, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rec = tmp_path / "rec.npz"
    (tmp_path / "a.log").write_text("(1.000000) can0 100#0011223344556677\n")
    (tmp_path / "dir.log").mkdir()
    if any("{rec}" in a for a in args):
        assert main(["sim", "--duration", "10", "-o", str(rec)]) == 0
        capsys.readouterr()
    argv = [a.replace("{rec}", str(rec)).replace("{tmp}", str(tmp_path)) for a in args]
    code = main(argv)
    cap = capsys.readouterr()
    if message is None:  # a trailing comma is fine
        assert code == 0
        return
    assert code == 2, cap
    assert cap.err.startswith("attica: error: ") and message in cap.err, cap.err
    assert "samples" not in cap.out and "Traceback" not in cap.err  # refused before the work


def test_argparse_errors_have_the_same_form(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["run", "--duration", "soon"])
    assert exc.value.code == 2
    assert "attica: error: run: argument --duration: invalid float value: 'soon'" in capsys.readouterr().err


def test_set_with_several_filters_applies_where_it_exists(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = [
        "run",
        "--filter",
        "ars,mars,kf",
        "--duration",
        "12",
        "-q",
        "--set",
        "tau=0.5",
        "--set",
        "q_noise=0.002",
    ]
    assert main(args) == 0
    cap = capsys.readouterr()
    assert "--set tau=0.5 applies to ars only (mars, kf have no setting 'tau')" in cap.err
    assert "--set q_noise=0.002 applies to kf only (ars, mars have no setting 'q_noise')" in cap.err
    assert cap.err.index("applies") < len(cap.err) and "ars:" in cap.out and "kf:" in cap.out
    # applied: the same error lines as a run of that filter alone with the setting
    assert main(["run", "--filter", "kf", "--duration", "12", "-q", "--set", "q_noise=0.002"]) == 0
    kf_line = [ln for ln in capsys.readouterr().out.splitlines() if "kf:" in ln][0]
    assert kf_line in cap.out.splitlines()


def test_run_unit_warning_and_silencing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from attica.sim import SimConfig, simulate

    rec = simulate(SimConfig(duration=12.0, rate=200.0, seed=1))
    rec.gyr = np.degrees(rec.gyr).astype(np.float32)
    path = tmp_path / "degrees.npz"
    rec.save(path)
    assert main(["run", "--data", str(path), "-q"]) == 0
    assert "attica: warning:" in capsys.readouterr().err
    assert main(["run", "--data", str(path), "-q", "--no-unit-check"]) == 0
    assert "warning" not in capsys.readouterr().err


def test_eval_tables_fit_and_plots_are_wide(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from attica.evaluate import Method, run_methods
    from attica.evaluate.plots import plot_groups, plot_trial
    from attica.evaluate.tables import format_tables
    from attica.sim import SimConfig, simulate

    recs = []
    for seed, name in ((1, "01_undisturbed_slow_rotation_A"), (2, "24_disturbed_tapping_A")):
        r = simulate(SimConfig(duration=12.0, rate=100.0, seed=seed))
        r.name, r.groups = name, ("all_trials", name.split("_")[1])
        recs.append(r)

    def method(i: int, nine: bool) -> Method:
        def run(rec: object) -> np.ndarray:
            q = np.array(rec.quat_true, np.float64)  # type: ignore[attr-defined]
            return q  # the truth (errors 0)

        return Method(f"{'nine' if nine else 'six'}_method_{i:02d}", "test", nine, "default", run)

    methods = [method(i, False) for i in range(14)] + [method(i, True) for i in range(9)]
    report = run_methods(methods, recs, progress=False, curves=True)
    text = format_tables(report)
    assert max(len(ln) for ln in text.splitlines()) <= 110
    assert "6-axis: inclination RMSE (deg)" in text and "9-axis: total RMSE (deg)" in text
    assert "part 2 of" in text  # 14 six-axis columns do not fit in one table
    wide = format_tables(report, wide=True)
    assert max(len(ln) for ln in wide.splitlines()) > 110 and "part 2" not in wide
    need(
        importlib.util.find_spec("matplotlib") is not None,
        "matplotlib is not installed (pip install '.[eval]')",
    )
    for path, draw in (
        (tmp_path / "trial.png", lambda p: plot_trial(report, recs[0], p)),
        (tmp_path / "groups.png", lambda p: plot_groups(report, p)),
    ):
        draw(path)
        head = path.read_bytes()[:24]
        assert head[:8] == b"\x89PNG\r\n\x1a\n"
        assert int.from_bytes(head[16:20], "big") == 1600  # IHDR width


def test_set_with_filter_all_says_where_before_running(capsys: pytest.CaptureFixture[str]) -> None:
    args = ["run", "--filter", "all", "--duration", "6", "-q", "--set", "tau=0.5", "--set", "r_noise=0.02"]
    assert main(args) == 0
    cap = capsys.readouterr()
    others = ", ".join(label for label in kinds.labels() if label != "ars")  # tau: the ARS's alone
    assert f"attica: note: --set tau=0.5 applies to ars only ({others} have no setting" in cap.err
    assert "attica: note: --set r_noise=0.02 applies to " in cap.err
    # before running: the notes come first, and a refused setting stops everything before any output
    assert main(["run", "--filter", "all", "--duration", "6", "-q", "--set", "tau=-1"]) == 2
    cap = capsys.readouterr()
    assert (
        cap.err.startswith("attica: note: --set tau=-1 applies to ars only") and "attica: error: " in cap.err
    )
    assert cap.out == ""


def test_run_prints_the_hard_iron_estimate(capsys: pytest.CaptureFixture[str]) -> None:
    """With hard_iron_tau > 0 `attica run` prints the offset a mars or mekf ends with (its -o files hold
    every step's: tests/test_run_output.py); not for a kind without the estimate or with it off."""
    assert main(["run", "--filter", "mars,ars", "--set", "hard_iron_tau=60", "--duration", "20", "-q"]) == 0
    out = capsys.readouterr().out
    assert out.count("hard-iron offset at the end:") == 1 and " uT (" in out
    assert main(["run", "--filter", "mars", "--duration", "20", "-q"]) == 0
    assert "hard-iron offset" not in capsys.readouterr().out
    # a mekf without its magnetometer has no estimate (as the node: no ATT_MAG_OFFSET)
    assert main(["run", "--filter", "mekf", "--set", "use_mag=false", "--set", "hard_iron_tau=60", "-q"]) == 0
    assert "hard-iron offset" not in capsys.readouterr().out


def test_a_gyro_range_in_deg_per_s_is_warned_about(capsys: pytest.CaptureFixture[str]) -> None:
    """`--set gyro_range=500` (meant as deg/s) is within the accepted (0, 1e3] rad/s but beyond any MEMS
    gyro, and it turns the clip recovery off: a warning says so (a review); 34.9 rad/s is not warned."""
    assert main(["run", "--filter", "mars", "--set", "gyro_range=500", "--duration", "2", "-q"]) == 0
    err = capsys.readouterr().err
    assert "attica: warning: gyro_range 500 rad/s is 28,648 deg/s" in err and "8.727 rad/s" in err
    assert main(["run", "--filter", "mars", "--set", "gyro_range=34.9", "--duration", "2", "-q"]) == 0
    assert "warning" not in capsys.readouterr().err
    assert main(["run", "--filter", "mars", "--set", "gyro_range=5000", "--duration", "2", "-q"]) == 2
    err = capsys.readouterr().err
    assert "out of range" in err and "warning" not in err  # refused, not warned about

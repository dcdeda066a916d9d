"""Real SocketCAN: ``attica-node`` (the C port, firmware/ports/linux) on vcan0 inside user-mode Linux.

The guest kernel (``linux.uml``, Debian's user-mode-linux package) boots with the host's file system as
its root (hostfs), loads can, can-raw, can-dev and vcan from /usr/lib/uml/modules, creates vcan0 (MTU
72: CAN FD) and runs a job script (tests/uml/boot.sh is its init). The job, inside the guest:

1. classic CAN: ``candump -L vcan0`` logs the bus, ``attica-node --filter ars`` serves it, and
   ``attica verify --interface socketcan --channel vcan0`` replays a simulated stream and checks every
   output set bit for bit against the numpy reference;
2. the same over CAN FD (``--fd``, the 9-axis filter).

Outside, after the guest powered off: the candump logs verify offline (inputs rebuilt from the log),
and ``cantools decode`` of each log agrees with ``attica monitor``'s decoding of it.

Under CI=true this must run: a missing linux.uml fails instead of skipping.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from helpers import IN_CI, ROOT, need

UML = shutil.which("linux.uml") or ("/usr/bin/linux.uml" if os.path.exists("/usr/bin/linux.uml") else None)
BOOT = ROOT / "tests" / "uml" / "boot.sh"
NODE = ROOT / "build" / "attica-node"
ENV = {**os.environ, "PYTHONPATH": str(ROOT / "host") + os.pathsep + os.environ.get("PYTHONPATH", "")}
SAMPLES = {"classic": 1200, "fd": 1200}
RATE = 285.714


def _modules_present() -> str:
    base = Path("/usr/lib/uml/modules")
    vers = sorted(p.name for p in base.iterdir()) if base.is_dir() else []
    if not vers:
        return "no /usr/lib/uml/modules/<version> (package user-mode-linux)"
    need_ko = [
        "net/can/can.ko",
        "net/can/can-raw.ko",
        "drivers/net/can/dev/can-dev.ko",
        "drivers/net/can/vcan.ko",
    ]
    missing = [k for k in need_ko if not (base / vers[-1] / "kernel" / k).exists()]
    return f"missing UML modules: {missing}" if missing else ""


@pytest.fixture(scope="module")
def node_binary() -> Path:
    """build/attica-node, rebuilt by ``make node`` when a source changed."""
    r = subprocess.run(["make", "-s", "node"], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    assert NODE.exists()
    return NODE


def test_attica_node_errors_are_clear(node_binary: Path) -> None:
    """Usage, settings and socket errors of the C port (these need no CAN at all)."""

    def run(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([str(node_binary), *args], capture_output=True, text=True, timeout=10)

    r = run("--channel", "vcan0", "--filter", "nosuch")
    assert r.returncode == 2 and "unknown filter 'nosuch'" in r.stderr
    r = run("--channel", "vcan0", "--rate", "5000")
    assert r.returncode == 2 and "more than 100 %" in r.stderr and "bit/s bus" in r.stderr
    r = run("--channel", "vcan0", "--rate", "abc")
    assert r.returncode == 2 and "--rate" in r.stderr
    r = run("--filter", "ars")
    assert r.returncode == 2 and "--channel is required" in r.stderr
    r = run("--channel", "nosuchcan9")
    assert r.returncode == 1
    assert "no CAN interface 'nosuchcan9'" in r.stderr or "no SocketCAN" in r.stderr
    r = run("--help")
    assert r.returncode == 0 and "--output-divider" in r.stdout


def _job(tmp: Path, py: str) -> Path:
    """The shell script run inside the guest."""
    lines = [
        "set -u",
        f"cd {ROOT}",
        f"export PYTHONPATH={ROOT / 'host'} HOME={os.environ.get('HOME', '/root')} PYTHONDONTWRITEBYTECODE=1",
        f"PY={py}",
        f"NODE={NODE}",
        f"OUT={tmp}",
        "rc=0",
        "run_case() {  # name, node args, verify args",
        "  name=$1; nargs=$2; vargs=$3",
        "  candump -r 16777216 -L vcan0 > $OUT/$name.log 2> $OUT/$name.candump.err &",
        "  cd_pid=$!",
        "  $NODE --channel vcan0 $nargs > $OUT/$name.node.out 2>&1 &",
        "  node_pid=$!",
        "  i=0; while ! grep -q ready $OUT/$name.node.out 2>/dev/null; do",
        "    i=$((i+1))",
        '    [ $i -gt 100 ] && { echo "$name: node not ready"; cat $OUT/$name.node.out; return 1; }',
        "    sleep 0.05; done",
        "  t0=$(date +%s.%N)",
        "  $PY -m attica.cli verify --interface socketcan --channel vcan0 -q $vargs \\",
        "    > $OUT/$name.verify.out 2>&1",
        "  vrc=$?",
        "  t1=$(date +%s.%N)",
        '  echo "$name: verify exit $vrc, wall $t0 $t1"',
        "  kill -INT $node_pid 2>/dev/null; wait $node_pid; nrc=$?  # (the FD node stops by itself: --count)",
        '  echo "$name: node exit $nrc"',
        "  sleep 0.2; kill -INT $cd_pid; wait $cd_pid",
        "  cat $OUT/$name.verify.out $OUT/$name.node.out",
        "  [ $vrc -eq 0 ] && [ $nrc -eq 0 ]",
        "}",
        f"run_case classic '--filter ars --rate {RATE}' \\",
        f"    '--filter ars --count {SAMPLES['classic']} --seed 4' || rc=1",
        f"run_case fd '--filter mars --rate {RATE} --fd --count {SAMPLES['fd']}' \\",
        f"    '--filter mars --fd --count {SAMPLES['fd']} --seed 5' || rc=1",
        "exit $rc",
    ]
    job = tmp / "job.sh"
    job.write_text("\n".join(lines) + "\n")
    return job


def _boot(job: Path, timeout: float = 150.0) -> tuple[int | None, str, str]:
    """Boot the guest on ``job``; (job exit status or None if the guest died, job log, console)."""
    assert UML is not None
    cmd = [
        UML,
        "mem=384M",
        "root=/dev/root",
        "rootfstype=hostfs",
        "rootflags=/",
        "rw",
        f"init={BOOT}",
        "con0=null,fd:1",
        "con=null",
        "quiet",
        f"attica_job={job}",
    ]
    r = subprocess.run(cmd, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=timeout)
    status_file = job.with_name(job.name + ".status")
    log_file = job.with_name(job.name + ".log")
    log = log_file.read_text() if log_file.exists() else ""
    status = int(status_file.read_text().strip()) if status_file.exists() else None
    return status, log, r.stdout + r.stderr


def _cantools_vs_monitor(log: Path) -> int:
    """Compare ``cantools decode`` with ``attica monitor --log`` line by line; return frames compared."""
    from attica.can.monitor import decoded_fields, same_value

    dbc = ROOT / "firmware" / "can" / "attica.dbc"
    with open(log) as fh:
        ref = subprocess.run(
            [sys.executable, "-m", "cantools", "decode", "--single-line", str(dbc)],
            stdin=fh,
            capture_output=True,
            text=True,
            check=True,
            env=ENV,
        ).stdout.splitlines()
    ours = subprocess.run(
        [sys.executable, "-m", "attica.cli", "monitor", "--log", str(log)],
        capture_output=True,
        text=True,
        check=True,
        env=ENV,
    )
    lines = ours.stdout.splitlines()
    assert len(lines) == len(ref) > 0
    for a, b in zip(lines, ref):
        head, name, values = decoded_fields(a)
        b_head, _, body = b.partition(" :: ")
        assert head == b_head
        m = re.match(r"^(\w+)\((.*)\)$", body)
        assert m is not None, b
        assert m.group(1) == name
        theirs = dict(item.split(": ", 1) for item in m.group(2).split(", "))
        assert theirs.keys() == values.keys()
        for k, v in values.items():
            assert same_value(v, theirs[k].split(" ")[0]), (k, a, b)
        assert "!" not in a.split("  ", 1)[1], a  # no CRC error, gap, DLC or unknown ID on a clean bus
    summary = ours.stderr
    assert "crc errors 0" in summary and "counter gaps 0" in summary
    return len(lines)


def test_vcan_in_uml_node_bit_exact(node_binary: Path, tmp_path: Path) -> None:
    why = "" if UML else "linux.uml not found (apt-get install user-mode-linux can-utils kmod)"
    why = why or _modules_present()
    if not why and shutil.which("candump") is None:
        why = "candump not found (apt-get install can-utils)"
    need(not why, why)
    # the extension must be current before the guest imports it (building inside the guest is slow)
    from attica import native  # noqa: F401

    t0 = time.perf_counter()
    status, log, console = _boot(_job(tmp_path, sys.executable))
    elapsed = time.perf_counter() - t0
    print(log)
    print(f"UML run: {elapsed:.1f} s")
    if status is None:
        pytest.fail(f"the UML guest died before the job finished:\n{console[-3000:]}\n{log}")
    assert status == 0, log
    for name, n in SAMPLES.items():
        out = (tmp_path / f"{name}.verify.out").read_text()
        assert re.search(r"verdict: BIT-EXACT$", out, re.M), out
        assert f"{n} bit-exact, 0 mismatched, 0 missing" in out, out
        m = re.search(r"(\d+) frames/s end to end", out)
        assert m is not None
        print(f"vcan in UML, {name}: {m.group(1)} frames/s end to end (verify and attica-node in the guest)")
        node = (tmp_path / f"{name}.node.out").read_text()
        assert "ready" in node and f"steps={n} " in node, node
        assert re.search(
            r"crc_errors=0 counter_gaps=0 dlc_errors=0 unknown_ids=0 duplicates=0 stale_partials=0", node
        )
        # offline: the candump log alone proves the same (inputs rebuilt from the log's IMU frames)
        logf = tmp_path / f"{name}.log"
        r = subprocess.run(
            [
                sys.executable,
                "-m",
                "attica.cli",
                "verify",
                "--log",
                str(logf),
                "--filter",
                "ars" if name == "classic" else "mars",
            ],
            capture_output=True,
            text=True,
            env=ENV,
        )
        assert r.returncode == 0 and re.search(r"verdict: BIT-EXACT$", r.stdout, re.M), r.stdout + r.stderr
        frames = _cantools_vs_monitor(logf)
        assert frames > n
    assert not IN_CI or status == 0

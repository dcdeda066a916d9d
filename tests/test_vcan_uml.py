"""Real SocketCAN: ``attica-node`` (the C port, firmware/ports/linux) on vcan0 inside user-mode Linux.

The guest kernel (``linux.uml``, Debian's user-mode-linux package) boots with the host's file system as
its root (hostfs), loads can, can-raw, can-dev and vcan from /usr/lib/uml/modules, creates vcan0 (MTU
72: CAN FD) and runs a job script (tests/uml/boot.sh is its init). The job, inside the guest:

1. classic CAN: ``candump -L vcan0`` logs the bus, ``attica-node --filter ars`` serves it, and
   ``attica verify --interface socketcan --channel vcan0`` replays a simulated stream and checks every
   output set bit for bit against the numpy reference;
2. the same over CAN FD (``--fd``, the 9-axis filter), and classic CAN against ``attica-node-small``
   (the small node of docs/firmware-quickstart.md: ARS only, no stages, classic frames, rings of 8)
   with its CAN IDs moved by an ID offset (``--id-offset``, host and node);
3. faults: while verify streams FAULT_SAMPLES valid samples, tests/uml/flood.py floods FLOOD_RATE
   malformed attica frames/s (unknown IDs, wrong lengths, bad CRCs, remote frames) and cangen adds
   CANGEN_FRAMES random extended-ID frames: the node counts every one of them in the right counter,
   loses no sample, and every output set is still bit-exact;
4. the interface is deleted under a running node: it stops with a message naming the interface;
5. a plug qdisc holds vcan2's tx queue (writes fail with ENOBUFS): the node waits instead of dying,
   and once the queue is released it has stepped every sample and sent every output.

Outside, after the guest powered off: the candump logs verify offline (inputs rebuilt from the log),
and ``cantools decode`` of each log agrees with ``attica monitor``'s decoding of it.

Under CI=true this must run: a missing linux.uml fails instead of skipping.

On hosts whose XSAVE area holds AMX state (11,008 bytes) Debian's UML 6.1 cannot restore a guest
process's registers (it passes 2,696 bytes, the host wants all of it) and the guest dies at boot; the
guest runs with tests/uml/xstate_pad.c preloaded, which pads that one ptrace request (see its comment).
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

from helpers import IN_CI, ROOT, cantools_decode, need

UML = shutil.which("linux.uml") or ("/usr/bin/linux.uml" if os.path.exists("/usr/bin/linux.uml") else None)
BOOT = ROOT / "tests" / "uml" / "boot.sh"
XSTATE_PAD_SRC = ROOT / "tests" / "uml" / "xstate_pad.c"
XSTATE_PAD = ROOT / "build" / "uml" / "xstate_pad.so"
NODE = ROOT / "build" / "attica-node"
NODE_SMALL = ROOT / "build" / "attica-node-small"
SMALL_OFFSET = "0x20"
ENV = {**os.environ, "PYTHONPATH": str(ROOT / "host") + os.pathsep + os.environ.get("PYTHONPATH", "")}
SAMPLES = {"classic": 1200, "fd": 1200, "small": 1200}
RATE = 285.714
MARK_ID = "1FFFFFF0"  # an extended ID no attica frame uses: the candump logs' start and end markers
FAULT_SAMPLES = 600
FLOOD_RATE = 500.0  # malformed attica frames/s from tests/uml/flood.py during the faults case
CANGEN_FRAMES = 1000  # random extended-ID frames from cangen, one every CANGEN_GAP_MS
CANGEN_GAP_MS = 5
NOBUFS_SAMPLES = 300


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
    """build/attica-node (and attica-node-small), rebuilt by ``make node`` when a source changed."""
    r = subprocess.run(["make", "-s", "node"], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    assert NODE.exists() and NODE_SMALL.exists()
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
        f"NODE_SMALL={NODE_SMALL}",
        f"OUT={tmp}",
        "rc=0",
        "wait_ready() {  # a node's output file",
        "  i=0; while ! grep -q ready $1 2>/dev/null; do",
        "    i=$((i+1)); [ $i -gt 100 ] && break; sleep 0.05; done",
        "}",
        # candump writes line by line (stdbuf) and is stopped only once it has logged an end marker:
        # under load it lags the bus, and a SIGINT 0.2 s after the node stopped cut the log's last 200
        # samples off (a CI run: 991 of 1200 samples logged, the last 8 output sets missing)
        "mark() {  # case name, marker byte: a frame nobody else sends, waited for in the candump log",
        f"  i=0; while ! grep -q '{MARK_ID}#'$2 $OUT/$1.log 2>/dev/null; do",
        f"    [ $((i % 10)) -eq 0 ] && cansend vcan0 {MARK_ID}#$2  # every 0.5 s: candump may not listen yet",
        "    i=$((i+1))",
        '    [ $i -gt 600 ] && { echo "$1: candump did not log marker $2 in 30 s"; return 1; }',
        "    sleep 0.05; done",
        "}",
        "run_case() {  # name, node args, verify args[, node binary]",
        "  name=$1; nargs=$2; vargs=$3; bin=${4:-$NODE}",
        "  stdbuf -oL candump -r 16777216 -L vcan0 > $OUT/$name.log 2> $OUT/$name.candump.err &",
        "  cd_pid=$!",
        "  mark $name 01 || { kill -INT $cd_pid; return 1; }",
        "  $bin --channel vcan0 $nargs > $OUT/$name.node.out 2>&1 &",
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
        "  mark $name 02; mrc=$?; kill -INT $cd_pid; wait $cd_pid",
        f"  grep -v ' {MARK_ID}#' $OUT/$name.log > $OUT/$name.log.tmp; mv $OUT/$name.log.tmp $OUT/$name.log",
        "  cat $OUT/$name.verify.out $OUT/$name.node.out",
        "  [ $vrc -eq 0 ] && [ $nrc -eq 0 ] && [ $mrc -eq 0 ]",
        "}",
        f"run_case classic '--filter ars --rate {RATE}' \\",
        f"    '--filter ars --count {SAMPLES['classic']} --seed 4' || rc=1",
        f"run_case fd '--filter mars --rate {RATE} --fd --count {SAMPLES['fd']}' \\",
        f"    '--filter mars --fd --count {SAMPLES['fd']} --seed 5' || rc=1",
        f"run_case small '--filter ars --rate {RATE} --id-offset {SMALL_OFFSET}' \\",
        f"    '--filter ars --count {SAMPLES['small']} --seed 7 --id-offset {SMALL_OFFSET}' \\",
        "    $NODE_SMALL || rc=1",
        # 3. faults: a second and a third writer flood the bus while verify streams valid samples; every
        # socket gets a 16 MB receive buffer (the verifier, Python in the guest, reads slower than the node)
        "echo 16777216 > /proc/sys/net/core/rmem_default",
        f"$NODE --channel vcan0 --filter ars --rate {RATE} > $OUT/faults.node.out 2>&1 &",
        "node_pid=$!",
        "wait_ready $OUT/faults.node.out",
        f"$PY {ROOT}/tests/uml/flood.py --channel vcan0 --rate {FLOOD_RATE} --stop $OUT/faults.stop "
        "--report $OUT/faults.flood.json > /dev/null 2> $OUT/faults.flood.err &",
        "fl_pid=$!",
        f"cangen vcan0 -e -I r -L r -D r -g {CANGEN_GAP_MS} -n {CANGEN_FRAMES} &",
        "cg_pid=$!",
        "sleep 0.3",
        "$PY -m attica.cli verify --interface socketcan --channel vcan0 -q "
        f"--filter ars --count {FAULT_SAMPLES} --seed 6 > $OUT/faults.verify.out 2>&1",
        'echo "faults: verify exit $?"',
        "wait $cg_pid; touch $OUT/faults.stop; wait $fl_pid",
        'sleep 0.3; kill -INT $node_pid; wait $node_pid; echo "faults: node exit $?"',
        "cat $OUT/faults.verify.out $OUT/faults.node.out $OUT/faults.flood.json",
        "echo 212992 > /proc/sys/net/core/rmem_default",
        # 4. the interface vanishes under a running node
        "ip link add dev vcan1 type vcan && ip link set up vcan1",
        "$NODE --channel vcan1 --filter ars > $OUT/gone.node.out 2>&1 &",
        "node_pid=$!",
        "wait_ready $OUT/gone.node.out",
        "ip link del vcan1",
        "i=0; while kill -0 $node_pid 2>/dev/null; do i=$((i+1)); [ $i -gt 100 ] && kill -9 $node_pid; "
        "sleep 0.05; done",
        'wait $node_pid; echo "gone: node exit $?"; cat $OUT/gone.node.out',
        # 5. a full tx queue: a plug qdisc holds the node's output until released (ENOBUFS meanwhile);
        # a prio qdisc lets the input writer's frames (socket priority 6 -> band 0) pass the plug (band 1)
        "mods=/usr/lib/uml/modules/$(uname -r)/kernel/net/sched",
        "for m in sch_prio sch_plug; do insmod $mods/$m.ko; done",
        "ip link add dev vcan2 type vcan && ip link set up vcan2 "
        "&& tc qdisc add dev vcan2 root handle 1: prio "
        "&& tc qdisc add dev vcan2 parent 1:2 handle 20: plug limit 32 "
        '|| echo "nobufs: cannot set up the plug qdisc"',
        f"$NODE --channel vcan2 --filter ars --rate {RATE} > $OUT/nobufs.node.out 2>&1 &",
        "node_pid=$!",
        "wait_ready $OUT/nobufs.node.out",
        f"$PY {ROOT}/tests/uml/flood.py --channel vcan2 --valid {NOBUFS_SAMPLES} --rate 1000 --priority 6",
        "sleep 2",
        'kill -0 $node_pid && echo "nobufs: node alive while the queue is held"',
        "tc qdisc change dev vcan2 parent 1:2 handle 20: plug release_indefinite",
        'sleep 1.5; kill -INT $node_pid; wait $node_pid; echo "nobufs: node exit $?"',
        "cat $OUT/nobufs.node.out",
        "exit $rc",
    ]
    job = tmp / "job.sh"
    job.write_text("\n".join(lines) + "\n")
    return job


def _xstate_pad() -> Path:
    """build/uml/xstate_pad.so (tests/uml/xstate_pad.c), built when missing or older than its source."""
    if not XSTATE_PAD.exists() or XSTATE_PAD.stat().st_mtime < XSTATE_PAD_SRC.stat().st_mtime:
        XSTATE_PAD.parent.mkdir(parents=True, exist_ok=True)
        cc = os.environ.get("CC", "cc")
        cmd = [
            cc,
            "-O2",
            "-Wall",
            "-Wextra",
            "-shared",
            "-fPIC",
            "-o",
            str(XSTATE_PAD),
            str(XSTATE_PAD_SRC),
            "-ldl",
        ]
        r = subprocess.run(cmd, capture_output=True, text=True)
        assert r.returncode == 0, f"building {XSTATE_PAD_SRC.name} failed:\n{r.stderr}"
    return XSTATE_PAD


def _boot(job: Path, timeout: float = 300.0) -> tuple[int | None, str, str]:
    """Boot the guest on ``job``; (job exit status or None if the guest died, job log, console)."""
    assert UML is not None
    env = {**os.environ, "LD_PRELOAD": str(_xstate_pad())}
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
    r = subprocess.run(
        cmd, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=timeout, env=env
    )
    status_file = job.with_name(job.name + ".status")
    log_file = job.with_name(job.name + ".log")
    log = log_file.read_text() if log_file.exists() else ""
    status = int(status_file.read_text().strip()) if status_file.exists() else None
    return status, log, r.stdout + r.stderr


def _cantools_vs_monitor(log: Path, id_offset: str = "0") -> int:
    """Compare ``cantools decode`` with ``attica monitor --log`` line by line; return frames compared.

    With an ID offset, cantools reads the DBC ``attica dbc --id-offset`` writes for it.
    """
    from attica.can.monitor import decoded_fields, same_value

    dbc = ROOT / "firmware" / "can" / "attica.dbc"
    if int(id_offset, 0) != 0:
        dbc = log.with_suffix(".dbc")
        subprocess.run(
            [sys.executable, "-m", "attica.cli", "dbc", "--id-offset", id_offset, "-o", str(dbc)],
            check=True,
            env=ENV,
        )
    ref = cantools_decode(log, dbc)
    ours = subprocess.run(
        [sys.executable, "-m", "attica.cli", "monitor", "--log", str(log), "--id-offset", id_offset],
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
                "mars" if name == "fd" else "ars",
                "--id-offset",
                SMALL_OFFSET if name == "small" else "0",
            ],
            capture_output=True,
            text=True,
            env=ENV,
        )
        assert r.returncode == 0 and re.search(r"verdict: BIT-EXACT$", r.stdout, re.M), r.stdout + r.stderr
        frames = _cantools_vs_monitor(logf, SMALL_OFFSET if name == "small" else "0")
        assert frames > n
    _check_faults(tmp_path, log)
    assert not IN_CI or status == 0


def _node_stats(text: str) -> dict[str, int]:
    line = next(ln for ln in text.splitlines() if "attica-node: stats:" in ln)
    return {k: int(v) for k, v in re.findall(r"(\w+)=(\d+)", line.split("| node:")[1])} | {
        f"port_{k}": int(v) for k, v in re.findall(r"(\w+)=(\d+)", line.split("| node:")[0])
    }


def _check_faults(tmp: Path, log: str) -> None:
    """Cases 3-5 of the guest job (see the module docstring)."""
    import json

    out = (tmp / "faults.verify.out").read_text()
    assert re.search(r"verdict: BIT-EXACT$", out, re.M), out + log
    assert f"{FAULT_SAMPLES} bit-exact, 0 mismatched, 0 missing" in out, out
    flood = json.loads((tmp / "faults.flood.json").read_text())
    st = _node_stats((tmp / "faults.node.out").read_text())
    c = flood["counts"]
    print(
        f"faults: {flood['frames']} malformed frames at {flood['rate']:.0f} frames/s ({c}) + {CANGEN_FRAMES} "
        f"cangen extended frames during {FAULT_SAMPLES} valid samples; node: {st}"
    )
    assert flood["rate"] > 0.5 * FLOOD_RATE, flood  # the stated rate was (nearly) reached
    assert st["unknown_ids"] == c["unknown"], (st, c)
    assert st["dlc_errors"] == c["dlc"], (st, c)
    assert st["crc_errors"] == c["crc"], (st, c)
    assert st["port_ignored"] == c["rtr"] + CANGEN_FRAMES, (st, c)
    assert st["steps"] == FAULT_SAMPLES and st["rx_overflows"] == 0 and st["port_rx_rejected"] == 0, st
    assert st["duplicates"] == 0 and st["stale_partials"] == 0 and st["counter_gaps"] == 0, st
    gone = (tmp / "gone.node.out").read_text()
    assert "gone: node exit 1" in log, log
    assert "CAN interface 'vcan1' was removed" in gone or "CAN interface 'vcan1' went down" in gone, gone
    nob = (tmp / "nobufs.node.out").read_text()
    assert "nobufs: node alive while the queue is held" in log, log
    assert "nobufs: node exit 0" in log, log
    assert "tx queue of 'vcan2' is full" in nob and "has room again" in nob, nob
    st = _node_stats(nob)
    assert st["steps"] == NOBUFS_SAMPLES and st["port_tx_full"] >= 1 and st["port_tx_retries"] > 0, st
    assert st["port_tx_frames"] == NOBUFS_SAMPLES * 6 + NOBUFS_SAMPLES // 16, st  # sets + DIAG every 16th

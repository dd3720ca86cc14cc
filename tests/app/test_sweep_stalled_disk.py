"""`orbitrig sweep` whose disk never returns: SIGTERM stops the run at once, both drives ramp to
zero and the run says it waits for its storage; a signal once a write has not returned for
DISK_STALL_S (the abort, the drives stopped already) leaves the run 2 s later: the command names what was not written and exits 1, every
block written before is kept and `--resume` continues the run.

Real parts: `orbitrig sweep --sim` as a process (the simulator in its own), real signals.
Injected (a disk that never returns cannot be produced by the real parts): the block writes
hang once the test creates a flag file (tests/support/stalled_disk.py)."""

import signal
import subprocess
import time

import pytest

from orbitrig.run.closing import DISK_STALL_S
from support.stalled_disk import stalling_env
from support.cli_helpers import orbitrig_started, reaped

pytestmark = pytest.mark.timeout(180)

MATRIX = "demo"


def _wait_log(log, what: str, proc: subprocess.Popen, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while what not in (log.read_text() if log.exists() else ""):
        assert proc.poll() is None, f"sweep exited {proc.returncode} before {what!r}"
        assert time.monotonic() < deadline, f"no {what!r} in run.log"
        time.sleep(0.01)


def _blocks_in_log(log) -> int:
    return (log.read_text() if log.exists() else "").count("speeds set:")


def test_a_signal_while_the_run_waits_for_its_disk_leaves_it_once_its_drives_are_stopped(tmp_path):
    env, flag = stalling_env(tmp_path)
    out = tmp_path / "run"
    log = out / "run.log"
    with reaped(orbitrig_started("sweep", "--sim", "--out", str(out), env=env, stdin=subprocess.PIPE)) as proc:
        deadline = time.monotonic() + 60
        while len(list((out / "points" / "0000").glob("*.h5"))) < 2:  # blocks written (a block's write
            assert proc.poll() is None and time.monotonic() < deadline, "no blocks"  # waits for the next ramp)
            time.sleep(0.01)
        flag.touch()
        seen = _blocks_in_log(log)
        while _blocks_in_log(log) < seen + 2:  # a block measured after: its write hangs
            assert proc.poll() is None and time.monotonic() < deadline, "no block after the stall"
            time.sleep(0.01)
        proc.send_signal(signal.SIGTERM)
        _wait_log(log, "waiting for the storage in flight: store 0000/", proc)
        assert "drives: ramp stop (OFF1); standstill after" in log.read_text()
        time.sleep(DISK_STALL_S)  # a write stalled that long: the run waits for a disk that stalls
        assert proc.poll() is None
        t = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30)
        assert proc.returncode == 1, err[-3000:]
        assert time.monotonic() - t < 6.0  # 2 s of grace, then the exit
    said = " ".join(err.split())  # the terminal's lines folded at 80 columns
    assert "error: left without waiting for the disk (SIGTERM again), after the drives' closing stop" in said, err
    assert "not written: store 0000/" in said and "the run's end (its status, run.h5)" in said, err
    assert f"`orbitrig sweep --resume {out}` continues it" in said, err
    assert len(list((out / "points" / "0000").glob("*.h5"))) >= 2  # written before the stall: kept

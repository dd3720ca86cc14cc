"""`orbitrig sweep` whose disk never returns: SIGTERM stops the run at once, both drives ramp to
zero and the run says it waits for its storage; a signal once a write has not returned for
DISK_STALL_S (the abort, the drives stopped already) leaves the run 2 s later: the command names what was not written and exits 1, every
block written before is kept and `--resume` continues the run.

Real parts: `orbitrig sweep --sim` as a process (the simulator in its own), real signals.
Injected (a disk that never returns cannot be produced by the real parts): the block writes
hang once the test creates a flag file (tests/support/stalled_disk.py)."""

import signal
import time

import pytest

from orbitrig.run.closing import DISK_STALL_S
from support.stalled_disk import stalling_env
from support.cli_helpers import reaped
from support.sweep_process import SweepProcess

pytestmark = pytest.mark.timeout(180)

MATRIX = "demo"


def test_a_signal_while_the_run_waits_for_its_disk_leaves_it_once_its_drives_are_stopped(tmp_path):
    env, flag = stalling_env(tmp_path)
    out = tmp_path / "run"
    sweep = SweepProcess(out, env=env)
    with reaped(sweep.proc) as proc:
        deadline = time.monotonic() + 60
        while len(list((out / "points" / "0000").glob("*.h5"))) < 2:  # blocks written (a block's write
            assert proc.poll() is None and time.monotonic() < deadline, "no blocks"  # waits for the next ramp)
            time.sleep(0.01)
        flag.touch()
        seen = sweep.text().count("speeds set:")
        while sweep.text().count("speeds set:") < seen + 2:  # a block measured after: its write hangs
            assert proc.poll() is None and time.monotonic() < deadline, "no block after the stall"
            time.sleep(0.01)
        proc.send_signal(signal.SIGTERM)
        sweep.wait_log("waiting for the storage in flight: store 0000/")
        assert "drives: ramp stop (OFF1); standstill after" in sweep.text()
        time.sleep(DISK_STALL_S)  # a write stalled that long: the run waits for a disk that stalls
        assert proc.poll() is None
        t = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30)
        assert proc.returncode == 1, err[-3000:]
        assert time.monotonic() - t < 6.0  # 2 s of grace, then the exit
    said = " ".join(err.split())  # the terminal's lines folded at 80 columns
    assert (
        "error: left without waiting for the disk (SIGTERM; a second signal), after the drives' closing stop" in said
    ), err
    assert "not written: store 0000/" in said and "the run's end (its status, run.h5)" in said, err
    assert f"`orbitrig sweep --resume {out}` continues it" in said, err
    assert len(list((out / "points" / "0000").glob("*.h5"))) >= 2  # written before the stall: kept

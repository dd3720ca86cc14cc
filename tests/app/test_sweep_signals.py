"""Every way out of `orbitrig sweep --sim` stops the drives first: the real signal sent to a real
subprocess, then the exit status, the run's status and what the drives were commanded (run.log
names the stop sent and both drives' speed and fault code once at standstill)."""

import os
import signal
import time
from pathlib import Path

import pytest

from support.store_checks import small_matrix
from support.sweep_process import SweepProcess, sweeps

pytestmark = pytest.mark.timeout(120)

MATRIX = small_matrix("signals", 20)
STANDSTILL = "standstill after"
SAFE = "spin ACT 0 rpm, fault 0; orbit ACT 0 rpm, fault 0"


class Sweep(SweepProcess):
    """`orbitrig sweep --sim` of MATRIX in a subprocess, watched through its run.log."""

    def __init__(self, tmp_path, *extra: str):
        (tmp_path / "m.toml").write_text(MATRIX)
        super().__init__(tmp_path / "run", "--matrix", str(tmp_path / "m.toml"), *extra)

    def finish(self, timeout: float = 30.0) -> tuple[int, str]:
        _, err = self.proc.communicate(timeout=timeout)
        return self.proc.returncode, err


@pytest.fixture
def sweep(tmp_path):
    with sweeps(lambda *extra: Sweep(tmp_path, *extra)) as start:
        yield start


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT], ids=["SIGTERM", "SIGHUP", "SIGQUIT"])
def test_sigterm_and_sighup_stop_with_a_ramp(sweep, sig):
    s = sweep()
    s.wait_log("[running] speeds set: spin 1000 rpm")
    s.proc.send_signal(sig)
    code, err = s.finish()
    assert code == 3, err
    assert f"run stopped: stopped at once by {sig.name}" in err and "Traceback" not in err
    assert s.status() == "stopped"
    log = s.text()
    assert f"[stopping] {sig.name}: stopping now, both drives ramp to zero" in log
    assert "drives: ramp stop (OFF1); " + STANDSTILL in log and SAFE in log, log


class NohupSweep(Sweep):
    """The sweep started by `nohup`, which ignores SIGHUP (standard output a pipe: nothing redirected)."""

    launcher = ("nohup",)


def _dir(path):
    path.mkdir()
    return path


def _nohup_sweep_sent(out, sig) -> tuple[NohupSweep, int, str]:
    """A sweep under nohup in `out`, sent `sig` once its speeds are set: (it, exit status, stderr)."""
    with sweeps(lambda *extra: NohupSweep(_dir(out), *extra)) as start:
        s = start()
        s.wait_log("[running] speeds set: spin 1000 rpm")
        s.proc.send_signal(sig)
        code, err = s.finish()
    return s, code, err


def test_a_sweep_started_under_nohup_goes_on_when_its_terminal_closes(tmp_path):
    """`nohup orbitrig sweep ...`: the hang-up stays ignored, as the operator asked (before, the
    sweep installed its own handler and stopped when the terminal closed): the run completes, and
    says at its start that SIGHUP is ignored. SIGTERM still stops both drives with a ramp."""
    s, code, err = _nohup_sweep_sent(tmp_path / "hup", signal.SIGHUP)
    assert code == 0, err
    words = " ".join(err.split())  # as wrapped on the terminal's width
    note = "note: started with SIGHUP ignored (nohup, or a background job): left ignored (closing the terminal"
    assert note + " does not stop it)" in words, err
    assert s.status() == "completed" and "SIGHUP" not in s.text()
    s, code, err = _nohup_sweep_sent(tmp_path / "term", signal.SIGTERM)
    assert code == 3, err
    assert "run stopped: stopped at once by SIGTERM" in err and "Traceback" not in err
    log = s.text()
    assert "drives: ramp stop (OFF1); " + STANDSTILL in log and SAFE in log, log


def test_ctrl_z_does_not_suspend_a_sweep_with_the_drives_turning(sweep):
    """Ctrl-Z (SIGTSTP) with the drives at speed is refused with a line and the sweep goes on:
    before, it was suspended, and on `fg` found its CAN node silent for the time it was held (on
    the rig, with the shipped 1 s drive watchdog, both drives tripped unwatched: fault 7510, the
    run failed). A later SIGTERM still stops with a ramp."""
    s = sweep("--speedup", "5")  # slower than the default: the run is still under way at the SIGTERM
    s.wait_log("[running] speeds set: spin 1000 rpm")
    s.proc.send_signal(signal.SIGTSTP)
    time.sleep(2.0)  # beyond the CAN node's heartbeat (1.5 s): a sweep held so long finds it lost
    s.proc.send_signal(signal.SIGCONT)  # `fg`, had it been suspended
    time.sleep(0.5)  # what it finds after being held, it says
    s.proc.send_signal(signal.SIGTERM)
    code, err = s.finish()
    assert code == 3, err
    assert "Ctrl-Z ignored: orbitrig sweep does not suspend while it commands the drives" in err
    assert s.status() == "stopped"
    log = s.text()
    assert "[stopping] SIGTERM: stopping now, both drives ramp to zero" in log
    assert "drives: ramp stop (OFF1); " + STANDSTILL in log and SAFE in log, log


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP], ids=["SIGTERM", "SIGHUP"])
def test_a_terminal_gone_does_not_keep_the_stop_from_the_drives(sweep, sig):
    """stderr's reader gone (a closed terminal or pipe: every write fails) before the signal:
    the stop still reaches the engine and both drives ramp to zero."""
    s = sweep()
    s.wait_log("[running] speeds set: spin 1000 rpm")
    s.proc.stderr.close()
    time.sleep(0.3)  # the progress bars meet the broken pipe
    s.proc.send_signal(sig)
    s.proc.stdout.read()
    assert s.proc.wait(timeout=30) == 3
    assert s.status() == "stopped"
    log = s.text()
    assert f"[stopping] {sig.name}: stopping now, both drives ramp to zero" in log
    assert "drives: ramp stop (OFF1); " + STANDSTILL in log and SAFE in log, log


def test_a_signal_during_the_ramp_aborts_with_an_emergency_stop(sweep):
    s = sweep("--speedup", "1")  # real time: the ramp from 1000 rpm takes seconds
    s.wait_log("[running] speeds set: spin 1000 rpm")
    time.sleep(1.0)
    s.proc.send_signal(signal.SIGTERM)
    s.wait_log("[stopping] SIGTERM")
    time.sleep(0.2)
    s.proc.send_signal(signal.SIGINT)
    code, err = s.finish()
    assert code == 4, err
    assert "Ctrl-C; a second signal: aborting" in err
    said = " ".join(err.split())  # the console's lines joined
    assert (
        "run aborted: aborted by " in said
        and "(Ctrl-C; a second signal) while stopping (stopped at once by SIGTERM)" in said
    )
    assert s.status() == "aborted"
    log = s.text()
    assert "drives: emergency stop (OFF3) after an abort during the ramp; " + STANDSTILL in log and SAFE in log, log


def test_ctrl_c_while_a_stop_is_under_way_aborts(sweep):
    s = sweep("--speedup", "5")  # a stop finishes its orbit frequency: seconds at speed-up 5
    s.wait_log("[running] speeds set: spin 1000 rpm")
    s.proc.send_signal(signal.SIGINT)
    s.wait_log("[paused] paused at a safe point")
    s.proc.stdin.write("s\n")
    s.proc.stdin.flush()
    s.wait_log("[stopping] stop requested")
    s.proc.send_signal(signal.SIGINT)
    code, err = s.finish()
    assert code == 4, err
    assert s.status() == "aborted"
    assert "drives: emergency stop (OFF3)" in s.text() and SAFE in s.text()


def _simulators_of(pid: int) -> list[int]:
    """The simulator processes started by process `pid` (`python -m sim ... --parent-pid PID`)."""
    found = []
    for entry in os.listdir("/proc"):
        try:
            args = (Path("/proc") / entry / "cmdline").read_bytes().split(b"\0")
        except (OSError, ValueError):
            continue
        if b"sim" in args and b"--parent-pid" in args and args[args.index(b"--parent-pid") + 1] == str(pid).encode():
            found.append(int(entry))
    return found


def test_sigterm_before_the_run_has_begun_leaves_nothing(sweep):
    """SIGTERM as the simulator starts (before the sweep handles signals: nothing opened to the drives)
    ends the sweep as SIGTERM does by default; the simulator ends with it, the run directory stays
    empty (its check made it)."""
    s = sweep()
    deadline = time.monotonic() + 30
    while not (simulators := _simulators_of(s.proc.pid)):
        assert s.proc.poll() is None and time.monotonic() < deadline, "no simulator started"
        time.sleep(0.005)
    s.proc.send_signal(signal.SIGTERM)
    code, err = s.finish()
    assert code == -signal.SIGTERM, err
    deadline = time.monotonic() + 10
    while any(Path("/proc", str(p)).exists() for p in simulators) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert _simulators_of(s.proc.pid) == [], "the simulator outlived the sweep"
    assert not s.out.exists() or list(s.out.iterdir()) == []


class OnePointSweep(SweepProcess):
    """`orbitrig sweep --sim` of one operating point (a short run), watched through its run.log."""

    def __init__(self, tmp_path, *extra: str):
        (tmp_path / "one.toml").write_text(small_matrix("closing", 6, spin_rpm=(1000.0,)))
        super().__init__(tmp_path / "run", "--matrix", str(tmp_path / "one.toml"), *extra)


#: what SIGTERM as the run ends makes of it, by exit status: as the drives ramp down at the end, a stop
#: at once (3); once the run already stops (its last writes finishing), an abort (4). The closing line
#: says the data are complete either way.
AT_THE_END = {
    3: ("stopped", "run stopped: all points completed; stopped at once by SIGTERM ("),
    4: ("aborted", "run aborted: all points completed; aborted by "),
}


def test_sigterm_as_the_drives_ramp_down_at_the_end_stops_the_run_all_points_completed(tmp_path):
    """SIGTERM once every point is measured (the drives ramping down at the end, or the last writes finishing)
    ends the run as a SIGTERM does, as the MQTT contract has every stop and abort end it: stopped, exit 3 (or,
    the run already stopping, aborted, exit 4, the ramp turned into the emergency stop); the drives stop, and
    the closing line starts with 'all points completed; ' so nobody looks for points that are not missing."""
    with sweeps(lambda *extra: OnePointSweep(tmp_path, *extra)) as start:
        s = start("--speedup", "2")  # the ramp from 1000 rpm at the end lasts about 0.6 s
        s.wait_log("every point measured: both drives ramp to zero")
        s.proc.send_signal(signal.SIGTERM)
        _, err = s.proc.communicate(timeout=60)
    log, code = s.text(), s.proc.returncode
    assert code in AT_THE_END, err
    status, closing = AT_THE_END[code]
    said = " ".join(err.split())
    assert closing in said, said
    last = said.split(f"run {status}: ")[-1]  # the closing line: 'all points completed; ... (1 of 1 points ...)'
    assert "SIGTERM" in last and "incomplete" not in last, said
    assert s.status() == status
    assert f"ended: {status}: all points completed; " in log, log
    assert STANDSTILL in log and SAFE in log, log

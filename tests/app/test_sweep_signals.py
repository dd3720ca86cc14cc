"""Every way out of `orbitrig sweep --sim` stops the drives first: the real signal sent to a real
subprocess, then the exit status, the run's status and what the drives were commanded (run.log
names the stop sent and both drives' speed and fault code once at standstill)."""

import signal
import subprocess
import time

import h5py
import pytest

from support.sweep_helpers import orbitrig_cmd
from support.paths import ROOT

pytestmark = pytest.mark.timeout(120)

MATRIX = """
name = "signals"
revolutions = 20
[operating]
spin_rpm = [1000.0, 2000.0]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.4]
static_eccentricity = [0.0]
dynamic_eccentricity = [0.096]
[orbit]
ratios = [0.3, 0.6, 0.9]
[[models]]
model = "kc8"
"""
STANDSTILL = "standstill after"
SAFE = "spin ACT 0 rpm, fault 0; orbit ACT 0 rpm, fault 0"


class Sweep:
    """`orbitrig sweep --sim` in a subprocess, watched through its run.log."""

    def __init__(self, tmp_path, *extra: str):
        (tmp_path / "m.toml").write_text(MATRIX)
        self.out = tmp_path / "run"
        self.log = self.out / "run.log"
        self.proc = subprocess.Popen(
            orbitrig_cmd("sweep", "--sim", "--matrix", str(tmp_path / "m.toml"), "--out", str(self.out), *extra),
            cwd=ROOT,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )

    def text(self) -> str:
        return self.log.read_text() if self.log.exists() else ""

    def wait_log(self, what: str, timeout: float = 60.0) -> None:
        deadline = time.monotonic() + timeout
        while what not in self.text():
            if self.proc.poll() is not None:
                raise AssertionError(f"sweep exited {self.proc.returncode} before {what!r}:\n{self.proc.stderr.read()}")
            assert time.monotonic() < deadline, f"no {what!r} in run.log:\n{self.text()}"
            time.sleep(0.005)

    def finish(self, timeout: float = 30.0) -> tuple[int, str]:
        _, err = self.proc.communicate(timeout=timeout)
        return self.proc.returncode, err

    def status(self) -> str:
        with h5py.File(self.out / "run.h5", "r") as f:
            return str(f.attrs["status"])

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


@pytest.fixture
def sweep(tmp_path):
    made = []

    def start(*extra):
        made.append(Sweep(tmp_path, *extra))
        return made[-1]

    yield start
    for s in made:
        s.close()


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
    assert "Ctrl-C again: aborting" in err
    assert "run aborted: aborted by " in err and "(Ctrl-C) while stopping (stopped at once by SIGTERM)" in err
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

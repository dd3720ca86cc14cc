"""`orbitrig sweep` as a background job of its terminal (`orbitrig sweep ... &`, `bg`) is not
stopped by the kernel's job control while it commands the drives: it ignores SIGTTIN and SIGTTOU
(orbitrig.cli.signals.refuse_suspension). Before, its pause prompt's read of the terminal (or,
after `stty tostop`, its progress bars' next write) stopped it as Ctrl-Z would: the drives turned
unwatched until their comm-loss watchdog tripped them. Real parts: a pseudo-terminal whose
foreground is another process group (support.job_control), the sweep's simulator."""

from __future__ import annotations

import re
import signal
import termios
import time

import pytest

from support.cli_helpers import child_env, orbitrig_cmd
from support.job_control import STOPPED, BackgroundJob
from support.pseudo_terminal import Terminal
from support.store_checks import small_matrix

pytestmark = pytest.mark.timeout(120)

SPEEDS_SET = "[running] speeds set: spin 1000 rpm"
WAITING = "prompt waiting: orbitrig sweep is a background job of its terminal and cannot read it"
QUESTION = "[r]esume, [s]top, [a]bort?"
BARS = ("points ", "orbit blocks ", "revolutions ")


class BackgroundSweep:
    """`orbitrig sweep --sim` started as a background job of a pseudo-terminal (its standard input,
    output and error), watched through its run.log."""

    def __init__(self, tmp_path) -> None:
        (tmp_path / "m.toml").write_text(small_matrix("background", 200, (1000.0,)))
        self.log = tmp_path / "run" / "run.log"
        cmd = orbitrig_cmd("sweep", "--sim", "--out", str(tmp_path / "run"), "--matrix", str(tmp_path / "m.toml"))
        self.terminal = Terminal()
        self.job = BackgroundJob(
            self.terminal, [*cmd, "--speedup", "5"], env=child_env({"COLUMNS": "200", "NO_COLOR": "1"})
        )

    def text(self) -> str:
        return self.log.read_text() if self.log.exists() else ""

    def wait_log(self, what: str, timeout: float = 60.0) -> None:
        deadline = time.monotonic() + timeout
        while what not in self.text():
            assert self.job.shell.poll() is None, f"ended before {what!r}:\n{self.terminal.text()[-3000:]}"
            assert time.monotonic() < deadline, f"no {what!r} in run.log (job state {self.job.state()}):\n{self.text()}"
            time.sleep(0.01)

    def said(self) -> str:
        """The terminal's lines but the progress bars' (what the sweep said)."""
        lines = re.sub(r"\x1b\[[0-9;]*[A-Za-z]", "", self.terminal.text()).splitlines()
        return "\n".join(line for line in lines if not line.startswith(BARS))

    def says(self, text: str, timeout: float) -> None:
        """Wait until the sweep has said `text` on the terminal (fail after `timeout` s)."""
        _until(lambda: text in self.said(), lambda: f"not said: {text!r}\n{self.said()[-2000:]}", timeout)

    def never_stopped(self, seconds: float) -> None:
        """The job is not stopped by the kernel at any look during `seconds` (every 0.05 s)."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            state = self.job.state()
            assert state != STOPPED, f"stopped (state {state}) with the drives turning:\n{self.terminal.text()[-2000:]}"
            time.sleep(0.05)

    def close(self) -> None:
        self.job.close()
        self.terminal.close()


def _until(condition, what, timeout: float = 10.0) -> None:
    """Until `condition()` holds; AssertionError saying `what()` after `timeout` s."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, what()
        time.sleep(0.02)


def _last_pause(log: str) -> str:
    """The last status line of the pause in `log` (run.log)."""
    return [line for line in log.splitlines() if "[paused]" in line][-1]


@pytest.fixture
def background_sweep(tmp_path):
    s = BackgroundSweep(tmp_path)
    try:
        yield s
    finally:
        s.close()


def test_a_pause_prompt_in_the_background_waits_for_fg_and_the_sweep_is_not_stopped(background_sweep):
    """The pause prompt's read fails instead of stopping the sweep: said once, the pause then waits
    as one nobody can answer ([interlocks] unanswered_pause_s); `fg` asks it again, the pause's
    limit dropped, and the terminal's answer is taken."""
    s = background_sweep
    s.wait_log(SPEEDS_SET)
    s.job.signal(signal.SIGINT)  # `kill -INT %1`: Ctrl-C does not reach a background job
    s.never_stopped(1.5)  # before: stopped by SIGTTIN at the prompt's read, the drives at speed
    s.says(WAITING, 10)
    s.wait_log("nobody could answer: limit 60 s", timeout=10)
    assert s.said().count(WAITING) == 1
    asked = s.said().count(QUESTION)
    s.job.fg()
    _until(lambda: s.said().count(QUESTION) > asked, s.said)  # asked again in the foreground
    _until(lambda: "unless resumed" not in _last_pause(s.text()), s.text)  # the pause's limit dropped
    s.terminal.press(b"r\n")
    # the resume taken (its command recorded; "resumed" alone is in the pause's limit, "unless
    # resumed"): a SIGTERM before it would be a second signal after the Ctrl-C, an abort (exit 4)
    s.wait_log("command resume by", timeout=10)
    s.job.signal(signal.SIGTERM)
    code = s.job.wait(30)
    log = s.text()
    assert code == 3, (code, log, s.terminal.text())
    assert "drives: ramp stop (OFF1); standstill after" in log and "stopped at once by SIGTERM" in log, log
    assert "Traceback" not in s.terminal.text()


def test_stty_tostop_does_not_stop_a_sweep_in_the_background(background_sweep):
    """`stty tostop` while the sweep runs in the background: its progress bars' writes go through
    (before, the first stopped it by SIGTTOU, the drives at speed); SIGTERM still stops it."""
    s = background_sweep
    s.wait_log(SPEEDS_SET)
    attrs = termios.tcgetattr(s.terminal.master)  # a pseudo-terminal's master sets its terminal's modes
    attrs[3] |= termios.TOSTOP
    termios.tcsetattr(s.terminal.master, termios.TCSANOW, attrs)
    shown = len(s.terminal.screen)
    s.never_stopped(1.0)  # the bars redraw 8 times a second
    assert len(s.terminal.screen) > shown, "nothing written in the background"
    s.job.signal(signal.SIGTERM)
    assert s.job.wait(30) == 3
    assert "drives: ramp stop (OFF1); standstill after" in s.text()

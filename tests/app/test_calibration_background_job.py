"""A calibration prompt read by a background job of its terminal (`orbitrig calibrate ... &`,
`bg`), the drives turning at the slow roll: the kernel does not stop the command (SIGTTIN ignored,
orbitrig.cli.signals.refuse_suspension; before, its read stopped it as Ctrl-Z would, the spindles
turning unwatched). The prompt says once that it waits for `fg`; brought to the foreground it is
asked again, waits without its limit and the terminal's Enter answers it; left in the background
it is a prompt nobody can answer, which fails the step after [interlocks] unanswered_pause_s, both
drives stopped. Real parts: a pseudo-terminal
whose foreground is another process group (support.job_control), the simulator."""

from __future__ import annotations

import sys
import time

import pytest

from support.cli_helpers import child_env
from support.job_control import STOPPED, BackgroundJob
from support.paths import ROOT
from support.pseudo_terminal import Terminal

pytestmark = pytest.mark.timeout(60)

PROMPT = "apply the static load fx = +500.0 N, fy = +0.0 N on the journal, then press Enter: "
WAITING = "prompt waiting: orbitrig calibrate is a background job of its terminal and cannot read it"


@pytest.fixture
def calibration():
    """`start(limit)`: the step (support.background_calibration) as a background job, [interlocks]
    unanswered_pause_s `limit` s; its terminal."""
    made: list[BackgroundJob] = []

    def start(limit: float) -> BackgroundJob:
        script = str(ROOT / "tests" / "support" / "background_calibration.py")
        env = child_env({"COLUMNS": "200", "NO_COLOR": "1"})
        made.append(BackgroundJob(Terminal(), [sys.executable, script, f"{limit:g}"], env=env))
        return made[-1]

    yield start
    for job in made:
        job.close()
        job.terminal.close()


def _asked_and_not_stopped(job: BackgroundJob) -> None:
    """The prompt asked (the terminal read in the background) within 30 s, the job never stopped
    until 1.5 s after (looked at every 0.05 s)."""
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        assert job.state() != STOPPED, f"stopped with the spindles turning:\n{job.terminal.text()[-2000:]}"
        if PROMPT in job.terminal.text():
            deadline = min(deadline, time.monotonic() + 1.5)
        time.sleep(0.05)
    assert PROMPT in job.terminal.text(), job.terminal.text()[-2000:]


def test_fg_answers_a_prompt_read_in_the_background(calibration):
    job = calibration(30.0)
    _asked_and_not_stopped(job)
    job.terminal.shows(WAITING, 5)
    assert "Meanwhile the step fails after 30 s ([interlocks] unanswered_pause_s), both drives stopped" in " ".join(
        job.terminal.text().split()
    )
    job.fg()
    job.terminal.press(b"\n")  # kept by the terminal until the job reads it in the foreground
    assert job.wait(30) == 0, job.terminal.text()[-2000:]
    job.terminal.shows("confirmed at spin 600 rpm", 5)
    assert job.terminal.text().count(WAITING) == 1


def test_the_background_words_and_the_prompt_asked_again_are_said_in_order_by_the_loop(calibration):
    """The words of the read that failed in the background, then after `fg` the prompt asked again,
    each once and in that order, written by the thread of the step's event loop (the main thread),
    as the sweep's operator writes them: before, the reader's thread (calibrate-stdin) wrote both
    while the loop could write too."""
    job = calibration(30.0)
    job.terminal.shows(WAITING, 30)
    job.fg()
    deadline = time.monotonic() + 10
    while job.terminal.text().count(PROMPT) < 2:  # asked again in the foreground
        assert time.monotonic() < deadline, f"not asked again after fg:\n{job.terminal.text()[-2000:]}"
        time.sleep(0.02)
    job.terminal.press(b"\n")
    assert job.wait(30) == 0, job.terminal.text()[-2000:]
    job.terminal.shows("confirmed at spin 600 rpm", 5)
    said = " ".join(job.terminal.text().split())
    asked = said.index(PROMPT.strip())
    waits = said.index(WAITING, asked)
    asked_again = said.index(PROMPT.strip(), waits)
    assert said.count(WAITING) == 1 and said.count(PROMPT.strip()) == 2, said[-2000:]
    assert asked_again < said.index("confirmed at spin 600 rpm", asked_again)
    assert "prompt lines written on: MainThread confirmed" in said, said[-2000:]


def test_a_prompt_left_in_the_background_fails_the_step_after_the_limit(calibration):
    job = calibration(2.0)
    _asked_and_not_stopped(job)
    assert job.wait(30) == 1, job.terminal.text()[-2000:]
    said = " ".join(job.terminal.text().split())
    assert "failed: nobody confirmed within 2 s ([interlocks] unanswered_pause_s) with the drives turning" in said
    assert "both drives stopped" in said


def test_fg_lifts_the_limit_of_a_prompt_read_in_the_background(calibration):
    """Brought to the foreground, the prompt is asked again and waits without its limit, as the
    sweep's pause does: Enter a second after the limit has passed since the prompt still answers it
    (before, the limit still counted from the prompt: the step failed then, exit 1)."""
    limit = 4.0
    job = calibration(limit)
    job.terminal.shows(PROMPT, 30)
    asked = time.monotonic()  # the prompt was asked before: its limit, if counted from there, ends sooner
    job.terminal.shows(WAITING, 5)
    job.fg()
    deadline = time.monotonic() + limit
    while job.terminal.text().count(PROMPT) < 2:  # asked again in the foreground
        assert time.monotonic() < deadline, f"not asked again after fg:\n{job.terminal.text()[-2000:]}"
        time.sleep(0.02)
    time.sleep(max(0.0, asked + limit + 1.0 - time.monotonic()))
    assert job.shell.poll() is None, job.terminal.text()[-2000:]  # still waiting for its answer
    job.terminal.press(b"\n")
    assert job.wait(30) == 0, job.terminal.text()[-2000:]
    job.terminal.shows("confirmed at spin 600 rpm", 5)
    assert "failed" not in job.terminal.text()

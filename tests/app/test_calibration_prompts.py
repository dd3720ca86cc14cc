"""The operator's prompts of `orbitrig calibrate` on the rig read standard input so that a prompt
cancelled while it waits (Ctrl-C, SIGTERM) does not take the next answer: the next prompt gets
the next line, one Enter. Standard input a real pipe; the read's thread is known to wait in
read(2) on it (Linux /proc) before the prompt is cancelled, as at an operator's terminal."""

from __future__ import annotations

import asyncio
import os
import sys
from pathlib import Path

import pytest

from orbitrig.cli.calibrate_steps import OperatorLoads
from orbitrig.run.calibration_checks import CalibrationFailed
from support.polling import until

pytestmark = pytest.mark.timeout(120)


def _read_syscall() -> str:
    """The number /proc/<tid>/syscall gives for read(2) on this machine ('' where not known)."""
    return {"x86_64": "0", "aarch64": "63"}.get(os.uname().machine, "")


def _blocked_reading(fd: int) -> bool:
    """Whether a thread of this process waits in read(2) on `fd`."""
    for task in Path("/proc/self/task").iterdir():
        try:
            words = (task / "syscall").read_text().split()
        except OSError:
            continue
        if len(words) > 1 and words[0] == _read_syscall() and int(words[1], 16) == fd:
            return True
    return False


class Pipe:
    """A pipe that is this process's standard input: its read end `r`, `write`, `close`."""

    def __init__(self) -> None:
        self.r, self.w = os.pipe()
        self.stdin = os.fdopen(self.r, "r")

    def write(self, data: bytes) -> None:
        os.write(self.w, data)

    def close(self) -> None:
        if self.w >= 0:
            os.close(self.w)
            self.w = -1


@pytest.fixture
def stdin_pipe(monkeypatch):
    if not _read_syscall() or not Path("/proc/self/task").is_dir():
        pytest.skip("needs Linux /proc/<tid>/syscall on x86_64 or arm64")
    pipe = Pipe()
    monkeypatch.setattr(sys, "stdin", pipe.stdin)
    yield pipe
    pipe.close()  # a read still waiting (a failed test) ends at EOF


async def test_a_cancelled_prompt_leaves_the_next_enter_to_the_next_prompt(stdin_pipe):
    hands = OperatorLoads()
    first = asyncio.ensure_future(hands.apply_load(500.0, 0.0))
    await until(lambda: _blocked_reading(stdin_pipe.r), 30, "the first prompt reading standard input", every=0.01)
    first.cancel()  # Ctrl-C: the step is cancelled while the prompt waits
    with pytest.raises(asyncio.CancelledError):
        await first
    second = asyncio.ensure_future(hands.apply_load(0.0, 0.0))
    for _ in range(2):  # the second prompt runs up to its wait for the line (before the Enter is written)
        await asyncio.sleep(0)
    await until(lambda: _blocked_reading(stdin_pipe.r), 30, "the second prompt reading standard input", every=0.01)
    stdin_pipe.write(b"\n")  # one Enter
    await asyncio.wait_for(second, 30)  # the second prompt has it (not a reader nobody waits for)


async def test_closed_standard_input_fails_the_step_saying_so(stdin_pipe):
    prompt = asyncio.ensure_future(OperatorLoads().apply_load(500.0, 0.0))
    await until(lambda: _blocked_reading(stdin_pipe.r), 30, "the prompt reading standard input", every=0.01)
    stdin_pipe.close()
    with pytest.raises(CalibrationFailed, match="standard input is closed: nobody can confirm at the terminal"):
        await asyncio.wait_for(prompt, 30)


async def test_the_prompts_give_lengths_in_micrometres_with_the_micro_sign(stdin_pipe, capsys):
    """The probes' and the delay's prompts say the steps and the reference as the operator's other
    words do (rigunits.micrometres: the micro sign), never an ASCII 'um'."""
    hands = OperatorLoads()
    stdin_pipe.write(b"\n\n")  # the operator's two Enters
    await asyncio.wait_for(hands.apply_displacement(5e-6, -2.5e-6), 30)
    await asyncio.wait_for(hands.apply_reference(500.0, 20e-6), 30)
    said = capsys.readouterr().out
    assert "step the journal by x = +5.00 \u00b5m, y = -2.50 \u00b5m (micrometer)" in said, said
    assert "500 N on the force channels, 20 \u00b5m on the probes" in said and " um" not in said, said

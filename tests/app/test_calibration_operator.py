"""`orbitrig calibrate loads` on the rig, the operator at its terminal: both drives are brought to
a confirmed standstill before the operator is asked to remove the loads, on the normal end as
on every other way out; after a step that did not complete (Ctrl-C, SIGTERM, several signals, a
failed acquisition) the command does not wait for an Enter with the drives turning: it stops
them, says what is left on the rig and ends (exit 3 interrupted, 1 failed), no record written.

Real parts: the simulator in its own process (`orbitrig sim`) behind a copy of the lab's
rig.toml, so the command sees a rig (no --sim) and prompts; the test plays the operator's hands
through the simulator's control API (`apply_load`), answers on the command's standard input (a
pipe kept open: nobody answers unless the test writes), reads the drives' speeds from the
simulator and sends real signals to the command's process."""

from __future__ import annotations

import json
import math
import os
import re
import signal
import subprocess
import threading
import time
from pathlib import Path

import pytest

from orbitrig.cli.simulated_rig import SimulatorLink
from support.paths import ROOT
from support.rig_configs import lab_record_config
from support.sweep_helpers import orbitrig_cmd

pytestmark = pytest.mark.timeout(300)
PROMPT_END = "then press Enter: "
LOAD = re.compile(r"fx = ([+-][\d.]+) N, fy = ([+-][\d.]+) N")
LOADS = 7  # none, +-x, +-y, two diagonals (reduction.calibration.static_loads)


def _wait(condition, timeout: float, what) -> None:
    """Until `condition()` holds; AssertionError saying `what()` after `timeout` s."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, what()
        time.sleep(0.02)


class Simulator:
    """`orbitrig sim` in a process of its own: its endpoints and its control API."""

    def __init__(self) -> None:
        self.proc = subprocess.Popen(
            orbitrig_cmd("sim", "--modbus-port", "0", "--adc-port", "0", "--can-port", "0", "--speedup", "10"),
            cwd=ROOT,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        self.endpoints = json.loads(self.proc.stdout.readline())
        self.link = SimulatorLink(self.endpoints["control"])
        self.call = self.link.call  # the control API: cmd, fields -> its reply

    def rpm(self) -> tuple[float, float]:
        """Both drives' actual speeds now (rpm)."""
        st = self.call("state")
        return st["spin"] * 60 / (2 * math.pi), st["orbit"] * 60 / (2 * math.pi)

    def rig_config(self, folder: Path) -> Path:
        """A copy of the lab's rig.toml (and its records) whose transports are this simulator's."""
        ep = self.endpoints
        return lab_record_config(
            folder,
            edits={
                "adc_url": f"adc_url = {json.dumps(ep['adc'])}",
                "modbus_url": f"modbus_url = {json.dumps(ep['modbus'])}",
                "can_channel": f"can_channel = {json.dumps(ep['can'])}",
                "can_interface": 'can_interface = "serial"',
            },
        )

    def close(self) -> None:
        self.link.close()
        self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


class Calibrate:
    """`orbitrig calibrate loads --config RIG` at an operator's terminal: its prompts (standard
    output) and notes (standard error) collected as they come, Enter written on request."""

    def __init__(self, rig: Path):
        self.proc = subprocess.Popen(
            orbitrig_cmd("calibrate", "loads", "--config", str(rig))
            + ["--reference-id", "dead-weights", "--reference-u-pct", "0.1", "--revolutions", "5"],
            cwd=ROOT,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        self.out, self.err = bytearray(), bytearray()
        self.readers = [
            threading.Thread(target=self._collect, args=(self.proc.stdout, self.out), daemon=True),
            threading.Thread(target=self._collect, args=(self.proc.stderr, self.err), daemon=True),
        ]
        for r in self.readers:
            r.start()

    @staticmethod
    def _collect(stream, into: bytearray) -> None:
        while chunk := os.read(stream.fileno(), 4096):
            into.extend(chunk)

    def stdout(self) -> str:
        return self.out.decode(errors="replace")

    def stderr(self) -> str:
        return self.err.decode(errors="replace")

    def prompts(self) -> list[str]:
        """The prompts asked so far (each up to its 'then press Enter')."""
        return [p.strip() for p in self.stdout().split(PROMPT_END)[:-1]]

    def wait_prompt(self, n: int, timeout: float = 90.0) -> str:
        """The `n`-th prompt (1: the first), once asked."""
        _wait(
            lambda: len(self.prompts()) >= n or self.proc.poll() is not None,
            timeout,
            lambda: f"no prompt {n}:\n{self.stdout()}\n{self.stderr()}",
        )
        assert len(self.prompts()) >= n, f"exit {self.proc.returncode} before prompt {n}:\n{self.stderr()}"
        return self.prompts()[n - 1]

    def enter(self) -> None:
        self.proc.stdin.write(b"\n")
        self.proc.stdin.flush()

    def ended(self, sim: Simulator, timeout: float = 90.0) -> int:
        """The exit status, once the command ended (the drives' speeds said if it does not)."""
        _wait(
            lambda: self.proc.poll() is not None,
            timeout,
            lambda: f"still running, drives at {sim.rpm()} rpm, prompts {self.prompts()}:\n{self.stderr()}",
        )
        for r in self.readers:
            r.join(timeout=30)
        return self.proc.returncode

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


@pytest.fixture
def rig(tmp_path):
    """(simulator, rig.toml reaching it, the records' folder, a `calibrate()` starting the command)."""
    sim = Simulator()
    started: list[Calibrate] = []
    try:
        config = sim.rig_config(tmp_path)

        def calibrate() -> Calibrate:
            started.append(Calibrate(config))
            return started[-1]

        yield sim, config.parent / "calibration", calibrate
    finally:
        for c in started:
            c.close()
        sim.close()


def _apply(sim: Simulator, prompt: str) -> None:
    """The operator's hands: the load a prompt asks for, on the simulator's journal."""
    m = LOAD.search(prompt)
    fx, fy = (float(m.group(1)), float(m.group(2))) if m else (0.0, 0.0)
    assert m or "remove every calibration load" in prompt, prompt
    sim.call("apply_load", fx=fx, fy=fy)


def _turning(sim: Simulator) -> bool:
    return all(abs(w) > 250.0 for w in sim.rpm())  # the slow roll: 300 rpm


def test_the_loads_are_removed_only_once_both_drives_are_at_standstill(rig):
    sim, records, calibrate = rig
    before = sorted(p.name for p in records.iterdir())
    step = calibrate()
    for n in range(1, LOADS + 1):
        prompt = step.wait_prompt(n)
        assert _turning(sim), (n, sim.rpm())  # the loads are read at the slow roll
        assert prompt.startswith("the drives are turning: spin 300 rpm, orbit 300 rpm: "), prompt
        _apply(sim, prompt)
        step.enter()
    removal = step.wait_prompt(LOADS + 1)
    assert sim.rpm() == (0.0, 0.0), f"asked to remove the loads with the drives at {sim.rpm()} rpm: {removal!r}"
    assert removal == "both drives at standstill: remove every calibration load,", removal
    _wait(lambda: "both drives stopped" in step.stderr(), 30, step.stderr)  # said before the prompt (another pipe)
    assert step.stderr().rstrip().endswith("both drives stopped"), step.stderr()
    sim.call("apply_load", fx=0.0, fy=0.0)
    step.enter()
    assert step.ended(sim) == 0, step.stderr()
    assert sim.rpm() == (0.0, 0.0)
    assert len(step.prompts()) == LOADS + 1
    (new,) = sorted(set(p.name for p in records.iterdir()) - set(before))
    assert new.endswith("-loads.toml"), new
    assert "Traceback" not in step.stderr()


@pytest.mark.parametrize(
    "signals",
    [(signal.SIGINT,), (signal.SIGTERM,), (signal.SIGINT, signal.SIGINT, signal.SIGTERM)],
    ids=["ctrl-c", "sigterm", "ctrl-c-twice-and-sigterm"],
)
def test_a_signal_at_a_prompt_stops_the_drives_and_ends_without_asking_again(rig, signals):
    sim, records, calibrate = rig
    before = sorted(p.name for p in records.iterdir())
    step = calibrate()
    _apply(sim, step.wait_prompt(1))
    step.enter()
    prompt = step.wait_prompt(2)  # +x: the drives turn, the command waits for the operator
    assert _turning(sim) and "apply the static load fx = +500.0 N" in prompt, (sim.rpm(), prompt)
    for sig in signals:
        step.proc.send_signal(sig)
    code = step.ended(sim)
    err = step.stderr()
    assert code == 3, err
    assert sim.rpm() == (0.0, 0.0)
    assert len(step.prompts()) == 2, step.stdout()  # nobody asked anything more
    told = "both drives at standstill: remove every calibration load (the step did not complete)"
    # signals sent together may reach the command in another order (each thread can take one)
    first = {"Ctrl-C" if s == signal.SIGINT else s.name for s in signals}
    (end,) = re.findall(r"calibration stopped by (.+): the drives were stopped, no record written", err)
    assert end in first, err
    assert err.index("both drives stopped") < err.index(told) < err.index("calibration stopped by"), err
    assert "Traceback" not in err
    assert sorted(p.name for p in records.iterdir()) == before


def test_a_failed_acquisition_stops_the_drives_before_anything_is_asked(rig):
    sim, records, calibrate = rig
    before = sorted(p.name for p in records.iterdir())
    step = calibrate()
    _apply(sim, step.wait_prompt(1))
    step.enter()
    prompt = step.wait_prompt(2)
    assert _turning(sim), sim.rpm()
    sim.call("inject", fault="stall_clock")  # the board's clock frozen: no block at the slow roll
    _apply(sim, prompt)
    step.enter()
    code = step.ended(sim)
    err = step.stderr()
    assert code == 1, err
    assert sim.rpm() == (0.0, 0.0)
    assert len(step.prompts()) == 2, step.stdout()
    told = "both drives at standstill: remove every calibration load (the step did not complete)"
    assert err.index("acquisition failed") < err.index("both drives stopped") < err.index(told), err
    assert "error: no block at the slow roll" in err and "Traceback" not in err
    assert sorted(p.name for p in records.iterdir()) == before

"""`orbitrig calibrate` on the rig code path, the simulator in its own process (`orbitrig sim`)
behind a copy of the lab's rig.toml: the simulator (`Simulator`, its control API) and the command
at an operator's terminal (`Calibrate`, standard input a pipe the test writes Enter to)."""

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

from orbitrig.cli.simulated_rig import SimulatorLink
from support.rig_configs import lab_record_config
from support.cli_helpers import ended, orbitrig_started

PROMPT_END = "then press Enter: "
SPEEDUP = 10  # the simulator's time / wall time


def wait(condition, timeout: float, what) -> None:
    """Until `condition()` holds; AssertionError saying `what()` after `timeout` s."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, what()
        time.sleep(0.02)


class Simulator:
    """`orbitrig sim` in a process of its own: its endpoints and its control API."""

    def __init__(self) -> None:
        ports = ("--modbus-port", "0", "--adc-port", "0", "--can-port", "0")
        self.proc = orbitrig_started("sim", *ports, "--speedup", str(SPEEDUP), stderr=subprocess.DEVNULL)
        self.endpoints = json.loads(self.proc.stdout.readline())
        self.link = SimulatorLink(self.endpoints["control"])
        self.call = self.link.call  # the control API: cmd, fields -> its reply

    def rpm(self) -> tuple[float, float]:
        """Both drives' actual speeds now (rpm)."""
        st = self.call("state")
        return st["spin"] * 60 / (2 * math.pi), st["orbit"] * 60 / (2 * math.pi)

    def rig_config(self, folder: Path) -> Path:
        """A copy of the lab's rig.toml (and its records) whose transports are this simulator's.

        The command sees a rig (time scale 1) while the simulator runs SPEEDUP times faster: the
        lab's physical waits given in wall seconds (the hold after a load or a speed change, the
        acquisition timeout's margin) are divided by SPEEDUP, so that they are the lab's seconds of
        the simulator's time (hold 2 s -> 0.2 s wall: 2 s of the simulated rig). The acquisition
        timeout keeps its factor (3 blocks) and the command's own 2 s wall allowance."""
        ep = self.endpoints
        return lab_record_config(
            folder,
            edits={
                "adc_url": f"adc_url = {json.dumps(ep['adc'])}",
                "modbus_url": f"modbus_url = {json.dumps(ep['modbus'])}",
                "can_channel": f"can_channel = {json.dumps(ep['can'])}",
                "can_interface": 'can_interface = "serial"',
                "hold_s": f"hold_s = {2.0 / SPEEDUP:g}",
                "timeout_margin_s": f"timeout_margin_s = {2.0 / SPEEDUP:g}",
            },
        )

    def close(self) -> None:
        self.link.close()
        ended(self.proc, signal.SIGINT, 30)


LOADS_ARGS = ("loads", "--reference-id", "dead-weights", "--reference-u-pct", "0.1", "--revolutions", "5")


class Calibrate:
    """`orbitrig calibrate STEP --config RIG ...` (default: the loads step) at an operator's
    terminal: its prompts (standard output) and notes (standard error) collected as they come,
    Enter written on request."""

    def __init__(self, rig: Path, args: tuple[str, ...] = LOADS_ARGS):
        self.proc = orbitrig_started(
            "calibrate", args[0], "--config", str(rig), *args[1:], stdin=subprocess.PIPE, text=False
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
        wait(
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
        wait(
            lambda: self.proc.poll() is not None,
            timeout,
            lambda: f"still running, drives at {sim.rpm()} rpm, prompts {self.prompts()}:\n{self.stderr()}",
        )
        for r in self.readers:
            r.join(timeout=30)
        return self.proc.returncode

    def close(self) -> None:
        ended(self.proc)


MANUAL = re.compile(
    r"^both drives at standstill: set orbit radius 0 \u00b5m, static eccentricity 0, "
    r"recess pressure ([\d.]+) MPa, pressure ratio ([\d.]+) for the run without orbit"
)


def confirm_manual(sim: Simulator, step: Calibrate, orbit_radius: float = 0.0) -> str:
    """The operator at the first prompt, the slow roll's manual settings, both drives at standstill:
    the pressures it asks for set on the simulator, the orbit radius `orbit_radius` (m; 0: as asked,
    more: left from an earlier sweep), then Enter. The prompt."""
    prompt = step.wait_prompt(1)
    assert sim.rpm() == (0.0, 0.0), f"asked for the manual settings with the drives at {sim.rpm()} rpm"
    m = MANUAL.search(prompt)
    assert m, prompt
    sim.call(
        "set_manual",
        orbit_radius=orbit_radius,
        static_eccentricity=0.0,
        recess_pressure=float(m.group(1)) * 1e6,
        pressure_ratio=float(m.group(2)),
    )
    step.enter()
    return prompt

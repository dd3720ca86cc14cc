"""The simulator's process (`python -m sim`, sim/__main__.py) from its start to its end: the
command line and environment it starts with, the line that announces its endpoints, its end when
asked (standard input closed; SIGKILL after STOP_TIMEOUT), and its end when not asked (logged with
its exit status and last words). orbitrig/cli/simulated_rig.py builds the rig's access on it.
"""

from __future__ import annotations

import asyncio
import contextlib
import importlib.util
import json
import logging
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from orbitrig.errors import OrbitrigError

log = logging.getLogger(__name__)

#: wall seconds the simulator process may take to announce its endpoints (a loaded machine)
START_TIMEOUT = 120.0
#: the simulator's nice value relative to the application's: its drives, A/D board and CAN
#: node stand for machines with processors of their own, which the host's load never delays
#: (applied where permitted: root or CAP_SYS_NICE; otherwise it runs at the application's)
SIMULATOR_NICE = -10
#: wall seconds it may take to end after its standard input closed, before SIGKILL
STOP_TIMEOUT = 10.0


class SimulatorError(OrbitrigError):
    """The simulator process did not start, or its control API failed or refused a request."""


def start_simulator(speedup: float, config=None, can_node_id: int | None = None) -> SimulatorStart:
    """Start the simulator process now (it takes a second or more to import and listen);
    `simulated_rig(..., started=)` waits for it. Whoever starts it passes it on at once.
    `can_node_id`: its CAN node's node id (the rig.toml's [transports] can_node_id; None: the scenario's)."""
    return SimulatorStart(_command(speedup, config, can_node_id))


class SimulatorStart:
    """A `python -m sim` child from its start to its end: the ready line, the stop."""

    def __init__(self, command: list[str]):
        self.log = tempfile.TemporaryFile()  # its stderr: shown when it fails to start or ends unasked
        self.ending = False  # its end was asked (`end`): it is expected to exit
        try:
            self.proc = subprocess.Popen(
                command,
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=self.log,
                env=_environment(),
                start_new_session=True,
            )
        except OSError as err:
            self.log.close()
            raise SimulatorError(f"the simulator process could not start: {err}") from None
        stdin, stdout = self.proc.stdin, self.proc.stdout
        assert stdin is not None and stdout is not None  # both piped above
        self._stdin, self._stdout = stdin, stdout

    async def ready(self) -> dict:
        """Its endpoints, once it announces them; SimulatorError with its last word if it does not."""
        try:
            async with asyncio.timeout(START_TIMEOUT):  # a signal's cancel not lost as the simulator answers
                line = await asyncio.to_thread(self._stdout.readline)
            endpoints = json.loads(line) if line.startswith(b"{") else None
        except (asyncio.TimeoutError, ValueError):
            endpoints = None
        if endpoints is None:
            await self._ended()
            self.log.seek(0)
            said = self.log.read().decode(errors="replace").strip().splitlines()
            self.log.close()
            raise SimulatorError(
                "the simulator process did not start (python -m sim, exit status "
                f"{self.proc.returncode}){': ' + said[-1] if said else ''}"
            )
        return endpoints

    async def watch(self) -> None:
        """Wait for the process to exit; if its end was not asked, log its exit status and the last
        lines it wrote (a run then fails on its lost links: this says why)."""
        code = await asyncio.to_thread(self.proc.wait)
        if self.ending:
            return
        self.log.seek(0)
        said = self.log.read().decode(errors="replace").strip().splitlines()[-5:]
        log.error(
            "the simulator process (python -m sim, pid %d) ended unasked, exit status %s%s",
            self.proc.pid,
            code,
            "".join(f"\n  {line}" for line in said) if said else " (it wrote nothing)",
        )

    async def end(self) -> None:
        """Close its standard input (it ends itself cleanly); SIGKILL after STOP_TIMEOUT."""
        try:
            await self._ended()
        finally:
            self.log.close()

    async def _ended(self) -> None:
        self.ending = True
        self._stdin.close()
        try:
            await asyncio.to_thread(self.proc.wait, STOP_TIMEOUT)
        except subprocess.TimeoutExpired:
            self._kill()
            await asyncio.to_thread(self.proc.wait)
        except asyncio.CancelledError:
            self._kill()
            raise
        finally:
            self._stdout.close()

    def _kill(self) -> None:
        with contextlib.suppress(ProcessLookupError):
            self.proc.kill()


def _command(speedup: float, config, can_node_id: int | None) -> list[str]:
    args = [
        sys.executable,
        "-m",
        "sim",
        "--modbus-port",
        "0",
        "--adc-port",
        "0",
        "--no-adc-pty",
        "--control-port",
        "0",
        "--can-hub",
        "0",
        "--speedup",
        repr(float(speedup)),
        "--nice",
        str(SIMULATOR_NICE),
        "--parent-pid",
        str(os.getpid()),
    ]
    if can_node_id is not None:
        args += ["--can-node-id", str(can_node_id)]
    if config is not None:
        from sim.scenario_files import sim_config_to_data

        args += ["--config-json", json.dumps(sim_config_to_data(config))]
    return args


def _environment() -> dict:
    """This environment, with the `sim` package this process would import first on the path."""
    spec = importlib.util.find_spec("sim")
    if spec is None or spec.origin is None:
        raise SimulatorError("the simulator package `sim` cannot be imported (installed with orbitrig)")
    root = str(Path(spec.origin).resolve().parents[1])
    path = os.environ.get("PYTHONPATH", "")
    return dict(os.environ, PYTHONPATH=root + (os.pathsep + path if path else ""))

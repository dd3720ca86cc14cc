"""Shared helpers of the sweep tests: small matrices and a run on the real simulator."""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import signal
import time
from pathlib import Path

from orbitrig import config as cfg
from support.cli_helpers import reaped, started
from support.paths import ROOT
from support.rig_configs import patient_rig

SPEEDUP = 40.0


def demo_text(name: str, revolutions: int | None = None) -> str:
    """The shipped demo matrix's text named ``name``, with ``revolutions`` per block (None: its own)."""
    text = (ROOT / "config" / "matrices" / "demo.toml").read_text()
    top = f'name = "{name}"' + ("" if revolutions is None else f"\nrevolutions = {revolutions}")
    return text.replace('name = "demo"', top)


def small_matrix(revolutions: int = 10, **operating) -> cfg.MatrixConfig:
    """The demo matrix with fewer revolutions per block (and other operating values)."""
    text = demo_text("small", revolutions)
    for key, values in operating.items():
        lines = [ln for ln in text.splitlines() if ln.startswith(f"{key} =")]
        text = text.replace(lines[0], f"{key} = {values!r}")
    return cfg.matrix_from_text(text, "small.toml")


def stop_after_first_point(cmd: list[str], out: Path, env: dict[str, str] | None = None) -> None:
    """Run the sweep ``cmd`` (writing to ``out``; ``env`` added to the environment) in a subprocess
    and stop it by SIGTERM once a point is complete: it must end stopped (exit 3)."""
    with reaped(started(cmd, env=env, stdin=None, stdout=None, text=False)) as proc:
        deadline = time.monotonic() + 120
        while not list(out.glob("points/*/complete.json")):
            assert proc.poll() is None and time.monotonic() < deadline, "no point completed"
            time.sleep(0.05)
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(60) == 3


def first_stop(sim, since: float, words: tuple[int, ...]) -> float | None:
    """s from `since` (monotonic, the simulator's clock too) to the spin drive's first control word
    of `words` (the tests spell the spec's words out themselves), None before one."""
    return min((t - since for t, cw in sim.drive(1)["control_words"] if t >= since and cw in words), default=None)


async def wait_for(predicate, timeout: float = 30.0, what: str = "condition") -> None:
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while not predicate():
        if loop.time() > end:
            raise AssertionError(f"timed out waiting for {what}")
        await asyncio.sleep(0.01)


class Recorder:
    def __init__(self):
        self.events = []

    def __call__(self, ev):
        self.events.append(ev)

    def states(self):
        from orbitrig.run.engine import StatusEvent

        return [e.state for e in self.events if isinstance(e, StatusEvent)]

    def blocks_done(self):
        """Blocks started so far (ProgressEvent.frequency of the latest event)."""
        from orbitrig.run.engine import ProgressEvent

        prog = [e for e in self.events if isinstance(e, ProgressEvent)]
        return prog[-1].frequency if prog else 0


class SimulatorView:
    """The simulator process as the sweep tests look into it: through its control API
    (docs/protocols/sim-control.md), speeds rad/s, drive speeds rpm."""

    def __init__(self, sim):
        self.link = sim.link
        self.last: dict | None = None  # after the simulator ended: its state and drives then

    def freeze(self) -> None:
        """Keep what the simulator says now; the view answers with it once the process is gone."""
        self.last = {"state": self.link.call("state"), "drives": self.link.call("drives")}

    def _ask(self, cmd: str) -> dict:
        return self.last[cmd] if self.last is not None else self.link.call(cmd)

    @property
    def speeds(self) -> tuple[float, float]:
        state = self._ask("state")
        return state["spin"], state["orbit"]

    def inject(self, fault: str, **kw) -> None:
        self.link.call("inject", fault=fault, **kw)

    def set_manual(self, **settings) -> None:
        self.link.call("set_manual", **settings)

    def drive(self, device: int) -> dict:
        """Drive `device` now: state, rpm, fault, control_word (the one it holds), control_words."""
        return self._ask("drives")["drives"][str(device)]


@contextlib.asynccontextmanager
async def running(tmp_path, matrix, rig=None, speedup=SPEEDUP, modbus=None, **engine_kw):
    """The simulator (its own process, as `sweep --sim` runs it) and a RunEngine running `matrix`
    on `rig` (default support.rig_configs.patient_rig(); a test of the link gives config/rig.toml's own) in a task:
    yields (SimulatorView, engine, recorder, run task). `modbus`: an async function of the
    simulator's Modbus URL giving the one the engine reaches the drives at (a path in between)."""
    from orbitrig.cli.simulated_rig import simulated_rig
    from orbitrig.run.engine import RunEngine

    async with simulated_rig(speedup) as (sim, access):
        if modbus is not None:
            url = await modbus(access.endpoints.modbus_url)
            access = dataclasses.replace(access, endpoints=dataclasses.replace(access.endpoints, modbus_url=url))
        engine_kw.setdefault("confirm_mode", "auto")
        eng = RunEngine(rig or patient_rig(), out_dir=tmp_path / "run", access=access, **engine_kw)
        rec = Recorder()
        eng.subscribe(rec)
        run = asyncio.create_task(eng.run(matrix))
        view = SimulatorView(sim)
        try:
            yield view, eng, rec, run
        finally:
            if not run.done():
                run.cancel()
                await asyncio.gather(run, return_exceptions=True)
            view.freeze()

"""Shared helpers of the sweep tests: small matrices and a run on the real simulator."""

from __future__ import annotations

import asyncio
import contextlib
import sys
from pathlib import Path

from orbitrig import config as cfg

ROOT = Path(__file__).resolve().parents[2]
SPEEDUP = 40.0


def small_matrix(revolutions: int = 10, **operating) -> cfg.MatrixConfig:
    """The demo matrix with fewer revolutions per block (and other operating values)."""
    text = cfg.default_matrix_path("demo").read_text()
    text = text.replace('name = "demo"', f'name = "small"\nrevolutions = {revolutions}')
    for key, values in operating.items():
        lines = [ln for ln in text.splitlines() if ln.startswith(f"{key} =")]
        text = text.replace(lines[0], f"{key} = {values!r}")
    return cfg.matrix_from_text(text, "small.toml")


def orbitrig_cmd(*args: str) -> list[str]:
    return [sys.executable, "-m", "orbitrig", *args]


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


@contextlib.asynccontextmanager
async def running(tmp_path, matrix, rig=None, speedup=SPEEDUP, **engine_kw):
    """A SimRig and a RunEngine running `matrix` on `rig` (default config/rig.toml) in a task:
    yields (sim, engine, recorder, run task)."""
    from orbitrig.cli.simulated_rig import simulated_access
    from orbitrig.run.engine import RunEngine
    from sim.rig import SimRig

    async with SimRig(speedup=speedup, adc_pty=False) as sim:
        engine_kw.setdefault("confirm_mode", "auto")
        eng = RunEngine(rig or cfg.load_rig(), out_dir=tmp_path / "run", access=simulated_access(sim), **engine_kw)
        rec = Recorder()
        eng.subscribe(rec)
        run = asyncio.create_task(eng.run(matrix))
        try:
            yield sim, eng, rec, run
        finally:
            if not run.done():
                run.cancel()
                await asyncio.gather(run, return_exceptions=True)

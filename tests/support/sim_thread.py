"""The simulator's rig served from an event loop of its own in a thread, for an `orbitrig`
command run in the test's thread (typer's runner: its own `asyncio.run`)."""

from __future__ import annotations

import asyncio
import math
import threading
from contextlib import contextmanager

from sim.scenario_files import scenario
from sim.rig import SimRig

ORBIT = 2 * math.pi * 12.5  # rad/s


@contextmanager
def sim_in_thread(orbit: float = ORBIT):
    """The simulator on its own event loop in a thread (the CLI runs asyncio.run here): its A/D
    board's URL; the spin at 150 rad/s, the orbit at `orbit` (rad/s, 0: the board sends no frames)."""
    ready, stop = threading.Event(), None
    box: dict = {}

    async def serve():
        nonlocal stop
        stop = asyncio.Event()
        async with SimRig(scenario("clean"), speedup=20.0, can_channel=None) as r:  # exact phasors, low noise
            r.local_control(spin=150.0, orbit=orbit)
            await asyncio.sleep(0.05)
            box["url"], box["loop"] = r.adc_url, asyncio.get_running_loop()
            ready.set()
            await stop.wait()

    t = threading.Thread(target=asyncio.run, args=(serve(),), daemon=True)
    t.start()
    assert ready.wait(20)
    try:
        yield box["url"]
    finally:
        box["loop"].call_soon_threadsafe(stop.set)
        t.join(20)

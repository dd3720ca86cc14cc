"""A sweep in auto mode whose verify stage fails (the manual settings the probes measure not met:
nobody to correct them) fails the run with both drives stopped first, storage second: the ramp's
standstill is in run.log before the run's end, and both drives read 0 rpm when the run returns.
The static eccentricity is verified with the drives turning (the failure meets them at speed); a
missed orbit radius stops them for the hands on the spindle before the run fails.

Real parts: the simulator in its own process (as `sweep --sim` runs it) and a RunEngine; the
simulator's own hands make the settings, off by what an operator's slip would make them."""

import asyncio
import dataclasses
import re

import pytest

from orbitrig.run.engine import RunEngine
from support.rig_configs import patient_rig
from support.sweep_helpers import SPEEDUP, SimulatorView, first_stop, small_matrix

pytestmark = pytest.mark.timeout(120)

STOP_WORDS = (0x047E, 0x047B)  # spec control words (OFF1, OFF3), written out on purpose
RADIUS_STOP = "for the orbit radius, set by hand: both drives ramped to zero"  # run.log, before a radius is set


class Slipped:
    """The simulator's hands, one setting off: `key` set to `value` (SI) whatever the point asks."""

    def __init__(self, hands, key: str, value: float):
        self.hands, self.key, self.value = hands, key, value

    async def set_manual(self, **settings: float) -> None:
        await self.hands.set_manual(**{**settings, self.key: self.value})


@pytest.mark.parametrize(
    "key, value, said",
    [
        ("static_eccentricity", 0.3, r"static eccentricity 0\.(2[89]|3[01])\d, want 0 \+/- 0\.05$"),
        ("orbit_radius", 4e-6, r"orbit radius (3\.[5-9]|4\.[0-4])\d µm, want 5\.76 µm \+/- 15 %$"),
    ],
    ids=["eccentricity-at-speed", "radius"],
)
async def test_a_verify_that_fails_in_auto_mode_stops_both_drives_before_the_run_ends(tmp_path, key, value, said):
    from orbitrig.cli.simulated_rig import simulated_rig

    async with simulated_rig(SPEEDUP) as (sim, access):
        access = dataclasses.replace(access, hands=Slipped(access.hands, key, value))
        eng = RunEngine(patient_rig(), out_dir=tmp_path / "run", access=access, confirm_mode="auto")
        run = asyncio.create_task(eng.run(small_matrix(revolutions=6)))
        view = SimulatorView(sim)
        try:
            outcome = await asyncio.wait_for(asyncio.shield(run), 90)
            drives = view.drive(1), view.drive(2)
            stopped = first_stop(view, 0.0, STOP_WORDS)
        finally:
            if not run.done():
                run.cancel()
                await asyncio.gather(run, return_exceptions=True)
    assert outcome.status == "failed", outcome.message
    assert outcome.message.startswith("point 0000: manual settings not met: "), outcome.message
    assert re.search(said, outcome.message), outcome.message
    assert stopped is not None and [d["rpm"] for d in drives] == [0, 0], drives
    log = (tmp_path / "run" / "run.log").read_text().splitlines()
    standstill = max(i for i, line in enumerate(log) if "drives:" in line and "standstill" in line)
    assert standstill < len(log) - 1 and outcome.message in log[-1], log[-5:]
    at_speed = not any(RADIUS_STOP in line for line in log)  # the drives turned as the verify failed
    assert at_speed is (key == "static_eccentricity"), log

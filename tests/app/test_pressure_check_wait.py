"""The pressure check before the spindles start waits for a CAN reading received after it began,
and takes it within `LOOK_S` of its arrival, or as it arrives when it is given the node's
`arrival` event (a sweep's check): it used to look every 0.1 s, so a frame arriving just after a
look waited up to 0.1 s more (at every point of a sweep)."""

from __future__ import annotations

import asyncio
import time

import pytest

from daq.aux import AuxState
from orbitrig.config import MPA, Verify
from orbitrig.run.rig_io import TimeScale
from orbitrig.run.steps import SetManual
from orbitrig.run.verification import LOOK_S, pressures_settled

pytestmark = pytest.mark.timeout(30)

SETTINGS = SetManual(0, 0.0, 0.0, 0.0, 0.4826 * MPA, 0.25, changed=True)
FRAME_AFTER = 0.03  # wall s after the check began that the first new frame arrives


def _node(t0: float):
    """The CAN node's readings: the settings met, the last frame received at t0 - 0.05 s, then at
    t0 + FRAME_AFTER (`latest` is the seam calibration's check uses too)."""

    def latest() -> AuxState:
        now = time.monotonic()
        arrived = t0 + FRAME_AFTER if now >= t0 + FRAME_AFTER else t0 - 0.05
        age = now - arrived
        p = SETTINGS.recess_pressure
        ages = {"p_recess": age, "p_supply": age, "beta": age}
        return AuxState(p_supply=p / 0.25, p_recess=(p,) * 4, beta=0.25, node_lost=False, ages=ages, heartbeat_age=age)

    return latest


async def test_the_first_frame_after_the_check_began_is_taken_at_once():
    took = []
    for _ in range(5):
        t0 = time.monotonic()
        problems = await pressures_settled(_node(t0), SETTINGS, Verify(), TimeScale(25.0))
        took.append(time.monotonic() - t0)
        assert problems == []
        await asyncio.sleep(0.01)
    assert min(took) >= FRAME_AFTER  # not the frame from before the check
    assert sorted(took)[2] < FRAME_AFTER + LOOK_S + 0.03, took  # not the 0.1 s look it had


async def test_with_the_arrival_event_the_frame_is_taken_as_it_arrives():
    """The frame at FRAME_AFTER sets the event the check waits on (AuxSensors.arrival): taken
    then, not up to LOOK_S later, and without looking every LOOK_S meanwhile."""
    took, looks = [], []
    for _ in range(5):
        t0 = time.monotonic()
        latest, event = _node(t0), asyncio.Event()
        asyncio.get_running_loop().call_later(FRAME_AFTER, event.set)

        def counted(latest=latest) -> AuxState:
            looks.append(1)
            return latest()

        problems = await pressures_settled(counted, SETTINGS, Verify(), TimeScale(25.0), arrival=lambda e=event: e)
        took.append(time.monotonic() - t0)
        assert problems == []
    assert min(took) >= FRAME_AFTER
    assert sorted(took)[2] < FRAME_AFTER + 0.02, took
    assert len(looks) <= 2 * 5  # one look as the check begins, one as the frame arrives

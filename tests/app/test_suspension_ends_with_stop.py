"""A stop asked as the interlock that suspends the run clears (both in the same turn of the event
loop: the supervisor's sample and an MQTT stop) ends the run as a stop asked during the
suspension does: StopRun at the suspension's end, the state stopping (the drives then ramp to
zero), never a failure of the run's state table (which ended the run failed, with the emergency
stop). Pure: the run's control and a supervisor holding the trip in force."""

from __future__ import annotations

import asyncio

import pytest

from orbitrig.run.control import RunControl, StopRun
from orbitrig.run.interlocks import SUSPEND, Trip, TripKind
from orbitrig.run.states import PAUSED, RUNNING, STOPPING

PUMP = Trip(TripKind.SUPPLY_PUMP, SUSPEND, "lubricant supply pump is off")


class Supervisor:
    """The InterlockSupervisor's face the run control reads: the trip in force and `clear`."""

    def __init__(self, trip: Trip):
        self.trip: Trip | None = trip
        self.clear = asyncio.Event()


@pytest.mark.parametrize("stop_first", [False, True])
async def test_a_stop_as_the_interlock_clears_ends_the_suspension_with_the_stop(stop_first):
    control = RunControl(lambda state, message: None, lambda note: None)
    control.state = RUNNING
    sup = Supervisor(PUMP)
    held = asyncio.create_task(control.hold_while_suspended(sup, limit=60.0))
    await asyncio.sleep(0.05)
    assert control.state == PAUSED
    if stop_first:
        control.request_stop("ada")
    sup.trip = None  # the supervisor's sample: the pump back on
    sup.clear.set()
    if not stop_first:
        control.request_stop("ada")
    with pytest.raises(StopRun):
        await asyncio.wait_for(held, 5.0)
    assert control.state == STOPPING and control.suspension is None


async def test_an_abort_as_the_interlock_clears_ends_the_suspension_cancelled():
    control = RunControl(lambda state, message: None, lambda note: None)
    control.state = RUNNING
    sup = Supervisor(PUMP)
    held = asyncio.create_task(control.hold_while_suspended(sup, limit=60.0))
    await asyncio.sleep(0.05)
    sup.trip = None
    sup.clear.set()
    control.request_abort()  # (its cancel of the run's body lost: the suspension's end honours it)
    with pytest.raises(asyncio.CancelledError):
        await asyncio.wait_for(held, 5.0)
    assert control.state == STOPPING

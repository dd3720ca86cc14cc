"""A suspension whose cause changes while it is in force says so in the run's events.

The CAN node sends the supply pressure and the pump status in separate frames, so when the pump
stops either may trip first: the suspension names the first, and once the other cause comes first
in the check (the pump ahead of the low pressure it causes) the run's events note it, a warning
(the sweep's console shows it), once per change of cause (not per new pressure reading). The failure after the limit names the cause in
force then. Pure: the run's control and a supervisor holding the trip in force."""

from __future__ import annotations

import asyncio

import pytest

from orbitrig.run.control import RunControl
from orbitrig.run.suspension import RECHECK_S
from orbitrig.run.events import RunFailed, Severity
from orbitrig.run.interlocks import SUSPEND, Trip, TripKind
from orbitrig.run.states import RUNNING


class Supervisor:
    """The InterlockSupervisor's face the run control reads: the trip in force and `clear`."""

    def __init__(self, trip: Trip):
        self.trip: Trip | None = trip
        self.clear = asyncio.Event()


def low(mpa: float) -> Trip:
    return Trip(TripKind.SUPPLY_LOW, SUSPEND, f"supply pressure {mpa:.3f} MPa outside the band 0.2..8 MPa")


PUMP = Trip(TripKind.SUPPLY_PUMP, SUSPEND, "lubricant supply pump is off")


def _control(notes: list[tuple[str, Severity]]) -> RunControl:
    control = RunControl(
        lambda state, message: None,
        lambda message, severity=Severity.INFO, kind=None: notes.append((message, severity)),
    )
    control.state = RUNNING
    return control


async def test_a_new_cause_is_noted_once_and_the_clearing_ends_the_suspension():
    notes: list[tuple[str, Severity]] = []
    control, sup = _control(notes), Supervisor(low(0.150))
    held = asyncio.create_task(control.hold_while_suspended(sup, limit=60.0))
    await asyncio.sleep(0.05)
    assert control.message == "suspended by interlock: supply pressure 0.150 MPa outside the band 0.2..8 MPa"
    sup.trip = low(0.010)  # the same cause, another reading: nothing noted
    await asyncio.sleep(2.5 * RECHECK_S)
    assert notes == []
    sup.trip = PUMP
    await asyncio.sleep(2.5 * RECHECK_S)
    assert notes == [("still suspended by interlock: lubricant supply pump is off", Severity.WARNING)]
    sup.trip = None
    sup.clear.set()
    await asyncio.wait_for(held, 5)
    assert control.suspension is None


async def test_the_failure_after_the_limit_names_the_cause_in_force_then():
    control, sup = _control([]), Supervisor(low(0.0))
    held = asyncio.create_task(control.hold_while_suspended(sup, limit=1.0))
    await asyncio.sleep(0.1)
    sup.trip = PUMP
    with pytest.raises(RunFailed, match=r"^interlock: lubricant supply pump is off for more than 1 s$"):
        await asyncio.wait_for(held, 10)

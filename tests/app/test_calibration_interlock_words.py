"""How a calibration step words the interlock that ends it (CalibrationChecks.check_interlocks): the
supply's own trips (SUPPLY_KINDS: the pump off, the supply below its minimum) as the lubricant supply
lost; a suspension of any other kind, which a calibration step does not expect (the supply above the
band, armed only at a sweep's point), as the interlock it is, never as supply loss. (The supervisor's
`trip` is always one interlocks.check found: the stand-in of a suspension whose cause is no longer
known, TripKind.INTERLOCK, is interlock_guard's, which a calibration step does not use.)

Real parts: the run's InterlockSupervisor sampling the CAN node's state as daq.aux reads it (AuxState)
with the shipped rig.toml's interlocks; the checks of the calibration session without its rig (no
drive turning: nothing said of a slow roll)."""

from __future__ import annotations

import pytest

from daq.aux import HEARTBEAT_OPERATIONAL, AuxState
from orbitrig.config import MPA, RigConfig, load_rig
from orbitrig.run.calibration_checks import CalibrationChecks, CalibrationFailed
from orbitrig.run.interlocks import SUPPLY_KINDS, Trip, TripKind
from orbitrig.run.supervision import InterlockSupervisor


class _Checks(CalibrationChecks):
    """The calibration session's checks on `rig` with `supervisor` as its interlocks, at standstill."""

    def __init__(self, rig: RigConfig, supervisor: InterlockSupervisor) -> None:
        self.rig, self.interlocks = rig, supervisor
        self.roll_spec, self.at_standstill, self.commanded = None, True, False


def _held(p_supply_mpa: float, *, pump_off: bool = False, armed: bool = False) -> tuple[Trip | None, str]:
    """(the suspension in force, check_interlocks' message) with the CAN node operational and fresh,
    reading `p_supply_mpa` MPa; `armed`: the supply band's upper edge watched (a sweep's verified point)."""
    rig = load_rig()
    aux = AuxState(
        p_supply=p_supply_mpa * MPA,
        pump_off=pump_off,
        heartbeat_state=HEARTBEAT_OPERATIONAL,
        heartbeat_age=0.1,
        node_lost=False,
        ages={"p_supply": 0.1, "pump_off": 0.1},
    )
    supervisor = InterlockSupervisor(lambda: (aux, None), rig.interlocks, lambda trip: None)
    supervisor.pressure_armed = armed
    supervisor.sample()
    with pytest.raises(CalibrationFailed) as failed:
        _Checks(rig, supervisor).check_interlocks()
    return supervisor.trip, str(failed.value)


def test_the_supply_lost_is_worded_as_the_lubricant_supply():
    assert load_rig().interlocks.supply_pressure_min_mpa == 0.2 and SUPPLY_KINDS == {
        TripKind.SUPPLY_PUMP,
        TripKind.SUPPLY_LOW,
    }
    trip, message = _held(0.1, armed=True)
    assert trip is not None and trip.kind is TripKind.SUPPLY_LOW
    assert message == (
        "interlock: supply pressure 0.100 MPa outside the band 0.2..8 MPa: no calibration without the lubricant supply"
    )
    trip, message = _held(3.0, pump_off=True, armed=True)
    assert trip is not None and trip.kind is TripKind.SUPPLY_PUMP
    assert message == "interlock: lubricant supply pump is off: no calibration without the lubricant supply"


def test_a_suspension_of_another_kind_is_worded_as_the_interlock_not_as_supply_loss():
    """Before, every held trip that was not the CAN node's said 'no calibration without the
    lubricant supply', a supply above its band too."""
    trip, message = _held(9.5, armed=True)
    assert trip is not None and trip.kind is TripKind.SUPPLY_HIGH
    assert message == (
        "interlock: supply pressure 9.500 MPa outside the band 0.2..8 MPa: "
        "no calibration while an interlock holds the rig (supply_pressure)"
    )
    assert "lubricant supply" not in message


def test_nothing_held_nothing_raised():
    rig = load_rig()
    supervisor = InterlockSupervisor(lambda: (AuxState(node_lost=False), None), rig.interlocks, lambda trip: None)
    supervisor.sample()  # at standstill, not armed: the supply is not watched
    assert supervisor.trip is None and supervisor.failure is None
    _Checks(rig, supervisor).check_interlocks()

"""How a run ends when a drive tripped during its closing stop (orbitrig.run.safe_stop): a completed
or stopped run fails, saying so first; an aborted run stays aborted and a failed run keeps its
own failure first, the trip added; a trip with the standstill not confirmed is a stop not
confirmed. The rules alone (the run on the simulator: test_closing_trip_run.py), with the error
RigDrives.stop raises built from the drive statuses it reads."""

from __future__ import annotations

import pytest

from drives import registers as R
from drives.drive import DriveStatus
from drives.rig import StopTripError
from orbitrig.run.safe_stop import not_confirmed, tripped_in_closing_stop, unconfirmed
from orbitrig.run.states import ABORTED, COMPLETED, FAILED, STOPPED

SPIN_TRIPPED = DriveStatus("spin", 1, R.CW_RAMP_STOP, 0.0, int(R.SWBit.TRIPPED), 0.0, 0.0, 2310, 1.0)
ORBIT_TRIPPED = DriveStatus("orbit", 2, R.CW_RAMP_STOP, 0.0, int(R.SWBit.TRIPPED), 0.0, 0.0, 7510, 1.0)
HEAD = "drive tripped during the closing stop (fault 2310, standstill confirmed): spin drive (id 1)"


def _trip(*tripped: DriveStatus, standstill: bool = True) -> StopTripError:
    return StopTripError(tripped, stop="ramp stop (OFF1)", standstill=standstill, end="not at zero speed within 5 s")


@pytest.mark.parametrize("status", [COMPLETED, STOPPED])
def test_closing_trip_fails_a_completed_or_stopped_run(status):
    got, message = tripped_in_closing_stop(status, "all points completed", _trip(SPIN_TRIPPED), aborting=False)
    assert got is FAILED
    assert message.startswith(HEAD), message
    assert "tripped during the ramp stop (OFF1); both drives at standstill" in message
    assert message.endswith(f"(the run was ending {status}: all points completed)")


def test_closing_trip_of_an_aborted_or_failed_run_keeps_its_status_and_adds_the_trip():
    trip = _trip(SPIN_TRIPPED, ORBIT_TRIPPED)
    for status, aborting, message in (
        (ABORTED, True, "aborted by ada"),
        (STOPPED, True, "stopped by bob"),  # an abort during the ramp: the engine makes it aborted
        (FAILED, False, "storage failed: disk full"),
    ):
        got, said = tripped_in_closing_stop(status, message, trip, aborting=aborting)
        assert got is status
        assert said.startswith(f"{message}; drive tripped during the closing stop (faults 2310, 7510, standstill")
        assert "orbit drive (id 2) tripped too (fault 7510)" in said


def test_closing_trip_without_standstill_is_a_stop_not_confirmed():
    trip = _trip(SPIN_TRIPPED, standstill=False)
    status, message = unconfirmed(COMPLETED, "all points completed", trip)
    assert status is FAILED
    assert message.startswith("drives not confirmed stopped: StopTripError: spin drive (id 1)"), message
    assert "not at zero speed within 5 s" in message
    # a step (calibration) or `drives run` that stopped the drives says a trip at standstill as such
    assert not_confirmed(_trip(SPIN_TRIPPED)).startswith("drive tripped during the stop (fault 2310, standstill")

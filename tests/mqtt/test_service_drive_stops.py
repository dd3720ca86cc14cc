"""The rig service's command side split along its seam: the stops of both drives that no run
carries out (a stop or abort with no run holding the drives, the first shutdown signal) are
orbitrig.service.drive_stops' alone; orbitrig.service.commands validates, carries out and answers
each command and reaches those stops through it (one owner each, both under the 400-line bound
with room to grow)."""

from __future__ import annotations

import inspect

from orbitrig.service import commands, drive_stops
from orbitrig.service.rig_service import RigService

STOPS = ("stop_idle_drives", "idle_stops", "stop_drives_on_signal", "settle_signal_stop", "run_active")


def test_the_stops_no_run_carries_out_are_drive_stops_alone():
    for name in STOPS:
        assert name in vars(drive_stops.DriveStopping), name
        assert name not in vars(commands.CommandHandling), name
    assert issubclass(RigService, drive_stops.DriveStopping)
    assert "emergency_within" not in inspect.getsource(commands)  # the OFF3-again rule is decided there only


def test_both_modules_have_room_under_the_bound():
    for module in (commands, drive_stops):
        lines = len(inspect.getsource(module).splitlines())
        assert lines <= 350, (module.__name__, lines)

"""The calibration session split along its seam: what ends a step while the drives turn (the drives'
poll, the interlocks, `watched`, and `CalibrationFailed` itself) is orbitrig.run.calibration_checks'
alone; orbitrig.run.calibration opens the rig, sets the slow roll, averages and stops the drives
(one owner each, both under the 400-line bound with room to grow)."""

from __future__ import annotations

import inspect

from orbitrig.run import calibration, calibration_checks

CHECKS = ("check_drives", "check_interlocks", "watched")


def test_what_ends_a_step_is_calibration_checks_alone():
    for name in CHECKS:
        assert name in vars(calibration_checks.CalibrationChecks), name
        assert name not in vars(calibration.CalibrationSession), name
    assert issubclass(calibration.CalibrationSession, calibration_checks.CalibrationChecks)
    assert calibration_checks.CalibrationFailed.__module__ == "orbitrig.run.calibration_checks"


def test_both_modules_have_room_under_the_bound():
    for module in (calibration, calibration_checks):
        lines = len(inspect.getsource(module).splitlines())
        assert lines <= 350, (module.__name__, lines)

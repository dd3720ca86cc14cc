"""The pure parts of drives/: register map, scaling, limits, settle, errors, URLs."""

from __future__ import annotations

import math

import pytest

from drives import registers as R
from drives.poll_pace import SettleDetector
from drives.errors import (
    DriveError,
    DriveExceptionResponse,
    DriveFaultError,
    DriveLimitError,
    DriveLinkError,
    DriveTimeoutError,
)
from drives.link import parse_modbus_url
from drives.limits import DriveLimits
from rigerrors import OrbitrigError

RPM = 2 * math.pi / 60


def test_control_words_are_the_specs_typical_words():
    assert (R.CW_READY, R.CW_RUN, R.CW_RAMP_STOP, R.CW_EMERGENCY_STOP, R.CW_RESET) == (
        0x0476,
        0x047F,
        0x047E,
        0x047B,
        0x04F6,
    )


def test_reference_scaling_and_twos_complement():
    assert R.rpm_to_ref(3000, 3000) == 20000
    assert R.rpm_to_ref(-1500, 3000) == -10000
    assert R.to_word(-10000) == 0xD8F0
    assert R.from_word(0xD8F0) == -10000
    assert R.ref_to_rpm(R.rpm_to_ref(1234.5, 6000), 6000) == pytest.approx(1234.5, abs=0.15)
    with pytest.raises(ValueError):
        R.rpm_to_ref(5000, 3000)  # 33333 does not fit int16
    with pytest.raises(ValueError):
        R.rpm_to_ref(math.nan, 3000)


def test_state_names_from_status_word():
    assert R.state_name(0x0000) == "switch-on inhibited"
    assert R.state_name(0x0231) == "ready to switch on"
    assert R.state_name(0x0337) == "running"
    assert R.state_name(0x0238) == "fault"
    assert R.state_name(0x0210) == "emergency stop"


def test_errors_name_drive_register_and_fault():
    err = DriveFaultError("tripped", drive=1, drive_name="spin", register=R.FAULT, fault_code=2310)
    assert str(err) == "spin drive (id 1), register FAULT (6), fault 2310 (overcurrent): tripped"
    assert (err.drive, err.register, err.fault_code) == (1, 6, 2310)
    exc = DriveExceptionResponse("write refused", exception_code=3, drive=2, drive_name="orbit", register=R.ACCEL_TIME)
    assert exc.exception_code == 3
    assert "orbit drive (id 2)" in str(exc) and "ACCEL_TIME (102)" in str(exc)
    assert "exception 03 (illegal data value)" in str(exc)
    for cls in (DriveFaultError, DriveLimitError, DriveLinkError, DriveTimeoutError):
        assert issubclass(cls, DriveError) and issubclass(cls, OrbitrigError)
    assert issubclass(DriveTimeoutError, TimeoutError)


def test_modbus_urls():
    a = parse_modbus_url("tcp://127.0.0.1:5020")
    assert (a.kind, a.host, a.port) == ("tcp", "127.0.0.1", 5020)
    assert parse_modbus_url("tcp://rig-drives").port == 502
    r = parse_modbus_url("rtu:///dev/ttyS0?baud=9600")
    assert (r.kind, r.path, r.baud) == ("rtu", "/dev/ttyS0", 9600)
    assert parse_modbus_url("rtu:///dev/pts/3").baud == 19200
    for bad in ("udp://x:1", "rtu://host/dev/ttyS0", "rtu:///dev/ttyS0?parity=E", "tcp://:5"):
        with pytest.raises(DriveLinkError, match="bad Modbus URL"):
            parse_modbus_url(bad)


def test_limits():
    lim = DriveLimits(max_spin=200.0, max_orbit=100.0, min_ratio=0.1, max_ratio=1.0)
    lim.check(150.0, -100.0)
    lim.check(150.0, 15.0)
    lim.check(0.0, 0.0)
    lim.check(150.0, 0.0)  # orbit spindle still: no ratio to keep
    with pytest.raises(DriveLimitError, match=r"spin drive \(id 1\).*max_spin"):
        lim.check(200.1, 50.0)
    with pytest.raises(DriveLimitError, match=r"orbit drive \(id 2\).*max_orbit"):
        lim.check(150.0, -100.5)
    with pytest.raises(DriveLimitError, match="one way only"):
        lim.check(-1.0, 0.0)
    with pytest.raises(DriveLimitError, match=r"\|Omega\|/omega = 1\.2"):
        lim.check(50.0, -60.0)
    with pytest.raises(DriveLimitError, match="outside the allowed range"):
        lim.check(100.0, 5.0)
    with pytest.raises(DriveLimitError):
        lim.check(0.0, 10.0)
    DriveLimits(math.inf, math.inf).check(0.0, 10.0)  # no ratio bound
    with pytest.raises(ValueError, match="max_orbit"):
        DriveLimits(100.0, -1.0)
    with pytest.raises(ValueError, match="min_ratio"):
        DriveLimits(100.0, 100.0, min_ratio=2.0, max_ratio=1.0)


def test_settle_detector_needs_an_unbroken_hold():
    s = SettleDetector(0.5)
    assert s.settles_at is None
    assert not s.update(True, 0.0)
    assert s.settles_at == 0.5
    assert not s.update(True, 0.4)
    assert not s.update(False, 0.45)
    assert s.settles_at is None
    assert not s.update(True, 0.5)
    assert s.settles_at == 1.0
    assert not s.update(True, 0.9)
    assert s.update(True, 1.0)


def test_require_link_passes_a_good_poll_and_names_a_lost_link():
    """One wording of a lost link for the run's interlock, a calibration step and `drives run --hold`."""
    from drives.state import RigDriveState

    ok = RigDriveState(None, None, link_ok=True)
    assert ok.require_link() is ok
    lost = RigDriveState(None, None, link_ok=False, link_error="no answer within 0.25 s on tcp://127.0.0.1:5020")
    with pytest.raises(DriveLinkError, match=r"^Modbus link to the drives lost \(no answer within 0\.25 s on tcp"):
        lost.require_link()

"""Which differences a rig configuration given again on `sweep --resume --config` may have
(orbitrig.config.resume): the devices' addresses and the planning times, nothing a stored
number depends on (adc_mode, a channel's gain, the calibration record's text)."""

from __future__ import annotations

import pytest

from orbitrig import config as cfg

STORED = cfg.load_rig(cfg.shipped_config() / "rig.toml")


def _edited(old: str, new: str) -> cfg.RigConfig:
    assert STORED.text.count(old) == 1, old
    return cfg.rig_from_text(STORED.text.replace(old, new), STORED.file)


@pytest.mark.parametrize(
    "old, new",
    [
        ('modbus_url = "tcp://127.0.0.1:5020"', 'modbus_url = "rtu:///dev/ttyUSB1?baud=19200"'),
        ('adc_url = "socket://127.0.0.1:5000"', 'adc_url = "/dev/ttyUSB0"'),
        ("store_s = 0.05", "store_s = 2.0"),
        ("static_eccentricity_s = 1800.0", "static_eccentricity_s = 60.0"),
    ],
)
def test_addresses_and_planning_times_may_change(old, new):
    assert cfg.resume_differences(STORED, _edited(old, new)) == []


@pytest.mark.parametrize(
    "old, new, named",
    [
        ('adc_mode = "sequential"', 'adc_mode = "simultaneous"', "[transports] adc_mode"),
        ('calibration_record = "2026-11-26T214732Z-initial"', "", "calibration_record"),
        ("stop_timeout_s = 30.0", "stop_timeout_s = 20.0", "[drives] stop_timeout_s"),
    ],
)
def test_what_the_data_or_the_drives_depend_on_may_not(old, new, named):
    assert cfg.resume_differences(STORED, _edited(old, new)) == [named]


def test_another_text_of_the_same_record_is_named():
    other = cfg.rig_from_text(STORED.text, STORED.file, STORED.record_text + "\n# edited\n")
    assert cfg.resume_differences(STORED, other) == [f"the text of calibration record {STORED.calibration_record}"]

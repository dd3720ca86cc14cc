"""rig.toml values the drives would refuse later (a speed limit above what a REF can command, a
comm-loss watchdog the drives hold as off or shorter than the link-loss time, a Modbus URL the link
cannot open, a device id outside Modbus' 1..247) are refused when the file is read, each naming the
file, the line, the key, the value and the drive's bound.

Real parts: the shipped rig.toml edited in a real file, and the simulator's drive behind a real
Modbus TCP server for the drive's own maximum."""

from __future__ import annotations

import warnings

import pytest

from drives import registers as R
from drives.drive import Drive
from drives.errors import DriveLimitError
from drives.link import ModbusLink
from orbitrig.config import Drives, load_rig
from orbitrig.errors import ConfigError
from rigunits import RPM

from support.paths import ROOT


def _edited(tmp_path, old: str, new: str) -> tuple[str, int]:
    """The shipped rig.toml with its line `old` made `new`, written to a file: (path, that line)."""
    text = (ROOT / "config" / "rig.toml").read_text()
    assert old in text, old
    text = text.replace(old, new, 1)
    path = tmp_path / "rig.toml"
    path.write_text(text)
    line = next(n for n, s in enumerate(text.splitlines(), 1) if s.startswith(new))
    return str(path), line


def _refused(path: str) -> str:
    with pytest.raises(ConfigError) as caught:
        load_rig(path)
    (problem,) = caught.value.problems
    return f"{caught.value.file}: {problem}"


def test_the_drives_maximum_is_the_contracts_max_speed_within_an_int16_ref():
    assert R.MAX_COMMANDABLE_RPM == R.MAX_SPEED_DEFAULT_RPM == 2500
    assert R.ref_to_rpm(0x7FFF, R.SPEED_SCALE_DEFAULT_RPM) == pytest.approx(4915.05)  # an int16 REF reaches further


async def test_a_drive_as_the_contract_gives_it_takes_the_maximum_and_refuses_more(tcp_sim):
    """The simulator's drive at the contract's defaults: MAX_COMMANDABLE_RPM is a REF it takes,
    one rpm more is refused when commanded (what the configuration now refuses when read)."""
    async with ModbusLink(tcp_sim.url, timeout=1.0) as link:
        drive = Drive(link, 2, "orbit", bidirectional=True)
        await drive.read_parameters()
    assert drive.reference_for(-R.MAX_COMMANDABLE_RPM * RPM) == -16666  # 2499.9 rpm: never clamped
    with pytest.raises(DriveLimitError, match="exceeds the drive's MAX_SPEED of 2500 rpm"):
        drive.reference_for((R.MAX_COMMANDABLE_RPM + 1) * RPM)


@pytest.mark.parametrize("key", ["max_spin_rpm", "max_orbit_rpm"])
def test_a_speed_limit_above_the_drives_maximum_is_refused_when_read(tmp_path, key):
    path, line = _edited(tmp_path, f"{key} = 2500.0", f"{key} = 3000.0")
    said = _refused(path)
    assert said.startswith(f"{path}: line {line}: key 'drives.{key}': 3000 rpm is above the drive's maximum"), said
    assert "maximum of 2500 rpm (its MAX_SPEED" in said and "(got 3000.0)" in said, said


def test_the_drives_maximum_itself_is_a_limit_the_file_may_give(tmp_path):
    assert Drives(max_spin_rpm=2500.0, max_orbit_rpm=2500.0).max_orbit_rpm == 2500.0
    with pytest.raises(ValueError, match="2500.5 rpm is above the drive's maximum of 2500 rpm"):
        Drives(max_orbit_rpm=2500.5)


def test_a_watchdog_the_drives_would_hold_as_off_is_refused_when_read(tmp_path):
    """0.04 s is 0 counts of COMM_LOSS_TIMEOUT (0.1 s): the drives' watchdog off, which `drives run`
    refused only once it had written it; a link that declares its loss within 0.03 s let it through."""
    path, line = _edited(tmp_path, "comm_loss_timeout_s = 1.0", "comm_loss_timeout_s = 0.04")
    text = open(path).read()
    text = text.replace("poll_interval_s = 0.1", "poll_interval_s = 0.01").replace(
        "timeout_s = 0.15", "timeout_s = 0.02"
    )
    text = text.replace("link_loss_polls = 3", "link_loss_polls = 1")
    open(path, "w").write(text)
    said = _refused(path)
    assert said.startswith(f"{path}: line {line}: key 'drives.comm_loss_timeout_s': 0.04 s is 0 counts"), said
    assert "watchdog off; give at least 0.1 s (got 0.04)" in said, said


def test_the_link_loss_time_is_checked_against_the_watchdog_the_drives_hold(tmp_path):
    """comm_loss_timeout_s 0.84 s is held as 8 counts, 0.8 s: a link loss declared after
    3 x (0.1 + 0.17) = 0.81 s comes after the drives stopped on their own watchdog."""
    path, _ = _edited(tmp_path, "comm_loss_timeout_s = 1.0", "comm_loss_timeout_s = 0.84")
    text = open(path).read().replace("timeout_s = 0.15", "timeout_s = 0.17", 1)
    open(path, "w").write(text)
    said = _refused(path)
    assert "= 0.81 s is not below comm_loss_timeout_s = 0.84 s (held by the drives as 0.8 s)" in said, said
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # 0.75 s of a watchdog held as 1.0 s: no warning, no refusal
        assert Drives(comm_loss_timeout_s=1.04).watchdog_s == pytest.approx(1.0)


@pytest.mark.parametrize(
    "url, why",
    [
        ("tcp//127.0.0.1:5020", "unknown scheme ''; use tcp:// or rtu://"),
        ("rtu:///dev/ttyUSB1?baud=fast", "invalid literal for int()"),
        ("tcp://127.0.0.1:5020?unit=1", "unexpected query 'unit=1'"),
    ],
)
def test_a_modbus_url_the_link_cannot_open_is_refused_when_read(tmp_path, url, why):
    path, line = _edited(tmp_path, 'modbus_url = "tcp://127.0.0.1:5020"', f'modbus_url = "{url}"')
    said = _refused(path)
    assert said.startswith(f"{path}: line {line}: key 'transports.modbus_url': bad Modbus URL {url!r}: "), said
    assert why in said, said


@pytest.mark.parametrize("old, new", [("spin_id = 1", "spin_id = 248"), ("orbit_id = 2", "orbit_id = 0")])
def test_a_device_id_outside_modbus_range_is_refused_when_read(tmp_path, old, new):
    path, line = _edited(tmp_path, old, new)
    said = _refused(path)
    key = new.split(" ")[0]
    assert said.startswith(f"{path}: line {line}: key 'drives.{key}': Input should be"), said

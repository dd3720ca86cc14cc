"""`orbitrig drives stop` and `status` with a rig.toml refused elsewhere than the drives' link: the
stop still reaches the simulator's turning drives over Modbus TCP (a limit above the drive's maximum,
a typo, a channel's unit, an active calibration record that is not there), the file's errors said as the
full load says them (file, line, key), exit 3; a link that cannot be taken (a broken modbus_url,
a device id out of range) is named with the option that gives it, and nothing is sent (exit 2)."""

from __future__ import annotations

import json
import re

import pytest
from support.drives_testkit import CW_RAMP_STOP, CW_RUN, invoke_cli
from support.paths import ROOT
from support.rig_configs import without_can_node

pytestmark = pytest.mark.timeout(40)

CW_READY = 0x0476  # the spec's "ready to switch on" word


def lab_rig(tmp_path, url: str, old: str, new: str) -> tuple[str, int]:
    """(config/rig.toml at `url` with its first line `old` made `new`, that line's number)."""
    text = without_can_node((ROOT / "config" / "rig.toml").read_text())
    text = re.sub(r'(?m)^modbus_url = ".*"', f'modbus_url = "{url}"', text)
    lines = text.splitlines()
    at = [n for n, line in enumerate(lines) if line.split("#")[0].strip() == old]
    assert at, old
    lines[at[0]] = new
    path = tmp_path / "rig.toml"
    path.write_text("\n".join(lines) + "\n")
    return str(path), at[0] + 1


def turning(sim) -> None:
    for dev in (1, 2):  # ready to switch on, then run (the spec's words), at REF 3000
        for address, word in ((1, 3000), (0, CW_READY), (0, CW_RUN)):
            sim.in_loop(sim.models[dev].write, address, [word])


def untouched_since_turning(sim) -> bool:
    return all(sim.regs(dev)["CW"] == CW_RUN and sim.regs(dev)["REF"] == 3000 for dev in (1, 2))


@pytest.mark.parametrize(
    "old, new, key",
    [
        ("max_spin_rpm = 2500.0", "max_spin_rpm = 3000", "drives.max_spin_rpm"),
        ("revolutions = 50", "revolutoins = 50", "averaging.revolutoins"),
        ('unit = "N"', 'unit = "V"', "channels[0].unit"),
        ('calibration_record = "2026-11-26T214732Z-initial"', 'calibration_record = "gone"', "calibration_record"),
    ],
)
def test_a_turning_drive_is_stopped_despite_an_error_elsewhere_in_the_file(threaded_tcp_sim, tmp_path, old, new, key):
    sim = threaded_tcp_sim
    path, line = lab_rig(tmp_path, sim.url, old, new)
    turning(sim)
    code, out, err = invoke_cli("drives", "stop", "--config", path)
    assert code == 3, err
    assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RAMP_STOP, err
    assert sim.regs(1)["ACT"] == sim.regs(2)["ACT"] == 0
    assert err.startswith("orbitrig drives stop: WARNING: the rig configuration has errors"), err
    assert f"\n{path}: line {line}: key '{key}': " in err, err
    assert f"WARNING: both drives stopped, but the rig configuration has errors ({path}, above)" in err
    code, out, err = invoke_cli("drives", "status", "--config", path, "--json")  # read-only, same file
    assert code == 3 and f"{path}: line {line}: key '{key}'" in err, err
    status = json.loads(out)
    assert status["modbus"] == sim.url and status["spin"]["id_from"] == "configuration"
    assert status["spin"]["actual_rpm"] == status["orbit"]["actual_rpm"] == 0


def test_status_reads_the_ids_the_file_gives_around_an_error(threaded_tcp_sim, tmp_path):
    """The [drives] ids the file gives are taken though a key beside them is refused."""
    sim = threaded_tcp_sim
    path, line = lab_rig(tmp_path, sim.url, "max_spin_rpm = 2500.0", "max_spin_rpm = 3000")
    text = open(path).read().replace("spin_id = 1\norbit_id = 2", "spin_id = 2\norbit_id = 1")
    open(path, "w").write(text)
    code, out, err = invoke_cli("drives", "status", "--config", path)
    assert code == 3, err
    assert "spin  (id 2): " in out and "orbit (id 1): " in out, out


@pytest.mark.parametrize(
    "old, new, key, give",
    [
        ('modbus_url = "URL"', 'modbus_url = "http://127.0.0.1:5020"', "transports.modbus_url", "--modbus URL"),
        ("spin_id = 1", "spin_id = 300", "drives.spin_id", "--spin-id ID --orbit-id ID"),
        # a hardware key left out is never the simulator's address or ids 1, 2
        ('modbus_url = "URL"', 'modbus-url = "URL"', "transports.modbus-url", "--modbus URL"),
        ("orbit_id = 2", "orbitid = 2", "drives.orbitid", "--spin-id ID --orbit-id ID"),
    ],
)
def test_a_link_that_cannot_be_taken_is_named_and_nothing_is_sent(threaded_tcp_sim, tmp_path, old, new, key, give):
    sim = threaded_tcp_sim
    path, line = lab_rig(tmp_path, sim.url, old.replace("URL", sim.url), new)
    turning(sim)
    code, out, err = invoke_cli("drives", "stop", "--config", path)
    assert code == 2 and untouched_since_turning(sim), err
    assert err.startswith("orbitrig drives stop: error (config): "), err
    assert f"{path}: line {line}: key '{key}': " in err and err.rstrip().endswith(f"cannot be taken: give {give}"), err
    code, out, err = invoke_cli("drives", "status", "--config", path)
    assert code == 2 and f"key '{key}'" in err and out == "", err


@pytest.mark.parametrize(
    "old, new",
    [
        ('modbus_url = "URL"', "#"),
        ("[transports]", "[transport]"),
        ("spin_id = 1", "#"),
        ("[drives]", "[drive]"),
    ],
)
def test_a_link_key_left_out_is_refused_not_defaulted(tmp_path, old, new):
    """The URL and the ids are the rig's hardware: left out, they are refused as the full load
    refuses them (naming the key and what to add), not taken as tcp://127.0.0.1:5020 and ids 1, 2."""
    from orbitrig.config import drives_link

    path, _ = lab_rig(tmp_path, "tcp://10.0.0.7:502", old.replace("URL", "tcp://10.0.0.7:502"), new)
    link = drives_link(path)
    section = "transports" if "transports" in old or "modbus" in old else "drives"
    if section == "transports":
        assert link.url is None and link.drives is not None, link
    else:
        assert link.drives is None and link.url == "tcp://10.0.0.7:502", link
    assert any(f"key '{section}" in p and ("missing from" in p or "section" in p) for p in link.problems), link


def test_the_options_give_what_the_file_cannot(threaded_tcp_sim, tmp_path):
    """A broken modbus_url with --modbus, an id out of range with --spin-id and --orbit-id: the stop
    goes out, the file's errors said, exit 3."""
    sim = threaded_tcp_sim
    path, _ = lab_rig(tmp_path, sim.url, f'modbus_url = "{sim.url}"', 'modbus_url = "http://nowhere"')
    turning(sim)
    code, out, err = invoke_cli("drives", "stop", "--config", path, "--modbus", sim.url)
    assert code == 3 and "key 'transports.modbus_url'" in err and f"the drives at {sim.url} (--modbus)" in err, err
    assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RAMP_STOP and sim.regs(1)["ACT"] == sim.regs(2)["ACT"] == 0
    path, _ = lab_rig(tmp_path, sim.url, "spin_id = 1", "spin_id = 300")
    turning(sim)
    code, out, err = invoke_cli("drives", "stop", "--config", path, "--spin-id", "1", "--orbit-id", "2")
    assert code == 3 and "key 'drives.spin_id'" in err and "spin (id 1, option), orbit (id 2, option)" in err, err
    assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RAMP_STOP and sim.regs(1)["ACT"] == sim.regs(2)["ACT"] == 0


@pytest.mark.parametrize(
    "options, said",
    [
        ((), "and its [drives] device ids are used all the same"),
        (
            ("--spin-id", "2", "--orbit-id", "1"),
            "and the device ids of the options (--spin-id 2, --orbit-id 1) are used",
        ),
        (
            ("--orbit-id", "1", "--spin-id", "2"),
            "and the device ids of the options (--spin-id 2, --orbit-id 1) are used",
        ),
    ],
)
def test_the_warning_names_the_device_ids_used_the_files_or_the_options(threaded_tcp_sim, tmp_path, options, said):
    """The WARNING of a command despite the file's errors says whose device ids address the drives:
    --spin-id/--orbit-id override the file's, and `status` reads the drives at the options' ids."""
    sim = threaded_tcp_sim
    path, _ = lab_rig(tmp_path, sim.url, "max_spin_rpm = 2500.0", "max_spin_rpm = 3000")
    code, out, err = invoke_cli("drives", "status", "--config", path, *options)
    assert code == 3, err
    assert said in err, err
    assert ("spin  (id 2): " in out) == bool(options), out


def test_the_warning_names_one_id_option_beside_the_files_other(threaded_tcp_sim, tmp_path):
    sim = threaded_tcp_sim
    path, _ = lab_rig(tmp_path, sim.url, "max_spin_rpm = 2500.0", "max_spin_rpm = 3000")
    code, out, err = invoke_cli("drives", "status", "--config", path, "--orbit-id", "3")
    assert code == 2, err  # no drive 3 on the simulator: refused, but named as the one used
    assert "and the device id of --orbit-id 3 and its [drives] spin_id are used all the same" in err, err

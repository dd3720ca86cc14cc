"""`orbitrig drives run` and `drives stop --emergency` with a drive in local control: someone at
the rig has the spin drive at its keypad, and it refuses the network's control words (the
simulator answers 03 until its keypad gives control back: docs/protocols/drive-modbus.md, "Local
control"). The command names the drive and local control, never says it stopped, and the other
drive is stopped. Real parts: the simulator's two drive models behind a real Modbus TCP server,
the command in a subprocess."""

from __future__ import annotations

import logging
import re

import pytest
from drives.local_control import LOCAL
from support.drives_testkit import CW_EMERGENCY, CW_RUN, SimDrives, make_models, run_cli, serve
from support.paths import ROOT
from support.rig_configs import drive_lines, without_can_node

pytestmark = pytest.mark.timeout(90)


@pytest.fixture
async def sim() -> SimDrives:
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    models = make_models()
    endpoint = await serve("tcp", models)
    try:
        yield SimDrives("tcp", models, endpoint)
    finally:
        await endpoint.aclose()


def rig_config(tmp_path, url: str) -> str:
    """config/rig.toml at the simulator, no CAN node, a patient link and a 3 s watchdog."""
    text = without_can_node((ROOT / "config" / "rig.toml").read_text())
    text = re.sub(r'(?m)^modbus_url = ".*"', f'modbus_url = "{url}"', text)
    changes = (("timeout_s = 0.15", "timeout_s = 0.5"), ("comm_loss_timeout_s = 1.0", "comm_loss_timeout_s = 3.0"))
    path = tmp_path / "rig.toml"
    path.write_text(drive_lines(text, changes))
    return str(path)


async def test_drives_run_with_a_drive_at_its_keypad_names_it_and_starts_neither(sim, tmp_path):
    """The spin drive held at its keypad, at standstill: the start's ready word is refused before any
    run word went out; the command says which drive and why (before: only `Modbus exception 03`)."""
    sim.models[1].local_control(0.0)
    code, _, err = await run_cli(
        "drives", "run", "--config", rig_config(tmp_path, sim.url), "--spin", "600", "--orbit", "-300", timeout=60
    )
    assert code == 1, err  # the spin drive refused the stop as well: not confirmed stopped, not said stopped
    assert (
        f"drives not confirmed stopped: DriveInLocalControl: spin drive (id 1), register CW (0): did not take the ramp stop (OFF1, 0x047E): {LOCAL}"
        in err
    ), err
    said = f"orbitrig drives run: error (refused): spin drive (id 1), register CW (0): did not take the ready word (0x0476): {LOCAL}"
    assert said in err, err
    assert all(cw != CW_RUN for _, cw in sim.models[2].control_words), sim.models[2].control_words  # never started
    assert sim.regs(1)["ACT"] == sim.regs(2)["ACT"] == 0


async def test_drives_run_with_the_orbit_drive_at_its_keypad_never_starts_the_spin_drive(sim, tmp_path):
    """The orbit drive held at its keypad: every drive the start runs gets its ready word before
    either gets a run word, so the spin drive (started first) is never run only to be stopped
    again (before: the spin drive ran up, then both got the stop when the orbit drive refused)."""
    sim.models[2].local_control(0.0)
    code, _, err = await run_cli(
        "drives", "run", "--config", rig_config(tmp_path, sim.url), "--spin", "600", "--orbit", "-300", timeout=60
    )
    assert code != 0, err
    said = f"error (refused): orbit drive (id 2), register CW (0): did not take the ready word (0x0476): {LOCAL}"
    assert said in err, err
    assert all(cw != CW_RUN for _, cw in sim.models[1].control_words), sim.models[1].control_words


async def test_an_emergency_stop_with_a_drive_at_its_keypad_stops_the_other_and_says_which(sim, tmp_path):
    """The spin drive run at its keypad (600 rpm, held), the orbit drive turning (-300 rpm, under the
    network): `drives stop --emergency` stops the orbit drive, and says the spin drive did not take
    the emergency stop because it is in local control, not that both stopped."""
    sim.models[1].local_control(600.0)
    sim.keypad_run(2, -300.0)
    code, _, err = await run_cli("drives", "stop", "--emergency", "--config", rig_config(tmp_path, sim.url), timeout=60)
    assert code == 2, err
    said = f"spin drive (id 1), register CW (0): did not take the emergency stop (OFF3, 0x047B): {LOCAL}"
    assert f"orbitrig drives stop: error (refused): {said}" in err, err
    assert "stop word delivered to: orbit (id 2)" in err and "which took the stop, at standstill" in err, err
    assert any(cw == CW_EMERGENCY for _, cw in sim.models[2].control_words)
    assert sim.regs(2)["ACT"] == 0 and sim.rpm(1) == pytest.approx(600.0)  # the keypad's drive runs on

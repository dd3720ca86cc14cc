"""`orbitrig drives run` arms the drives' comm-loss watchdog before it leaves them running.

The drive contract (docs/protocols/drive-modbus.md) lets COMM_LOSS_TIMEOUT be 0: "0 disables" the
watchdog, and a drive set so at its keypad or by another tool keeps turning with nobody polling
it. `run` gives both drives [drives] comm_loss_timeout_s on entry (with and without --hold),
leaves them running only once both read an armed watchdog back, and says after how many
seconds it ramps them down; a drive that reads 0 is named with the register, both are ramped to
zero and it exits 2.

Real parts: the simulator's two drive models behind a real Modbus TCP server; the command in a
subprocess (its own rig.toml), except where the configuration is one its validation would not
let through the file (in process, the command's own coroutine).
"""

from __future__ import annotations

import asyncio
import logging
import re
import signal

import pytest
from support.cli_helpers import orbitrig_started_async, reaped_async
from support.drives_testkit import CW_RAMP_STOP, CW_RUN, RPM, SimDrives, make_models, run_cli, serve
from support.paths import ROOT
from support.rig_configs import drive_lines, without_can_node

from orbitrig.config import Drives

pytestmark = pytest.mark.timeout(90)

COMM_LOSS_TIMEOUT = 104  # the contract's register, 0.1 s units (written out, not imported from drives/)
FAULT_COMM_LOSS = 7510
SW_AT_SETPOINT = 0x100
WATCHDOG_S = 3.0  # the configured watchdog: generous, both cores are busy


@pytest.fixture
async def drives_off() -> SimDrives:
    """Both drives with COMM_LOSS_TIMEOUT 0 (disabled, e.g. set at the keypad), over Modbus TCP."""
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    models = make_models()
    for model in models.values():
        model.write(COMM_LOSS_TIMEOUT, [0])
    endpoint = await serve("tcp", models)
    try:
        yield SimDrives("tcp", models, endpoint)
    finally:
        await endpoint.aclose()


def rig_config(tmp_path, url: str) -> str:
    """config/rig.toml at the simulator, a 3 s watchdog and a patient link (3 x (0.1 + 0.5) s < 3 s);
    no CAN node (the simulator's drives alone)."""
    text = without_can_node((ROOT / "config" / "rig.toml").read_text())
    text = re.sub(r'(?m)^modbus_url = ".*"', f'modbus_url = "{url}"', text)
    changes = (
        ("comm_loss_timeout_s = 1.0", f"comm_loss_timeout_s = {WATCHDOG_S}"),
        ("timeout_s = 0.15", "timeout_s = 0.5"),
    )
    text = drive_lines(text, changes)
    path = tmp_path / "rig.toml"
    path.write_text(text)
    return str(path)


def watchdog_counts(sim: SimDrives) -> list[int]:
    return [sim.models[dev].parameter(COMM_LOSS_TIMEOUT) for dev in (1, 2)]


async def ramped_down_by_the_watchdog(sim: SimDrives) -> None:
    """Both drives tripped 7510 and at standstill, with nobody polling them."""
    await sim.wait_for(
        lambda: all(sim.regs(dev)["FAULT"] == FAULT_COMM_LOSS and sim.regs(dev)["ACT"] == 0 for dev in (1, 2)),
        WATCHDOG_S + 20.0,
        "both drives ramped down by their comm-loss watchdog",
    )


async def test_run_arms_the_watchdog_that_ramps_the_released_drives_down(drives_off, tmp_path):
    sim = drives_off
    cfg = rig_config(tmp_path, sim.url)
    code, out, err = await run_cli(
        "drives", "run", "--config", cfg, "--spin", "1000", "--orbit", "-500", "--settle", "0.1", "--timeout", "20"
    )
    assert code == 0, err
    assert watchdog_counts(sim) == [30, 30]  # 3 s in 0.1 s units, written on entry
    left = "both drives left running at the setpoint: with no client polling them, their comm-loss watchdog "
    assert left + "(COMM_LOSS_TIMEOUT) ramps them down 3 s after the last request" in err, err
    assert err.count("left running") == 1, err  # said once, by the rig's exit
    assert all(sim.regs(dev)["CW"] == CW_RUN for dev in (1, 2))  # left running at the setpoint
    await ramped_down_by_the_watchdog(sim)
    # the next command resets the watchdog's trip, saying whose it is: no stranger's ("a previous client")
    code, out, err = await run_cli("drives", "run", "--config", cfg, "--spin", "0", "--orbit", "0", "--timeout", "20")
    # reset; the 3 s watchdog armed again may trip once the command has left (its exit is slow on a busy host)
    assert code == 0 and all(sim.not_the_watchdog(dev) for dev in (1, 2)), err
    for drive in ("spin drive (id 1)", "orbit drive (id 2)"):
        assert f"{drive}: at standstill with fault 7510, its comm-loss watchdog's since the last client" in err, err


async def test_run_hold_arms_the_watchdog_for_a_command_that_dies(drives_off, tmp_path):
    sim = drives_off
    proc = await orbitrig_started_async(
        "drives",
        "run",
        "--config",
        rig_config(tmp_path, sim.url),
        "--spin",
        "900",
        "--orbit",
        "450",
        "--settle",
        "0.05",
        "--hold",
        stdout=asyncio.subprocess.DEVNULL,
        stderr=asyncio.subprocess.DEVNULL,
    )
    async with reaped_async(proc):
        await sim.wait_for(
            lambda: all(sim.regs(dev)["SW"] & SW_AT_SETPOINT for dev in (1, 2)), 30, "both drives at the setpoint"
        )
        assert watchdog_counts(sim) == [30, 30]
        proc.send_signal(signal.SIGKILL)  # the hold dies without a word to the drives
        await asyncio.wait_for(proc.wait(), 15)
    await ramped_down_by_the_watchdog(sim)


async def test_a_watchdog_that_reads_back_0_is_not_left_running(drives_off, capsys):
    """[drives] comm_loss_timeout_s 0.04 s is under the register's 0.1 s unit: 0 counts, the
    watchdog disabled. (The file's validation refuses it; the command is given such a configuration
    in process.)"""
    from orbitrig.cli.drives import effective_limits
    from orbitrig.cli.drives_hold import Interrupt
    from orbitrig.cli.drives_run import _run_open

    sim = drives_off
    d = Drives(timeout_s=0.5, comm_loss_timeout_s=3.0).model_copy(update={"comm_loss_timeout_s": 0.04})
    how = (0.05, 20.0, False, 5.0)  # settle, timeout, hold, status_every; no CAN node watched (None)
    code = await _run_open(sim.url, d, effective_limits(d), 1000 * RPM, 500 * RPM, how, Interrupt(), None)
    err = capsys.readouterr().err
    assert code == 2, err
    assert "orbitrig drives run: error (watchdog): spin drive (id 1), register COMM_LOSS_TIMEOUT (104)" in err, err
    assert "reads 0" in err and "both drives stopped" in err, err
    assert "ramps them down" not in err  # no watchdog time is promised
    await asyncio.sleep(1.0)
    for dev in (1, 2):
        regs = sim.regs(dev)
        assert regs["CW"] == CW_RAMP_STOP and regs["ACT"] == 0 and regs["REF"] == 0, regs

"""An entry of the rig that fails once connected (a parameter write the drive refuses, a Modbus
timeout on the second drive) stops drives found turning (left running by a released rig, or
at their keypad) before the link closes: both get the ramp stop word, and the
entry's own exception goes on, saying which drive was turning at what speed and what the stop
reached. On the simulator's drives over real Modbus (TCP, RTU on a pty), which record every
control word written."""

from __future__ import annotations

import time

import pytest
from support.drives_testkit import CW_RAMP_STOP, CW_RUN, RPM, SimDrives, open_rig, run_cli

from drives.drive import Drive
from drives.errors import DriveExceptionResponse, DriveTimeoutError
from drives.limits import DriveLimits

pytestmark = pytest.mark.timeout(60)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)
# s per request where no answer is meant to be missed: the opening and the failed entry's reads
# (not retried: a drive not read is stopped at once) given a busy host's margin; no test waits on it
MARGIN_TIMEOUT = 1.0
LOST_TIMEOUT = 0.4  # s per request where two are dropped on purpose: 0.8 s spent on them


def stopped_since(sim: SimDrives, dev: int, t0: float) -> bool:
    """Drive `dev` took the ramp stop word since `t0` (monotonic s), and no other word."""
    words = [cw for t, cw in sim.models[dev].control_words if t >= t0]
    return bool(words) and set(words) == {CW_RAMP_STOP}


async def left_running(sim: SimDrives) -> None:
    """Both drives left turning by a released rig, their comm-loss watchdog off (nothing else stops them)."""
    rig = open_rig(sim, LIMITS, comm_loss_timeout=0.0, timeout=MARGIN_TIMEOUT)
    async with rig:
        await rig.set_speeds(1200 * RPM, -600 * RPM)
        await rig.wait_settled(hold=0.05, timeout=10.0)
        rig.release()
    assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RUN


def after_spin_read(monkeypatch, then) -> None:
    """`then()` once the spin drive's parameters are read on entry, before the orbit drive's."""
    read, done = Drive.read_parameters, []

    async def read_then(self):
        if self.device_id == 2 and not done:
            done.append(then())
        return await read(self)

    monkeypatch.setattr(Drive, "read_parameters", read_then)


async def test_a_refused_parameter_write_stops_both_running_drives_and_says_so(sim):
    await left_running(sim)
    t0 = time.monotonic()
    rig = open_rig(sim, LIMITS, comm_loss_timeout=0.5, timeout=MARGIN_TIMEOUT)  # running: refused, exception 03
    with pytest.raises(DriveExceptionResponse) as raised:
        await rig.__aenter__()
    assert raised.value.exception_code == 3
    for dev in (1, 2):
        assert stopped_since(sim, dev, t0), (dev, sim.models[dev].control_words)
    note = " ".join(getattr(raised.value, "__notes__", []))
    assert "spin (id 1) running at 125.664 rad/s (1200.0 rpm)" in note, note
    assert "orbit (id 2) running at -62.832 rad/s (-600.0 rpm)" in note, note
    assert "the ramp stop (OFF1) sent to spin (id 1), orbit (id 2): taken by spin (id 1), orbit (id 2)" in note, note
    assert not rig.link.connected
    await sim.wait_stopped(5.0)


async def test_a_timeout_on_the_second_drive_stops_a_drive_at_its_keypad(tcp_sim, monkeypatch):
    sim = tcp_sim
    sim.keypad_run(2, -900)  # the orbit drive run from its keypad, handed back; the spin drive stopped
    after_spin_read(monkeypatch, lambda: sim.endpoint.drop_next(2))  # its read and its retry time out
    t0 = time.monotonic()
    rig = open_rig(sim, LIMITS, timeout=LOST_TIMEOUT)
    with pytest.raises(DriveTimeoutError) as raised:
        await rig.__aenter__()
    for dev in (1, 2):
        assert stopped_since(sim, dev, t0), (dev, sim.models[dev].control_words)
    note = " ".join(getattr(raised.value, "__notes__", []))
    assert "orbit (id 2) running at -94.248 rad/s (-900.0 rpm)" in note, note
    assert "spin (id 1)" not in note.split("the ramp stop")[0], note  # read at standstill: not named
    assert "taken by spin (id 1), orbit (id 2)" in note, note
    await sim.wait_stopped(5.0)


async def test_drives_run_refused_by_a_turning_drive_stops_both_and_says_so(tcp_sim):
    sim = tcp_sim
    await left_running(sim)
    rc, _, err = await run_cli("drives", "run", "--modbus", sim.url, "--spin", "300", "--orbit", "100")
    assert rc == 2, err
    assert "the entry failed with spin (id 1) running at 125.664 rad/s (1200.0 rpm)" in err, err
    assert "the ramp stop (OFF1) sent to spin (id 1), orbit (id 2): taken by spin (id 1), orbit (id 2)" in err, err
    # the failure's own line says the same: the stop sent, not "nothing sent", nor to stop it first
    failed = next(line for line in err.splitlines() if line.startswith("orbitrig drives run: error"))
    assert failed.endswith("; stop sent to both drives") or "stop sent to both drives;" in failed, err
    assert "nothing sent" not in err and "stop it first" not in err, err
    await sim.wait_stopped(5.0)

"""A ramp stop over a bare link (no RigDrives reading the drives) never turns an emergency ramp
another client started back into the ten times slower ramp stop: it reads each drive's status
word first (one exchange, no retries) and sends the emergency stop (OFF3) instead if a drive
turns in its emergency ramp, and says so. The paths: `send_stop_words` (a cancelled calibration
opening, `orbitrig drives stop` and `drives run` when they cannot open the drives) and the
service's idle `stop` (orbitrig.service.idle_stop). An abort (the emergency stop) reads nothing
first: its word is the first request each drive sees.

The simulator's drives over real Modbus (TCP, RTU on a pty), ramps slowed (DECEL_TIME 90 s for
3000 rpm, at 3 x: the emergency stop about 1.5 s wall from 1500 rpm, the ramp stop 15 s); the
emergency stop comes from a client of its own (a raw link, not this process' drives.stop, whose
memory `emergency_within` cannot know it)."""

from __future__ import annotations

import time
from types import SimpleNamespace

import pytest
from support.drives_testkit import CW_EMERGENCY, CW_RAMP_STOP, RPM, SimDrives, open_rig, set_parameter

from drives import registers as R
from drives.limits import DriveLimits
from drives.link import ModbusLink
from orbitrig.config import Drives
from orbitrig.run.stop_words import send_stop_words
from orbitrig.service import idle_stop

pytestmark = pytest.mark.timeout(60)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)
CONFIG = Drives(timeout_s=0.3, comm_loss_timeout_s=2.0)  # spin id 1, orbit id 2
EMERGENCY_RAMP_S = 4.0  # wall s to standstill along the emergency ramp from 1500 rpm (1.5 s), with margin
NO_SIGNAL = SimpleNamespace(received=[])  # a command's signal record: none received
READ_IN_EMERGENCY = "emergency stop (OFF3, as spin (id 1) read turning in its emergency ramp)"


async def _both_turning(sim: SimDrives) -> None:
    """Both drives at 1500 rpm, left turning by a client gone away (their watchdog off), ramps slowed."""
    for model in sim.models.values():
        set_parameter(model, R.DECEL_TIME, 900)
    async with open_rig(sim, LIMITS, comm_loss_timeout=0.0, timeout=1.0) as rig:  # 1 s: nothing is to go unanswered
        await rig.set_speeds(1500 * RPM, -1500 * RPM)
        await rig.wait_settled(hold=0.05, timeout=20)
        rig.release()


async def _spin_in_its_emergency_ramp(sim: SimDrives) -> float:
    """`_both_turning`, then another client's emergency stop (OFF3) to the spin drive only; the
    monotonic s it was written. The orbit drive runs on."""
    await _both_turning(sim)
    async with ModbusLink(sim.url, timeout=0.3) as other:
        t_off3 = time.monotonic()
        await other.write(1, R.CW, [CW_EMERGENCY])
    await sim.wait_for(lambda: abs(sim.rpm(1)) < 1450, 3, "the spin drive in its emergency ramp")
    assert sim.regs(1)["SW"] & R.SWBit.OFF_3_STA == 0 and sim.regs(2)["ACT"] != 0
    return t_off3


def _words_since(sim: SimDrives, dev: int, since: float) -> list[int]:
    return [cw for t, cw in sim.models[dev].control_words if t >= since]


async def _kept_the_emergency_ramp(sim: SimDrives, t_off3: float, t_stop: float) -> None:
    """Both drives got OFF3 from the stop, never OFF1, and reach standstill along the emergency
    ramp (the spin drive's begun at `t_off3`; OFF1 would have made it some 15 s)."""
    for dev in (1, 2):
        words = _words_since(sim, dev, t_stop)
        assert CW_EMERGENCY in words and CW_RAMP_STOP not in words, (dev, [hex(w) for w in words])
    await sim.wait_for(lambda: sim.regs(1)["ACT"] == 0, EMERGENCY_RAMP_S, "spin standstill")
    assert time.monotonic() - t_off3 < EMERGENCY_RAMP_S
    await sim.wait_for(lambda: sim.regs(2)["ACT"] == 0, EMERGENCY_RAMP_S, "orbit standstill")
    assert time.monotonic() - t_stop < EMERGENCY_RAMP_S


def _requests_seen(sim: SimDrives, monkeypatch) -> dict[int, list[float]]:
    """Monotonic s of every request each drive answers from now on (the server's request count)."""
    seen: dict[int, list[float]] = {1: [], 2: []}
    for dev, model in sim.models.items():
        note = model.note_request

        def noted(dev=dev, note=note) -> None:
            seen[dev].append(time.monotonic())
            note()

        monkeypatch.setattr(model, "note_request", noted)
    return seen


async def test_stop_words_into_another_clients_emergency_ramp_are_the_emergency_stop(slow_drives):
    """`send_stop_words` (calibration's cancelled opening, `drives stop` on the bare link)."""
    sim: SimDrives = slow_drives
    t_off3 = await _spin_in_its_emergency_ramp(sim)
    t_stop = time.monotonic()
    sent = await send_stop_words(sim.url, CONFIG)
    await _kept_the_emergency_ramp(sim, t_off3, t_stop)
    assert (sent.emergency, sent.escalated, sent.errors) == (True, False, [])
    assert sent.took == ["spin (id 1)", "orbit (id 2)"]
    assert sent.said(NO_SIGNAL) == f"{READ_IN_EMERGENCY} sent"


async def test_the_services_idle_stop_into_another_clients_emergency_ramp_is_the_emergency_stop(slow_drives):
    """The service's `stop` that no run carries out, the emergency stop not its own (another
    process'): the reply names the emergency stop it sent and why."""
    sim: SimDrives = slow_drives
    t_off3 = await _spin_in_its_emergency_ramp(sim)
    t_stop = time.monotonic()
    error, detail = await idle_stop.emergency_stop(sim.url, CONFIG, emergency=False)
    await _kept_the_emergency_ramp(sim, t_off3, t_stop)
    assert error is None, error
    assert detail == f"{READ_IN_EMERGENCY} sent to both drives over a link of the service's own (no run held them)"


async def test_a_ramp_stop_with_no_drive_in_its_emergency_ramp_stays_the_ramp_stop(slow_drives, monkeypatch):
    """Both drives read running (each read once, before its word): the ramp stop (OFF1), as asked,
    said as before."""
    sim: SimDrives = slow_drives
    await _both_turning(sim)
    seen = _requests_seen(sim, monkeypatch)
    t_stop = time.monotonic()
    error, detail = await idle_stop.emergency_stop(sim.url, CONFIG, emergency=False)
    for dev in (1, 2):
        assert _words_since(sim, dev, t_stop) == [CW_RAMP_STOP], dev
        t_word = sim.models[dev].control_words[-1][0]
        assert len([t for t in seen[dev] if t <= t_word]) == 2, (dev, seen[dev], t_word)  # its read, its word
    assert error is None and detail.startswith("ramp stop (OFF1) sent to both drives"), (error, detail)
    await idle_stop.emergency_stop(sim.url, CONFIG)  # (the test's end: not 15 s)
    await sim.wait_stopped(EMERGENCY_RAMP_S)


@pytest.mark.parametrize("path", ["idle abort", "stop words"])
async def test_an_abort_reads_nothing_before_its_emergency_stop(slow_drives, monkeypatch, path):
    """The emergency stop's word is the first request each drive sees (no status read first), as
    quick as before; a ramp stop's is the second (its status read first)."""
    sim: SimDrives = slow_drives
    await _spin_in_its_emergency_ramp(sim)
    seen = _requests_seen(sim, monkeypatch)
    t_abort = time.monotonic()
    if path == "idle abort":
        assert (await idle_stop.emergency_stop(sim.url, CONFIG))[0] is None
    else:
        assert (await send_stop_words(sim.url, CONFIG, emergency=True)).errors == []
    for dev in (1, 2):
        (t_word,) = [t for t, cw in sim.models[dev].control_words if t >= t_abort]
        assert len([t for t in seen[dev] if t <= t_word]) == 1, (dev, seen[dev], t_word)
    assert sim.models[2].control_words[-1][0] - t_abort < 1.0  # both words out at once (two requests)

    seen[1].clear()
    t_ramp = time.monotonic()
    await send_stop_words(sim.url, CONFIG)  # the ramp stop asked: read first, then OFF3
    (t_word,) = [t for t, cw in sim.models[1].control_words if t >= t_ramp]
    assert len([t for t in seen[1] if t <= t_word]) == 2, (seen[1], t_word)
    await sim.wait_stopped(EMERGENCY_RAMP_S)

"""A drive that runs on through the stop (its words refused with 03, or taken and ignored) is
kept running by the poll's own requests, which feed its comm-loss watchdog. The poll then stops
addressing it (drives/starve.py) until its watchdog has tripped fault 7510 and ramps it down,
polls the other drive meanwhile, and reads it again to say what it shows. On the simulator's
drives over real Modbus; the refusal alone is the test's (the simulator's drives always obey)."""

from __future__ import annotations

import asyncio
import logging
import time

import pytest
from support.drives_testkit import CW_RUN, RPM, SimDrives, open_rig

from drives.errors import DriveError
from drives.limits import DriveLimits
from drives.starve import MARGIN_S
from sim.drive_registers import COMM_LOSS_FAULT, DriveModbusException

pytestmark = pytest.mark.timeout(60)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)
CW, REF = 0, 1  # register addresses
POLL_S, WATCHDOG_S = 0.05, 0.5  # open_rig's
PRESS_S = 0.005


def defy_stops(sim: SimDrives, dev: int, monkeypatch, *, refuse: bool) -> None:
    """From now on drive `dev` ignores every CW and REF write: answered with exception 03
    (`refuse`), else answered as taken."""
    model, real = sim.models[dev], sim.models[dev].write

    def write(address, values):
        if address in (CW, REF):
            if refuse:
                raise DriveModbusException(0x03, "refused by the test")
            return
        real(address, values)

    monkeypatch.setattr(model, "write", write)


async def at_speed(rig) -> None:
    """Spin 1000 rpm, orbit -500 rpm (backward whirl), settled."""
    await rig.set_speeds(1000 * RPM, -500 * RPM)
    await rig.wait_settled(hold=0.05, timeout=10.0)


def request_times(sim: SimDrives, monkeypatch) -> dict[int, list[float]]:
    """Monotonic s of every request each drive receives from now on (observed, passed through)."""
    times: dict[int, list[float]] = {1: [], 2: []}
    for dev, model in sim.models.items():
        real = model.note_request

        def note(dev=dev, real=real):
            times[dev].append(time.monotonic())
            real()

        monkeypatch.setattr(model, "note_request", note)
    return times


def longest_gap(times: list[float], t0: float, t1: float) -> tuple[float, float]:
    """(length s, start) of the longest silence in `times` within [t0, t1]."""
    ts = [t0] + [t for t in times if t0 <= t <= t1] + [t1]
    return max((b - a, a) for a, b in zip(ts, ts[1:]))


async def _defied(sim: SimDrives, monkeypatch, caplog, *, refuse: bool) -> tuple[dict[int, list[float]], float]:
    """Both drives at speed, then the spin drive defies the stop; returns the requests each drive
    received and the monotonic s of the stop, once the spin drive reads tripped at standstill."""
    caplog.set_level(logging.ERROR, logger="drives")
    async with open_rig(sim, LIMITS) as rig:
        await at_speed(rig)
        times = request_times(sim, monkeypatch)
        defy_stops(sim, 1, monkeypatch, refuse=refuse)
        t_stop = time.monotonic()
        if refuse:
            with pytest.raises(DriveError, match=r"spin drive \(id 1\), register CW"):
                await rig.stop(wait=False)
        else:
            await rig.stop(wait=False)
        assert sim.regs(2)["CW"] == 0x047E and sim.regs(1)["CW"] == 0x047F  # spin: still the run word
        await sim.wait_for(lambda: sim.regs(1)["FAULT"] == COMM_LOSS_FAULT, 5.0, "fault 7510 at the spin drive")
        await sim.wait_stopped(timeout=3.0)
        await sim.wait_for(lambda: "read again after" in caplog.text, 3.0, "the starved drive read again")
        with pytest.raises(DriveError):
            rig.check()
        monkeypatch.undo()  # the exit's stop reaches the spin drive again
    return times, t_stop


@pytest.mark.parametrize("refuse", [True, False], ids=["refused-03", "taken-ignored"])
async def test_a_drive_running_on_through_the_stop_is_stopped_by_its_starved_watchdog(sim, monkeypatch, caplog, refuse):
    times, t_stop = await _defied(sim, monkeypatch, caplog, refuse=refuse)
    t_trip = sim.models[1].comm_lost_after + WATCHDOG_S  # the spin drive's watchdog wall time
    gap, gap_start = longest_gap(times[1], t_stop, max(times[1]))
    starved = WATCHDOG_S + MARGIN_S + 2 * POLL_S
    assert starved - 0.05 <= gap <= starved + 1.0, f"spin drive left alone {gap:.2f} s, not about {starved:.2f} s"
    assert gap_start - t_stop < 1.0, f"starving began {gap_start - t_stop:.2f} s after the stop (bound 2 polls)"
    assert abs(sim.models[1].comm_lost_after - gap_start) < 0.05  # no request reached it during the gap
    orbit_gap, _ = longest_gap(times[2], gap_start, gap_start + gap)
    assert orbit_gap < 0.5, f"the orbit drive went {orbit_gap:.2f} s unpolled while the spin drive was starved"
    assert sim.regs(2)["FAULT"] == 0  # the orbit drive took its stop: never starved
    decision = [r.getMessage() for r in caplog.records if "watchdog (0.5 s) trips fault 7510" in r.getMessage()]
    assert decision and decision[0].startswith("spin drive (id 1), register COMM_LOSS_TIMEOUT (104): found "), decision
    assert ("missed" if refuse else "took") in decision[0]
    outcome = [r.getMessage() for r in caplog.records if "read again after" in r.getMessage()]
    assert len(outcome) == 1 and "fault 7510" in outcome[0] and "tripped by its comm-loss watchdog" in outcome[0]
    assert t_trip - gap_start == pytest.approx(WATCHDOG_S, abs=0.05)


async def test_a_drive_without_watchdog_running_on_is_said_unstoppable_at_once(tcp_sim, monkeypatch, caplog):
    """COMM_LOSS_TIMEOUT 0: starving would not stop it; the finding says so at once and the
    poll goes on addressing it (the stop sent again every poll)."""
    sim = tcp_sim
    caplog.set_level(logging.ERROR, logger="drives")
    async with open_rig(sim, LIMITS, comm_loss_timeout=0.0) as rig:
        await at_speed(rig)
        times = request_times(sim, monkeypatch)
        defy_stops(sim, 1, monkeypatch, refuse=True)
        t_stop = time.monotonic()
        with pytest.raises(DriveError):
            await rig.stop(wait=False)
        await sim.wait_for(lambda: "nothing over the network can stop it" in caplog.text, 2.0, "the finding")
        t_said = time.monotonic()
        await sim.wait_for(lambda: time.monotonic() > t_said + 0.5, 1.0, "half a second more")
        monkeypatch.undo()
    assert t_said - t_stop < 1.0
    gap, _ = longest_gap(times[1], t_stop, t_said + 0.5)
    assert gap < 0.5, f"the spin drive (no watchdog) went {gap:.2f} s unaddressed"
    said = [r.getMessage() for r in caplog.records if "nothing over the network" in r.getMessage()]
    assert said[0].startswith("spin drive (id 1), register COMM_LOSS_TIMEOUT (104): ")
    assert "its COMM_LOSS_TIMEOUT reads 0 (no watchdog)" in said[0] and "emergency stop" in said[0]
    assert sim.regs(1)["FAULT"] == 0 and sim.regs(1)["ACT"] != 0  # running on: only the rig's e-stop now


async def test_a_drive_ramping_down_at_a_zero_reference_is_not_starved(slow_drives, monkeypatch, caplog):
    """The spin drive refuses its stop word but takes REF 0: it follows it down its own ramp
    (about 0.6 s wall here) in operation, merely slowly; given that ramp from the speed read
    (DECEL_TIME x |ACT| / SPEED_SCALE) plus two polls, it is never starved: the poll keeps
    addressing it (the stop sent again every poll, as before) and no watchdog trips."""
    sim = slow_drives
    caplog.set_level(logging.ERROR, logger="drives")
    async with open_rig(sim, LIMITS, comm_loss_timeout=WATCHDOG_S) as rig:
        await at_speed(rig)
        times = request_times(sim, monkeypatch)
        model, real = sim.models[1], sim.models[1].write

        def refuse_cw(address, values):
            if address == CW:
                raise DriveModbusException(0x03, "refused by the test")
            real(address, values)

        monkeypatch.setattr(model, "write", refuse_cw)
        t_stop = time.monotonic()
        with pytest.raises(DriveError):
            await rig.stop(wait=False)
        took = await sim.wait_stopped(timeout=5.0)
        await sim.wait_for(lambda: time.monotonic() > t_stop + took + 0.5, 2.0, "half a second at standstill")
        assert sim.regs(1)["CW"] == CW_RUN and sim.regs(1)["FAULT"] == 0  # enabled at REF 0, not tripped
        gap, _ = longest_gap(times[1], t_stop, time.monotonic())
        monkeypatch.undo()
    assert took > 2 * POLL_S, f"the ramp took {took:.2f} s: not slow enough to tell"
    assert gap < 0.3, f"the spin drive went {gap:.2f} s unaddressed while ramping down"
    assert "comm-loss watchdog" not in caplog.text, caplog.text


async def test_a_drive_in_local_control_refusing_the_stop_is_said_unstoppable_after_starving(
    tcp_sim, monkeypatch, caplog
):
    """The spin drive taken to its keypad refuses the network's stop word (the simulator's keypad
    answers 03 until it gives control back): the simulator's keypad disarms its watchdog (the
    contract does not say), so starving it does not stop it; read again, it still runs, and the
    finding says nothing over the network can stop it."""
    sim = tcp_sim
    caplog.set_level(logging.ERROR, logger="drives")
    async with open_rig(sim, LIMITS) as rig:
        await at_speed(rig)
        sim.models[1].local_control(1000.0)  # someone at the drive: the poll stops both, the spin drive refuses
        await sim.wait_for(lambda: "read again after" in caplog.text, 5.0, "the starved drive read again")
        sim.models[1].hand_back()  # the operator gives it back: the rig's exit stops it
    decision = [r.getMessage() for r in caplog.records if "trips fault 7510" in r.getMessage()]
    assert decision and "in local control (SW REMOTE = 0: its watchdog may be disarmed)" in decision[0], decision
    outcome = [r.getMessage() for r in caplog.records if "read again after" in r.getMessage()][0]
    assert outcome.startswith("spin drive (id 1), register SW (3): read again after "), outcome
    assert "still running: its comm-loss watchdog did not stop it; nothing over the network can stop it" in outcome
    assert "use the rig's emergency stop" in outcome


@pytest.mark.parametrize("refuse", [True, False], ids=["refused-03", "taken-ignored"])
async def test_a_drive_running_on_while_the_operator_presses_stop_again_and_again_is_starved(
    sim, monkeypatch, caplog, refuse
):
    """What an operator does when a drive will not stop: press the emergency stop again and again,
    here every 5 ms (ten times a poll). Nearly every poll then meets a stop in flight, or reads
    before the last one ended; the drive is judged on its reads after the first stop all the
    same, and starved within about the same bound as with one stop (its watchdog trips 7510 and
    ramps it down): 4 s and more under load when only polls clear of stops counted."""
    caplog.set_level(logging.ERROR, logger="drives")
    async with open_rig(sim, LIMITS) as rig:
        await at_speed(rig)
        defy_stops(sim, 1, monkeypatch, refuse=refuse)
        t_stop, presses = time.monotonic(), 0
        while sim.regs(1)["FAULT"] != COMM_LOSS_FAULT and time.monotonic() < t_stop + 5.0:
            try:
                await rig.stop(emergency=True, wait=False)
            except DriveError:
                pass  # refused, or (starved) not sent to the spin drive: the operator presses on
            presses += 1
            await asyncio.sleep(PRESS_S)
        t_trip = time.monotonic()
        await sim.wait_for(lambda: "read again after" in caplog.text, 3.0, "the starved drive read again")
        monkeypatch.undo()
        await sim.wait_stopped(timeout=3.0)
        with pytest.raises(DriveError):
            rig.check()
    assert presses >= 5, presses  # again and again: about 100 idle, 10 with both cores busy (each press is a request)
    assert sim.regs(1)["FAULT"] == COMM_LOSS_FAULT, f"not starved in {t_trip - t_stop:.1f} s of stops pressed"
    bound = 2 * POLL_S + 3 * POLL_S + WATCHDOG_S  # judged over two polls (a few more met a stop in flight)
    # + 1.5 s for busy cores (1.92 s seen with both cores busy); counting only polls clear of stops took 4 s
    assert t_trip - t_stop < bound + 1.5, f"fault 7510 came {t_trip - t_stop:.2f} s after the first stop"


async def test_the_rig_closing_while_a_drive_is_starved_reads_it_again_first(sim, monkeypatch, caplog):
    """The command ends (the rig's exit) right after the spin drive's starving began: the exit
    waits for its watchdog and for the poll to read it again, the orbit drive polled on, so the
    run ends with the outcome said (tripped 7510, slowing), not with a drive left unread."""
    caplog.set_level(logging.WARNING, logger="drives")
    async with open_rig(sim, LIMITS) as rig:
        await at_speed(rig)
        times = request_times(sim, monkeypatch)
        defy_stops(sim, 1, monkeypatch, refuse=False)
        await rig.stop(wait=False)
        await sim.wait_for(lambda: "trips fault 7510" in caplog.text, 3.0, "the starving decided")
        t_exit = time.monotonic()
    t_closed = time.monotonic()
    outcome = [r.getMessage() for r in caplog.records if "read again after" in r.getMessage()]
    assert len(outcome) == 1 and "fault 7510" in outcome[0], caplog.text
    starved = WATCHDOG_S + MARGIN_S + 2 * POLL_S
    assert t_closed - t_exit < starved + 1.0, f"the exit took {t_closed - t_exit:.2f} s"
    orbit_gap, _ = longest_gap(times[2], t_exit, t_closed)
    assert orbit_gap < 0.5, f"the orbit drive went {orbit_gap:.2f} s unpolled while the exit waited"
    assert sim.regs(2)["FAULT"] == 0 and sim.regs(1)["FAULT"] == COMM_LOSS_FAULT

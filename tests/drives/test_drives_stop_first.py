"""A stop goes out first: its words go ahead of every request waiting for the drives'
link (drives/turns.py), and two stops never interleave on it (drives/stop.py
StopSender). The order is checked on the simulator's own records of the writes."""

from __future__ import annotations

import asyncio

import pytest
from support.drives_testkit import CW_EMERGENCY, CW_RAMP_STOP, CW_RUN, RPM, open_rig

from drives.drive import Drive
from drives.limits import DriveLimits
from drives.link import ModbusLink
from drives.stop import send_stop
from drives.turns import Turns

pytestmark = pytest.mark.timeout(30)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)


async def test_urgent_waiters_go_first_each_kind_in_order_and_a_cancelled_one_passes_its_turn():
    turns, order = Turns(), []

    async def one(name: str, urgent: bool) -> None:
        async with turns.turn(urgent):
            order.append(name)
            await asyncio.sleep(0)

    await turns.acquire()  # held: everyone below waits
    tasks = [
        asyncio.create_task(one(n, u))
        for n, u in (("poll-1", False), ("run", False), ("stop-cw", True), ("poll-2", False), ("stop-ref", True))
    ]
    cancelled = asyncio.create_task(one("cancelled", True))
    await asyncio.sleep(0.01)
    assert turns.waiting(True) == 3 and turns.waiting(False) == 3
    cancelled.cancel()
    turns.release()
    await asyncio.gather(*tasks)
    assert order == ["stop-cw", "stop-ref", "poll-1", "run", "poll-2"]
    assert not turns.locked() and turns.waiting(True) == turns.waiting(False) == 0


@pytest.mark.parametrize("sim", ["tcp", "rtu"], indirect=True)
async def test_stop_words_overtake_the_reads_queued_before_them(sim):
    sim.models[1].write(0, [CW_RUN])
    sim.models[2].write(0, [CW_RUN])
    async with ModbusLink(sim.url, timeout=0.5) as link:
        drives = [Drive(link, 1, "spin", bidirectional=False), Drive(link, 2, "orbit", bidirectional=True)]
        for d in drives:
            await d.read_parameters()
        reads = [asyncio.create_task(drives[i % 2].read_status()) for i in range(12)]
        await asyncio.sleep(0)  # the first read holds the link, the others wait for it
        errors = await send_stop(drives, emergency=True)
        done_before = sum(t.done() for t in reads)
        await asyncio.gather(*reads)
    assert errors == []
    assert done_before <= 1, f"{done_before} of 12 reads queued before the stop went first"
    assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_EMERGENCY


async def test_a_stop_asked_during_another_goes_out_after_it_not_interleaved(tcp_sim):
    sim = tcp_sim
    async with open_rig(sim, LIMITS) as rig:
        await rig.set_speeds(spin=600 * RPM, orbit=-300 * RPM)
        t_first = asyncio.get_running_loop().time()
        first = rig.stop_now(emergency=True)
        await rig.stop(emergency=True, wait=True, timeout=5.0)  # the cleanup's stop, right behind
        assert first.done() and first.result() == []
    words = {dev: [(t, cw) for t, cw in sim.models[dev].control_words if cw == CW_EMERGENCY] for dev in (1, 2)}
    assert len(words[1]) >= 2 and len(words[2]) >= 2, words
    # spin, orbit of the first stop, then spin, orbit of the second: never spin, spin, orbit, orbit
    assert words[1][0][0] < words[2][0][0] < words[1][1][0] < words[2][1][0], words
    assert words[1][0][0] >= t_first - 1.0


@pytest.mark.parametrize("wait", ["standstill", "setpoint"])
async def test_a_cancel_in_the_loop_step_of_a_poll_ends_the_wait_at_once(tcp_sim, wait):
    """An abort cancels the ramp stop's wait for standstill (or a wait for the setpoint) in the
    very loop step in which the poll publishes. The cancel must end the wait at once: Python
    3.11's asyncio.wait_for returned the tick and dropped it, so the emergency stop that follows
    an abort waited out the whole ramp (about 10 s here). The alignment of the two in one loop
    step is the one thing the real parts cannot be made to produce on demand."""
    # 2400 rpm to zero: 200 simulated s, 8 s wall; 0.3 s a request, 2 s watchdog: a busy host's polls
    # starved the 0.5 s watchdog (7510 on both), and the stop after the abort raised the trip
    rig = open_rig(tcp_sim, LIMITS, decel_time=250.0, timeout=0.3, comm_loss_timeout=2.0)
    async with rig:
        await rig.set_speeds(2400 * RPM, 600 * RPM)
        await rig.wait_settled(hold=0.1, timeout=20)
        if wait == "standstill":
            task = asyncio.create_task(rig.stop(emergency=False, wait=True, timeout=60))
            await tcp_sim.wait_for(lambda: tcp_sim.regs(1)["CW"] == CW_RAMP_STOP, 5, "the ramp stop delivered")
        else:
            await rig.set_speeds(1200 * RPM, 600 * RPM)  # a 4 s wall ramp to settle at
            task = asyncio.create_task(rig.wait_settled(hold=0.1, timeout=60))
            await asyncio.sleep(0)
        poll, publish = rig._poll, rig._poll.publish

        def publish_then_cancel(*args, **kw):  # the tick and the abort's cancel in one loop step
            publish(*args, **kw)
            task.cancel()

        poll.publish = publish_then_cancel
        try:
            done, _ = await asyncio.wait({task}, timeout=3.0)
        finally:
            poll.publish = publish
            task.cancel()
            await asyncio.gather(task, return_exceptions=True)
            await rig.stop(emergency=True, wait=True, timeout=20)
        assert done and task.cancelled(), "the cancel was dropped: the wait went on"


async def test_a_drive_whose_write_raises_an_unexpected_error_does_not_keep_the_stop_from_the_other(tcp_sim):
    """The spin drive's stop word fails with an error that is not a DriveError (termios.error
    from a line set up again): the orbit drive still gets its emergency stop, and the stop
    reports the spin drive's failure as a DriveError naming it."""
    import termios

    rig = open_rig(tcp_sim, LIMITS)
    async with rig:
        await rig.set_speeds(1000 * RPM, 500 * RPM)
        await rig.wait_settled(hold=0.1, timeout=20)
        real = rig.spin.write_control

        async def broken(word, **kw):  # what no real part produces on demand
            raise termios.error(5, "Input/output error")

        rig.spin.write_control = broken
        try:
            errors = await rig.stop_now(emergency=True)
            assert tcp_sim.regs(2)["CW"] == CW_EMERGENCY  # the orbit drive got its word
            assert len(errors) == 1 and errors[0].drive == 1 and "Input/output error" in str(errors[0]), errors
            assert "spin drive (id 1)" in str(errors[0])
        finally:
            rig.spin.write_control = real
            await rig.stop(emergency=True, wait=True, timeout=20)

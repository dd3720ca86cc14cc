"""The wait for standstill after a stop asks the poll for statuses, as the wait for the setpoint
does: one right after the stop command (drives at standstill already, as at the end of a run
whose last step stopped them), then every quarter interval until both read zero speed; it does
not wait for the poll's pace, up to an interval after the drives got there."""

from __future__ import annotations

import time

import pytest
from support.drives_testkit import RPM, open_rig

from drives.limits import DriveLimits

pytestmark = pytest.mark.timeout(30)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM, min_ratio=None, max_ratio=1.0)
POLL = 1.0  # s between polls at the pace: far longer than the waits below


async def test_a_stop_of_drives_at_standstill_is_confirmed_at_once_not_at_the_next_poll(tcp_sim):
    pace = 2.0  # s: the polls at the pace far apart, so that "at once" has a margin a busy machine keeps
    async with open_rig(tcp_sim, LIMITS, poll_interval=pace, timeout=0.3, comm_loss_timeout=2 * pace) as r:
        took = []
        for _ in range(3):
            t0 = time.monotonic()
            await r.stop(timeout=5)
            took.append(time.monotonic() - t0)
            assert r.state.stopped and r.state.time > t0
    # confirmed at the next paced poll instead, the second and third stops (right after the
    # first's confirming read) would each wait about `pace`; a stop at standstill is 4 writes and 2
    # reads, 126 ms at worst seen with 2 test workers and 4 busy processes on 2 cores, 0.47 s with
    # the machine's load average at 20
    assert max(took) < pace / 2, took


async def test_a_ramp_stop_is_confirmed_soon_after_standstill(tcp_sim):
    async with open_rig(tcp_sim, LIMITS, poll_interval=POLL, timeout=0.3, comm_loss_timeout=2 * POLL) as r:
        await r.set_speeds(600 * RPM, 300 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        t0 = time.monotonic()
        await r.stop(timeout=5)
        took = r.state.time - t0  # to the poll that read the standstill, not to this task's wake-up
        assert r.state.stopped and tcp_sim.regs(1)["ACT"] == tcp_sim.regs(2)["ACT"] == 0
    # the drives' ramp from 600 rpm: 1 s at 600 rpm/s, 0.04 s wall at the testkit's speed-up of 25,
    # then a quarter of the pace and the read asked (0.29 s in all, against 0.04 + 0.125 + 0.1, with
    # the pace at 0.5 s and a load of 15 to 21 on 2 cores); read at the pace instead, up to POLL later
    assert took < 0.04 + POLL / 4 + 0.25, took


async def test_a_stop_not_confirmed_never_gives_a_reading_from_before_it_for_the_present(tcp_sim, monkeypatch):
    """The orbit drive takes the stop word but answers every status read with Modbus exception 04
    (made on the simulator's side: its drives never fail so). The standstill cannot be confirmed;
    the error gives each drive as last read, before the stop, and says so: it gave the spin drive
    "running, ACT 600 rpm" as if read after the stop, while both drives were at rest."""
    from drives.errors import DriveTimeoutError
    from sim.drive_registers import DriveModbusException

    orbit, real = tcp_sim.models[2], tcp_sim.models[2].read
    failing = [False]

    def read(address, count):
        if failing[0] and count > 1:  # the status block (CW .. FAULT), not a write's echo of one word
            raise DriveModbusException(0x04, "device failure (made by the test)")
        return real(address, count)

    monkeypatch.setattr(orbit, "read", read)
    with pytest.raises(DriveTimeoutError) as caught:
        async with open_rig(tcp_sim, LIMITS) as r:
            await r.set_speeds(600 * RPM, 300 * RPM)
            await r.wait_settled(hold=0.05, timeout=5)
            failing[0] = True
            await r.stop(timeout=0.5)
    message, failing[0] = str(caught.value), False
    await tcp_sim.wait_stopped()  # both took the stop word: at rest
    assert "spin (id 1) running, REF 62.832 rad/s (600.0 rpm)" in message, message
    assert message.count("(not read since the stop: as read ") == 2, message
    assert "link down: orbit drive (id 2)" in message and "Modbus exception 04" in message, message

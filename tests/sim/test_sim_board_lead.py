"""The A/D board never trails the drives by more than its lead: a simulator that cannot keep up
slows its simulated time (the clock held) instead of letting frames lag the shaft."""

from __future__ import annotations

import asyncio
import math
import socket
import time

import pytest

from sim.clock import SimClock
from sim.scenario_files import scenario
from sim.rig import SimRig
from sim.slot_stream import LEAD_S
from support.sim_reader import parse, revolutions

SPIN = 150.0  # rad/s


def test_a_held_clock_stands_at_its_limit_and_runs_on_from_there():
    wall = [0.0]
    clock = SimClock(10.0, wall=lambda: wall[0])
    clock.hold(5.0)
    wall[0] = 1.0
    assert clock.now() == 5.0 and clock.lost == pytest.approx(5.0)  # 10 s would have run
    wall[0] = 2.0
    assert clock.now() == 5.0 and clock.lost == pytest.approx(15.0)
    clock.hold(8.0)
    assert clock.now() == 5.0  # continuous: it runs on from where it stood
    wall[0] = 2.2
    assert clock.now() == pytest.approx(7.0)
    wall[0] = 3.0
    assert clock.now() == 8.0 and clock.lost == pytest.approx(22.0)
    clock.hold(6.0)  # a limit below the time reached: the clock stands, never runs back
    wall[0] = 3.5
    assert clock.now() == 8.0
    clock.hold(math.inf)
    wall[0] = 4.0
    assert clock.now() == pytest.approx(13.0)


async def test_a_stalled_simulator_slows_its_time_and_its_board_stays_within_the_lead():
    """The simulator's loop blocked 0.5 s wall (20 s simulated at 40 x), twice: the drives' time
    stands at the board's last conversion + the lead meanwhile, and a reader that takes every
    byte the board has sent sees frames at most the lead (and the frame being filled) behind
    the drives' time; no frame is lost. Before, the drives' time ran on: 20 s behind."""
    speedup, orbit_hz = 40.0, 10.0
    frame_s = 45 / 360 / orbit_hz  # simulated s of one frame's slot edges
    async with SimRig(scenario("clean"), speedup=speedup, can_channel=None, adc_pty=False) as rig:
        rig.local_control(spin=SPIN, orbit=2 * math.pi * orbit_hz)
        sock = socket.create_connection(("127.0.0.1", rig.adc_server.port))
        sock.setblocking(False)
        buf, frames, lags, dropped, stalls = bytearray(), [], [], None, [0.8, 1.6]
        t0 = time.monotonic()
        try:
            while time.monotonic() - t0 < 2.5:
                await asyncio.sleep(0.005)
                if stalls and time.monotonic() - t0 > stalls[0]:
                    stalls.pop(0)
                    time.sleep(0.5)  # the loop held (a blocking call, a starved process)
                while True:  # every byte sent so far, at once
                    try:
                        chunk = sock.recv(1 << 20)
                    except BlockingIOError:
                        break
                    buf += chunk
                got, _, rest = parse(bytes(buf))
                del buf[:rest]
                frames += got
                if frames and dropped is None:  # frames made before the reader came were nobody's
                    dropped = rig.board.frames_lost
                if frames:
                    lags.append(rig.clock.now() - frames[-1].t_us * 1e-6)
        finally:
            sock.close()
        state = rig.state()
    assert max(lags) <= LEAD_S + 2 * frame_s + 1e-3
    assert state["board"]["longest_lag"] <= LEAD_S + 1e-9
    assert rig.clock.lost > 2 * (0.5 * speedup - LEAD_S) - 5.0  # the stalls' time not run
    assert state["board"]["frames_lost"] == dropped
    assert all(b.seq == (a.seq + 1) & 0xFFFF for a, b in zip(frames, frames[1:]))  # none lost, none twice
    assert not any(f.flags & 0x02 for f in frames[1:])  # no OVERRUN (the first says those made before it came)
    revs = revolutions(frames)
    assert not stalls and len(revs) >= 20 and all(b[0] == a[0] + 1 for a, b in zip(revs, revs[1:]))


def test_the_board_ticks_so_that_the_clock_runs_half_the_lead_between_two_ticks():
    rig = SimRig(scenario("clean"), speedup=400.0, can_channel=None, adc_pty=False)
    assert rig.stream.tick_period(0.01) == pytest.approx(0.5 * LEAD_S / 400.0)
    rig.clock.speedup = 20.0
    assert rig.stream.tick_period(0.01) == 0.01

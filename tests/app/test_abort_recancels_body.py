"""An abort ends the run even when its cancel of the run body is lost, on the real simulator.

Python 3.11's asyncio.wait_for swallows a cancel that comes in the loop step in which its
awaitable completes (the drives' reconnect had one): the body then goes on. A further abort
cancels it again, and the body itself ends at its next safe point, before commanding the
drives again. The lost cancel is the one fault injected: no real part loses one on demand."""

import asyncio
import time

import pytest

from support.sweep_helpers import running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(150)

# Spec control words, written out here (not imported from drives/) on purpose.
CW_RUN, CW_EMERGENCY = 0x047F, 0x047B


async def _cancel_lost(abort) -> None:
    """`abort()` comes in the step in which the awaited part completes; its cancel is swallowed
    there, as wait_for swallows it (the task's cancelling() count stays up, as wait_for leaves it)."""
    asyncio.get_running_loop().call_soon(abort)
    try:
        await asyncio.sleep(0)
    except asyncio.CancelledError:
        pass


def _words(sim, since: float) -> dict[int, list[int]]:
    """Each drive's control words written since `since` (monotonic, the simulator's clock too)."""
    return {dev: [cw for t, cw in sim.drive(dev)["control_words"] if t >= since] for dev in (1, 2)}


def _at_standstill(sim) -> bool:
    spin, orbit = sim.speeds
    return abs(spin) < 1.0 and abs(orbit) < 1.0 and all(abs(sim.drive(dev)["rpm"]) < 1.0 for dev in (1, 2))


async def test_a_further_abort_cancels_a_body_that_lost_the_first_cancel(tmp_path, monkeypatch):
    async with running(tmp_path, small_matrix(spin_rpm=[1000.0, 2000.0])) as (sim, eng, rec, run):
        await wait_for(lambda: rec.blocks_done() >= 2, 60, what="two blocks")
        drives, restarted = eng.io.drives, asyncio.Event()
        real = drives.set_speeds

        async def set_speeds(spin: float, orbit: float) -> None:
            """The next block's speeds: the abort comes as the link's reconnect completes."""
            monkeypatch.setattr(drives, "set_speeds", real)
            await _cancel_lost(lambda: eng.request_abort(by="ada"))
            await real(spin, orbit)
            restarted.set()

        monkeypatch.setattr(drives, "set_speeds", set_speeds)
        t1 = time.monotonic()
        await asyncio.wait_for(restarted.wait(), 30)
        blocks = rec.blocks_done()
        for dev, words in _words(sim, t1).items():  # the fault: the drives told to run after the abort's stop
            assert CW_EMERGENCY in words and words[-1] == CW_RUN, (dev, [hex(w) for w in words])
        t2 = time.monotonic()
        assert eng.request_abort(by="bob") is True
        outcome = await asyncio.wait_for(asyncio.shield(run), 30)
        took = time.monotonic() - t2
        assert _at_standstill(sim), (sim.speeds, sim.drive(1)["rpm"], sim.drive(2)["rpm"])
        after = _words(sim, t2)
    assert outcome.status == "aborted", outcome.message
    assert outcome.message.startswith("aborted by ada"), outcome.message  # the first abort's sender
    assert rec.blocks_done() == blocks  # cancelled in the settle: no block acquired after the aborts
    for dev, words in after.items():  # stopped, and never told to run again
        assert words and CW_RUN not in words and words[-1] == CW_EMERGENCY, (dev, [hex(w) for w in words])
    assert took < 15.0, took


async def test_a_body_that_lost_the_abort_cancel_does_not_command_the_drives_again(tmp_path, monkeypatch):
    async with running(tmp_path, small_matrix(spin_rpm=[1000.0, 2000.0])) as (sim, eng, rec, run):
        hands, made, aborted_at = eng.access.hands, [], []
        real = hands.set_manual

        async def set_manual(**settings: float) -> None:
            """The second point's manual settings (the drives turning): the abort comes as they are made."""
            await real(**settings)
            made.append(settings)
            if len(made) == 2:
                aborted_at.append(time.monotonic())
                await _cancel_lost(lambda: eng.request_abort(by="ada"))

        monkeypatch.setattr(hands, "set_manual", set_manual)  # before the run's body has begun
        outcome = await asyncio.wait_for(asyncio.shield(run), 90)
        assert aborted_at, "the abort was not sent"
        assert _at_standstill(sim), (sim.speeds, sim.drive(1)["rpm"], sim.drive(2)["rpm"])
        after = _words(sim, aborted_at[0])
    for dev, words in after.items():  # the emergency stop, and no speed command after it
        assert words and CW_RUN not in words and words[-1] == CW_EMERGENCY, (dev, [hex(w) for w in words])
    assert outcome.status == "aborted" and outcome.message.startswith("aborted by ada"), outcome.message
    assert "while stopping" not in outcome.message and outcome.completed_points == [0], outcome

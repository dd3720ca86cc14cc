"""A second signal while the first is being handled is not ignored: `run_until_signal` (as
`orbitrig calibrate` runs a step) cancels the step again, so a wait on its way out that the
first cancellation did not end (a prompt, a read) ends at once, and the command ends naming the
first signal. Real signals to this process."""

from __future__ import annotations

import asyncio
import os
import signal

import pytest

from orbitrig.cli.signals import Interrupted, run_until_signal

pytestmark = pytest.mark.timeout(120)
WAY_OUT_WAIT = 60.0  # s the way out would wait if nothing cut it short


def _step(seen: dict):
    """A step that waits; SIGTERM once it does; its way out waits again (up to WAY_OUT_WAIT s),
    and SIGINT once it does. `seen`: how that second wait ended."""

    async def step() -> None:
        loop = asyncio.get_running_loop()
        waiting = asyncio.Event()

        async def signal_when_waiting(sig: signal.Signals) -> None:
            await waiting.wait()
            waiting.clear()
            os.kill(os.getpid(), sig)

        loop.create_task(signal_when_waiting(signal.SIGTERM))
        try:
            waiting.set()
            await asyncio.Event().wait()  # the step's wait: the first signal cancels it
        finally:
            loop.create_task(signal_when_waiting(signal.SIGINT))
            waiting.set()
            try:
                await asyncio.wait_for(asyncio.Event().wait(), WAY_OUT_WAIT)
                seen["way out"] = "ended by itself"
            except asyncio.TimeoutError:
                seen["way out"] = f"waited {WAY_OUT_WAIT:g} s: the second signal was ignored"
            except asyncio.CancelledError:
                seen["way out"] = "cancelled by the second signal"
                raise

    return step


def test_a_second_signal_cancels_a_wait_the_first_did_not_end():
    seen: dict = {}
    with pytest.raises(Interrupted) as stopped:
        run_until_signal(_step(seen), "calibrate")
    assert seen == {"way out": "cancelled by the second signal"}, seen
    assert stopped.value.sig == signal.SIGTERM  # the first one
    assert str(stopped.value) == "SIGTERM"

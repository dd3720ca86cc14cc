"""A run cancelled during its closing ramp stop (its task cancelled: a fault elsewhere in the
service ends its task group, the service's bounded wait for it runs out): the cancellation is an
abort, as it is before the closing stop. The ramp stop becomes the emergency stop (OFF3) at once,
both drives are still waited for at standstill before the run's end is recorded, and the run ends
aborted, not 'drives not confirmed stopped' with nothing but a repeated ramp stop sent.

Real parts: the simulator in its own process (as `sweep --sim` runs it, at physical speed so that
the closing ramp lasts), the engine over Modbus TCP, the run's run.log."""

from __future__ import annotations

import asyncio
import time

import pytest

from orbitrig.run.states import STOPPING
from support.sweep_helpers import running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(120)

# Spec control words, written out here (not imported from drives/) on purpose.
CW_EMERGENCY = 0x047B


async def test_a_cancel_during_the_closing_ramp_stop_makes_it_the_emergency_stop_waited_for(tmp_path):
    async with running(tmp_path, small_matrix(spin_rpm=[2000.0]), speedup=1.0) as (sim, eng, rec, run):
        await wait_for(lambda: min(abs(w) for w in sim.speeds) > 50.0, 60, what="both drives turning")
        eng.request_stop_now("SIGTERM", by="test")
        await wait_for(lambda: eng.state == STOPPING, 10, what="the closing stop")
        await asyncio.sleep(0.3)
        assert max(abs(w) for w in sim.speeds) > 20.0, sim.speeds  # the closing ramp is under way
        t_cancel = time.monotonic()
        run.cancel()
        (outcome,) = await asyncio.wait_for(asyncio.gather(run, return_exceptions=True), 60)
        speeds_at_end = sim.speeds
        words = {dev: [cw for t, cw in sim.drive(dev)["control_words"] if t >= t_cancel] for dev in (1, 2)}
    assert speeds_at_end == (0.0, 0.0), speeds_at_end  # standstill waited for before the run ended
    for dev, after in words.items():
        assert CW_EMERGENCY in after, (dev, [hex(w) for w in after])
    assert not isinstance(outcome, BaseException), outcome
    assert outcome.status == "aborted", outcome.message
    assert "not confirmed" not in outcome.message, outcome.message
    text = (tmp_path / "run" / "run.log").read_text()
    assert "drives: emergency stop (OFF3)" in text, text
    assert text.index("drives: emergency stop (OFF3)") < text.rindex("aborted"), text

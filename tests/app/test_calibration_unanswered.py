"""A calibration prompt nobody can answer while the drives turn: standard input a pipe nobody
writes to (not a terminal, as an unattended sweep judges it), the step at its slow roll asking for
a load. After [interlocks] unanswered_pause_s the step fails saying so and both drives are stopped
and confirmed at standstill, as an unattended sweep's pause stops the run. (Before, the prompt
waited forever with the spindles turning.) A prompt at standstill keeps no such limit.

Real parts: the simulator in this process behind its real Modbus server and CAN node (python-can
`virtual` bus), a real pipe as standard input."""

from __future__ import annotations

import asyncio
import os
import sys
import time

import pytest

from orbitrig.cli.calibrate_steps import OperatorLoads
from orbitrig.cli.simulated_rig import simulated_access
from orbitrig.config import MPA, RPM, load_rig
from orbitrig.run.calibration import CalibrationSession, SlowRoll
from orbitrig.run.calibration_checks import CalibrationFailed

pytestmark = pytest.mark.timeout(60)

ROLL = SlowRoll(spin=600 * RPM, recess_pressure=0.4826 * MPA, pressure_ratio=0.25, revolutions=5)
LIMIT_S = 1.0  # [interlocks] unanswered_pause_s here (wall s)
ENDS_WITHIN_S = LIMIT_S + 4.0  # the limit, the emergency stop from 600 rpm, a loaded machine's margin


@pytest.fixture
def silent_stdin(monkeypatch):
    """Standard input a pipe nobody writes to (its write end held open until the test ends), read
    by a reader of the test's own (the read left waiting ends at EOF after the test, not in the
    next test's prompt)."""
    from orbitrig.cli import calibrate_prompt

    r, w = os.pipe()
    monkeypatch.setattr(sys, "stdin", os.fdopen(r, "r"))
    monkeypatch.setattr(calibrate_prompt, "STDIN", calibrate_prompt.StandardInput())
    yield
    os.close(w)  # a read still waiting ends at EOF


def _rig():
    rig = load_rig()
    return rig.model_copy(update={"interlocks": rig.interlocks.model_copy(update={"unanswered_pause_s": LIMIT_S})})


async def test_a_prompt_nobody_answers_at_the_slow_roll_stops_the_drives_after_the_limit(silent_stdin):
    from sim.rig import SimRig

    notes: list[str] = []
    async with SimRig(speedup=20, adc_pty=False) as sim_rig:
        session, hands = CalibrationSession(_rig(), simulated_access(sim_rig), notes.append), OperatorLoads()
        hands.watch(session)
        t0 = 0.0

        async def step() -> None:
            nonlocal t0
            async with session:
                await session.roll(ROLL)
                assert all(abs(w) > 0.9 * ROLL.spin for w in sim_rig.speeds), sim_rig.speeds
                t0 = time.monotonic()
                await session.watched(lambda: hands.apply_load(500.0, 0.0))

        task = asyncio.create_task(step())
        await asyncio.wait({task}, timeout=15.0 + ENDS_WITHIN_S)
        if not task.done():
            turning = sim_rig.speeds
            task.cancel()  # (its way out stops the drives)
            await asyncio.gather(task, return_exceptions=True)
            pytest.fail(f"the prompt still waited, the spindles at {turning} rad/s")
        took = time.monotonic() - t0
        with pytest.raises(
            CalibrationFailed, match=f"nobody confirmed within {LIMIT_S:g} s .* with the drives turning"
        ):
            task.result()
        assert LIMIT_S <= took < ENDS_WITHIN_S, took
        assert all(abs(w) < 1e-3 for w in sim_rig.speeds), sim_rig.speeds
    assert "both drives stopped" in notes, notes


async def test_a_prompt_at_standstill_keeps_no_limit(silent_stdin):
    from sim.rig import SimRig

    async with SimRig(speedup=20, adc_pty=False) as sim_rig:
        session, hands = CalibrationSession(_rig(), simulated_access(sim_rig)), OperatorLoads()
        hands.watch(session)
        async with session:
            asking = asyncio.ensure_future(hands.apply_load(0.0, 0.0))
            done, _ = await asyncio.wait({asking}, timeout=LIMIT_S + 1.0)
            asking.cancel()
            await asyncio.gather(asking, return_exceptions=True)
            assert not done, asking  # still waiting for the operator

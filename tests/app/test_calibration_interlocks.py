"""A calibration step's interlocks, by the sweep's rule (a suspension drops the block): the
lubricant supply lost (the pump off, the supply below its minimum) while the spindles turn fails
the step at once, not after [interlocks] supply_lost_timeout_s (its shipped 10 s); a lost CAN sensor
node as soon as a sweep suspends on it (1.5 s without its heartbeat), with can_heartbeat_timeout_s's
default of 10 s and a silence shorter than that: a record holds no reading taken without supply or
without the node's interlocks. Both drives get the emergency stop and are
confirmed at standstill, the error names the interlock (and the node's CAN id). With the node lost
before the slow roll, no spindle is started. A step may wait minutes at the slow roll (an operator's
prompt for the next load, an acquisition): nothing else stops the spindles turning without oil.

Real parts: the simulator in this process behind its real Modbus server and CAN node (python-can
`virtual` bus); the pump is switched off by the simulator's hands (recess pressure 0), the node's
heartbeat silenced through its fault injection."""

from __future__ import annotations

import asyncio
import time

import pytest

from daq.aux import LOST_AFTER
from orbitrig.cli.simulated_rig import simulated_access
from orbitrig.config import MPA, RPM, load_rig
from orbitrig.run.calibration import CalibrationSession, SlowRoll
from orbitrig.run.calibration_checks import CalibrationFailed

pytestmark = pytest.mark.timeout(120)

ROLL = SlowRoll(spin=600 * RPM, recess_pressure=0.4826 * MPA, pressure_ratio=0.25, revolutions=5)
LIMIT_S = 1.0  # [interlocks] supply_lost_timeout_s and can_heartbeat_timeout_s of these tests (wall s)
#: wall s from the cause to the step's end: the limit, the node's 1.5 s of silence before it counts as
#: lost, the emergency stop from 600 rpm (0.1 s wall at speed-up 20) and a loaded machine's margin
ENDS_WITHIN_S = LIMIT_S + 1.5 + 4.0
#: wall s from silencing the node to its loss, at the least: 1.5 s after its last heartbeat (every 0.5 s)
LOST_FROM_S = LOST_AFTER - 0.5
#: wall s from the supply lost to the step's end: the node's next frame (0.1 s), a poll interval, the
#: emergency stop from 600 rpm (0.1 s wall at speed-up 20) and a loaded machine's margin
SUPPLY_ENDS_S = 3.0
#: the node's heartbeat 0x701 lost, as the step's error says it (regex); said silent when a loaded host held
#: every frame of it 0.5 s at that moment
LOST_0X701 = r"(silent: )?no heartbeat 0x701 (for 1\.5 s|and no process data for \d+\.\d s)"
CW_EMERGENCY, CW_RUN = 0x047B, 0x047F  # spec control words (OFF3, run), written out on purpose
PROMPT_S = 60.0  # an operator's prompt nobody answers (wall s)


def _rig(**interlocks):
    rig = load_rig()
    quick = {"supply_lost_timeout_s": LIMIT_S, "can_heartbeat_timeout_s": LIMIT_S, **interlocks}
    return rig.model_copy(update={"interlocks": rig.interlocks.model_copy(update=quick)})


def _control_words(sim_rig) -> tuple[int, int]:
    return sim_rig.drives[1].read(0, 1)[0], sim_rig.drives[2].read(0, 1)[0]


async def _rolling_then_waiting(sim_rig, notes: list[str], rig=None) -> asyncio.Task[None]:
    """The step at the slow roll (on `rig`, default `_rig()`), waiting (watched, as every prompt and
    acquisition) for an answer that does not come; returned once both spindles turn."""
    session = CalibrationSession(rig or _rig(), simulated_access(sim_rig), notes.append)

    async def step() -> None:
        async with session:
            await session.roll(ROLL)
            await session.watched(lambda: asyncio.sleep(PROMPT_S))

    task = asyncio.create_task(step())
    deadline = time.monotonic() + 30.0
    while not any(n.startswith("slow roll:") for n in notes):
        assert not task.done() and time.monotonic() < deadline, (notes, task)
        await asyncio.sleep(0.02)
    assert all(abs(w) > 0.9 * ROLL.spin for w in sim_rig.speeds), sim_rig.speeds
    return task


async def _ends_stopped(task: asyncio.Task[None], sim_rig, t0: float, words: str) -> float:
    """The step's failure (naming `words`) and both drives emergency-stopped at standstill; the
    wall s from `t0` to the step's end."""
    await asyncio.wait({task}, timeout=ENDS_WITHIN_S + 10.0)
    took = time.monotonic() - t0
    if not task.done():
        turning = sim_rig.speeds
        task.cancel()  # (its way out stops the drives)
        await asyncio.gather(task, return_exceptions=True)
        pytest.fail(f"the step went on {took:.1f} s after the cause, the spindles at {turning} rad/s")
    with pytest.raises(CalibrationFailed, match=words):
        task.result()
    assert all(abs(w) < 1e-3 for w in sim_rig.speeds), sim_rig.speeds
    assert _control_words(sim_rig) == (CW_EMERGENCY, CW_EMERGENCY)
    return took


@pytest.mark.parametrize(
    "recess_pressure, named",
    [
        (0.0, "lubricant supply pump is off"),  # the pump off (the simulator's supply)
        (0.04 * MPA, r"supply pressure 0\.160 MPa outside the band 0\.2\.\.8 MPa"),  # 0.04 MPa / beta 0.25
    ],
    ids=["pump-off", "supply-low"],
)
async def test_the_supply_lost_at_the_slow_roll_fails_the_step_at_once_and_stops_both_drives(recess_pressure, named):
    """The shipped supply_lost_timeout_s (10 s): the step ends as a sweep drops its block, within
    SUPPLY_ENDS_S (it went on for the 10 s, its readings taken without supply)."""
    from sim.rig import SimRig

    notes: list[str] = []
    async with SimRig(speedup=20, adc_pty=False) as sim_rig:
        task = await _rolling_then_waiting(sim_rig, notes, _rig(supply_lost_timeout_s=10.0))
        t0 = time.monotonic()
        sim_rig.set_manual(recess_pressure=recess_pressure)  # the node's supply pressure follows
        said = f"interlock: {named} during the slow roll at spin 600 rpm, orbit 600 rpm: no calibration without"
        took = await _ends_stopped(task, sim_rig, t0, said)
        assert took < SUPPLY_ENDS_S, took
    assert "both drives stopped" in notes, notes


async def test_a_lost_can_node_at_the_slow_roll_fails_the_step_and_stops_both_drives():
    from sim.rig import SimRig

    notes: list[str] = []
    async with SimRig(speedup=20, adc_pty=False) as sim_rig:
        task = await _rolling_then_waiting(sim_rig, notes)
        t0 = time.monotonic()
        sim_rig.inject("can_heartbeat_loss", on=True)
        took = await _ends_stopped(task, sim_rig, t0, rf"interlock: CAN sensor node lost \({LOST_0X701}\)")
        assert LOST_FROM_S <= took < ENDS_WITHIN_S, took
    assert "both drives stopped" in notes, notes


async def test_no_spindle_starts_with_the_can_node_lost():
    """The node lost at standstill longer than can_heartbeat_timeout_s (the interlock failed, not
    only suspended): the error names the lasting loss and the node's heartbeat CAN id, and no slow roll
    it was said to happen during (it named no id, and 'during the slow roll at spin 600 rpm')."""
    from sim.rig import SimRig

    notes: list[str] = []
    async with SimRig(speedup=20, adc_pty=False) as sim_rig:
        sim_rig.inject("can_heartbeat_loss", on=True)
        session = CalibrationSession(_rig(), simulated_access(sim_rig), notes.append)
        said = r"interlock: CAN sensor node lost for more than 1 s \(.*heartbeat 0x701.*\): supply pressure and pump "
        with pytest.raises(CalibrationFailed, match=said + "are not watched$"):
            async with session:
                await asyncio.sleep(1.5 + LIMIT_S + 1.0)  # the operator sets the pressures meanwhile
                await session.roll(ROLL)
        assert max(abs(w) for w in sim_rig.speeds) == 0.0, sim_rig.speeds
        for drive in (1, 2):  # never commanded to run
            assert CW_RUN not in [cw for _, cw in sim_rig.drives[drive].control_words], sim_rig.drives[
                drive
            ].control_words


async def test_a_can_node_silent_shorter_than_its_timeout_fails_the_step_once_a_sweep_would_suspend():
    """The shipped can_heartbeat_timeout_s (10 s) and a silence of 3 s: the step ends at 1.5 s, as a
    sweep suspends and drops its block (it went on and wrote its record, or ran 10 s without the node)."""
    from sim.rig import SimRig

    notes: list[str] = []
    async with SimRig(speedup=20, adc_pty=False) as sim_rig:
        task = await _rolling_then_waiting(sim_rig, notes, _rig(can_heartbeat_timeout_s=10.0))
        t0 = time.monotonic()
        sim_rig.inject("can_heartbeat_loss", on=True)
        await asyncio.wait({task}, timeout=3.0)
        sim_rig.inject("can_heartbeat_loss", on=False)  # back before the 10 s
        took = await _ends_stopped(
            task,
            sim_rig,
            t0,
            rf"CAN sensor node lost \({LOST_0X701}\) during the slow roll at spin 600 rpm",
        )
        assert LOST_FROM_S <= took < 3.0 + 1.0, took
    assert "both drives stopped" in notes, notes

"""An A/D link drop in an attempt at a block that an interlock suspension then abandoned (the
simulator's close_adc_link mid-block over TCP; once the reader has data again, the supply pressure
out of its band): the
attempt's data is discarded and the block measured again after the suspension, and run.log and the
run's warnings say the drop once, as that attempt's, with the counts seen until then (it is not
said again as a drop before the next attempt, nor lost)."""

import asyncio
import re

import pytest

from orbitrig.run.engine import NoteEvent, NoteKind, ProgressEvent, Severity
from orbitrig.run.states import Outcome, RunState
from support.sweep_helpers import running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(150)

REVOLUTIONS = 600  # a block lasts a wall second and more at speed-up 40
SAID = re.compile(
    r"point 0000 \[(\w+)\]: A/D link dropped once during an attempt at the block that the suspension "
    r"abandoned: (\d+) frames lost, (\d+) revolutions dropped until then; the block is measured again"
)


def _under_way(rec) -> tuple[int, int]:
    """(block, good revolutions so far) of the latest progress event; (0, 0) before one."""
    prog = [e for e in rec.events if isinstance(e, ProgressEvent)]
    return (prog[-1].frequency, prog[-1].revolutions) if prog else (0, 0)


async def test_a_link_drop_in_an_attempt_a_suspension_abandoned_is_said_once(tmp_path):
    matrix = small_matrix(revolutions=REVOLUTIONS, spin_rpm=[1000.0])
    async with running(tmp_path, matrix) as (sim, eng, rec, run):
        await wait_for(lambda: _under_way(rec)[1] >= 30, 60, what="the first block under way")
        block = _under_way(rec)[0]
        sim.inject("close_adc_link", reopen_after=0.2)
        adc = eng.io.adc
        # back on the link: the frames the board sent meanwhile are counted lost, and the
        # revolutions they held dropped (a drop at a revolution's end loses none in progress)
        await wait_for(lambda: adc.link_drops >= 1 and adc.stats.frames_lost > 0, 10, what="the link back")
        sim.set_manual(pressure_ratio=0.05)  # supply = 0.4826 / 0.05 = 9.7 MPa > 8 MPa: suspended
        await wait_for(lambda: eng.state is RunState.PAUSED, timeout=10, what="the suspension")
        assert _under_way(rec)[0] == block  # the suspension came inside the block's attempt
        await asyncio.sleep(0.5)  # the link is back meanwhile
        sim.set_manual(pressure_ratio=0.4)
        outcome = await asyncio.wait_for(asyncio.shield(run), 120)
    assert outcome.status is Outcome.COMPLETED, outcome.message
    lines = (tmp_path / "run" / "run.log").read_text().splitlines()
    dropped = [line for line in lines if "A/D link dropped" in line]
    assert len(dropped) == 1 and (said := SAID.search(dropped[0])), dropped
    assert int(said.group(2)) >= 1 and int(said.group(3)) >= 1, said.group(0)  # counted until then
    suspended = next(i for i, line in enumerate(lines) if "suspended by interlock" in line)
    assert lines.index(dropped[0]) < suspended  # said as the attempt is abandoned, before the hold
    warnings = [e for e in rec.events if isinstance(e, NoteEvent) and e.severity is Severity.WARNING]
    assert [w.message for w in warnings if "A/D link" in w.message] == [said.group(0)], warnings
    assert [w.kind for w in warnings if "A/D link" in w.message] == [NoteKind.ADC_LINK_DROP]  # counted by kind

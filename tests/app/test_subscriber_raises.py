"""An event subscriber of the run engine that raises on every event it gets (a terminal's progress
bars, a publisher, a bug in either): logged with its traceback, the run goes on to its end and
both drives are ramped to zero, read at standstill from the simulated drives. Real parts: the
simulator in its own process, its drives over Modbus TCP; the bug is the test's."""

import asyncio
import logging

import pytest

from orbitrig.run.engine import ProgressEvent, StatusEvent
from support.sweep_helpers import running, small_matrix

pytestmark = pytest.mark.timeout(90)

CW_RAMP_STOP = 0x047E  # spec control word (OFF1), written out on purpose


async def test_a_subscriber_that_raises_on_every_event_disturbs_neither_the_run_nor_its_stop(tmp_path, caplog):
    seen = []

    def broken(ev):
        seen.append(type(ev))
        raise RuntimeError("progress bar bug")

    caplog.set_level(logging.ERROR, logger="orbitrig.run.engine")
    async with running(tmp_path, small_matrix(spin_rpm=[1000.0])) as (sim, eng, rec, run):
        eng.subscribe(broken)
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
        drives = sim.drive(1), sim.drive(2)
    assert outcome.status == "completed", outcome.message
    assert ProgressEvent in seen and StatusEvent in seen
    assert [d["control_word"] for d in drives] == [CW_RAMP_STOP, CW_RAMP_STOP]
    assert [d["rpm"] for d in drives] == [0, 0] and [d["fault"] for d in drives] == [0, 0]
    assert any(r.exc_info and r.getMessage() == "event subscriber failed" for r in caplog.records)
    assert "drives: ramp stop (OFF1); standstill after" in (tmp_path / "run" / "run.log").read_text()

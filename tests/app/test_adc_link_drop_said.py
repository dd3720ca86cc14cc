"""The A/D link dropped inside a block (the simulator's close_adc_link, mid-acquisition, over
TCP): the reader reconnects, the block completes, and run.log says so once, for that block, with
the counts its stored statistics hold; the engine's log (the console) says the same line. A drop
while no block is under way is said once, as the next block starts."""

import asyncio
import json
import logging
import re

import h5py
import pytest

from orbitrig.run.engine import ProgressEvent
from support.sweep_helpers import running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(120)

REVOLUTIONS = 600  # the first block lasts a wall second and more at speed-up 40
SAID = re.compile(
    r"point 0000 \[(\w+)\]: A/D link dropped once during the block: (\d+) frames lost, "
    r"(\d+) revolutions dropped \(([^)]*)\); the block averaged (\d+) good revolutions"
)


def _under_way(rec) -> tuple[int, int]:
    """(block, good revolutions so far) of the latest progress event; (0, 0) before one."""
    prog = [e for e in rec.events if isinstance(e, ProgressEvent)]
    return (prog[-1].frequency, prog[-1].revolutions) if prog else (0, 0)


async def test_a_link_drop_inside_a_block_is_said_once_for_that_block(tmp_path, caplog):
    caplog.set_level(logging.INFO, logger="orbitrig.run.engine")
    matrix = small_matrix(revolutions=REVOLUTIONS, spin_rpm=[1000.0])
    async with running(tmp_path, matrix) as (sim, eng, rec, run):
        await wait_for(lambda: _under_way(rec)[1] >= 30, 60, what="the first block under way")
        sim.inject("close_adc_link")
        assert _under_way(rec)[1] < REVOLUTIONS  # the block is still under way
        outcome = await asyncio.wait_for(asyncio.shield(run), 90)
    assert outcome.status == "completed", outcome.message
    lines = (tmp_path / "run" / "run.log").read_text().splitlines()
    said = [m for line in lines if (m := SAID.search(line))]
    assert len(said) == 1 and sum("A/D link" in line for line in lines) == 1, [ln for ln in lines if "A/D" in ln]
    tag, frames, revs, reasons, used = said[0].groups()
    assert int(used) == REVOLUTIONS and int(revs) >= 1, said[0].group(0)
    stats = {}
    for path in (tmp_path / "run" / "points" / "0000").glob("*_???.h5"):
        with h5py.File(path, "r") as f:
            stats[path.stem] = dict(f["stats"].attrs)
    assert len(stats) == 10 and [t for t, s in stats.items() if s["link_drops"]] == [tag], stats
    assert stats[tag]["link_drops"] == 1 and stats[tag]["frames_lost"] == int(frames) > 0, stats[tag]
    assert stats[tag]["revolutions_dropped"] == int(revs), stats[tag]
    assert reasons == ", ".join(f"{k} {v}" for k, v in sorted(json.loads(stats[tag]["drop_reasons"]).items()))
    assert sum(said[0].group(0) in r.getMessage() for r in caplog.records) == 1


async def test_a_link_drop_while_no_block_is_under_way_is_said_as_the_next_block_starts(tmp_path):
    async with running(tmp_path, small_matrix(revolutions=10), confirm_mode="remote") as (sim, eng, rec, run):
        await wait_for(lambda: eng.waiting_step == "manual:0000", what="the first point's settings")
        sim.inject("close_adc_link")
        eng.confirm("manual:0000")
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
    assert outcome.status == "completed", outcome.message
    lines = (tmp_path / "run" / "run.log").read_text().splitlines()
    said = [line for line in lines if "A/D link dropped" in line]
    assert len(said) == 1 and re.search(
        r"\[running\] point 0000 \[\w+\]: A/D link dropped once before the block \(no block under way", said[0]
    ), said
    first = next(i for i, line in enumerate(lines) if "speeds set" in line)
    assert lines.index(said[0]) > first  # said as the first block starts, not before the drives run

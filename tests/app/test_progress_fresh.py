"""Progress is never stale at the edges, on the real simulator: revolutions are throttled, but
every block's final count and every point's start are sent (a page waiting for a manual setting
shows the new point, not the last throttled count of the one before), and a block's end counts it
as measured in the run's fraction."""

import asyncio

import pytest

from orbitrig.run.engine import ProgressEvent
from support.sweep_helpers import running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(120)

REVOLUTIONS = 30


async def test_block_ends_and_point_starts_are_sent(tmp_path):
    matrix = small_matrix(revolutions=REVOLUTIONS, dynamic_eccentricity=[0.096, 0.12])  # two points, set by hand
    async with running(tmp_path, matrix, confirm_mode="remote") as (sim, eng, rec, run):
        await wait_for(lambda: eng.waiting_step == "manual:0000", what="the first manual setting")
        eng.confirm("manual:0000")
        await wait_for(lambda: eng.waiting_step == "manual:0001", timeout=60, what="the second point's setting")
        progress = [e for e in rec.events if isinstance(e, ProgressEvent)]
        # while the run waits for the second point's setting: that point, no block yet
        last = progress[-1]
        assert (last.point, last.points, last.frequency, last.revolutions) == (2, 2, 0, 0), last
        # every block of the first point: its last event carries its whole count
        final: dict[int, int] = {}
        for e in progress:
            if e.point == 1 and e.frequency >= 1:
                final[e.frequency] = e.revolutions
        assert sorted(final) == list(range(1, last.frequencies + 1)), final
        assert set(final.values()) == {REVOLUTIONS}, final
        # the first point's last event: its last block acquired, so half the run measured (not
        # its last block counted as unfinished); the target is the block's revolutions
        end = [e for e in progress if e.point == 1][-1]
        assert (end.frequency, end.block_revolutions, end.acquired) == (end.frequencies, REVOLUTIONS, True), end
        assert (end.blocks_done, end.fraction) == (end.frequencies, 0.5), end
        assert last.fraction == 0.5, last
        eng.request_abort()
        outcome = await asyncio.wait_for(run, 30)
    assert outcome.status == "aborted", outcome.message

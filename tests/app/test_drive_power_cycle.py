"""A drive power-cycled mid-point (a mains dip, its breaker; the simulator's drive_power_cycle:
it comes up switch-on inhibited with CW, REF and its parameters at their power-on values): the
other drive gets its stop word at the next poll, the run fails naming the drive and the register
and says it lost power, and the blocks stored before stay."""

import asyncio
import time

import pytest

from orbitrig import config as cfg
from support.sweep_helpers import first_stop, running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(90)

# Spec control words, written out here (not imported from drives/) on purpose.
STOP_WORDS = (0x047E, 0x047B)


async def test_a_drive_power_cycled_mid_point_fails_the_run_saying_it_lost_power(tmp_path):
    async with running(tmp_path, small_matrix(spin_rpm=[1000.0, 1500.0]), cfg.load_rig()) as (sim, eng, rec, run):
        await wait_for(lambda: rec.blocks_done() >= 2, 60, what="two blocks")
        measured, t = rec.blocks_done() - 1, time.monotonic()  # blocks started, less the one under way
        sim.inject("drive_power_cycle", drive=2)
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
        spin_stop = first_stop(sim, t, STOP_WORDS)
    assert outcome.status == "failed", outcome.message
    assert "orbit drive (id 2), register SW (3): is no longer running" in outcome.message, outcome.message
    assert "as after power-on: the drive lost power or was reset" in outcome.message, outcome.message
    assert spin_stop is not None and spin_stop < 1.0, spin_stop  # next poll: 0.1 s, margin for load
    assert len(list((tmp_path / "run" / "points" / "0000").glob("*_fwd.h5"))) >= measured >= 1

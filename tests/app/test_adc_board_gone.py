"""The A/D board gone mid-block (the simulator's adc_board_gone: nothing listens at its port).
An attempt waits for a board that sends nothing [averaging] timeout_margin_s + two revolutions
(+2 s wall), not the block's whole timeout; the block is settled and acquired again
[averaging] retries times, then the run fails with both drives stopped first, a message naming
the A/D board and how long it has been silent, and the blocks stored before kept. A board back
within that wait lets the block complete, its link drop said."""

import asyncio
import re
import time

import pytest

from orbitrig import config as cfg
from orbitrig.run.engine import ProgressEvent
from orbitrig.run.averaging import acquire_waits
from support.sweep_helpers import SPEEDUP, first_stop, running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(120)

STOP_WORDS = (0x047E, 0x047B)  # spec control words (OFF1, OFF3), written out on purpose
SILENT = re.compile(
    r"acquisition failed: the A/D board \(socket://127\.0\.0\.1:\d+\) has sent nothing for (\d+\.\d) s "
    r"\(its link is down: cannot connect"
)
AVERAGING = cfg.load_rig().averaging


def _waits(orbit: float, revolutions: int) -> tuple[float, float]:
    """Wall s an attempt waits at speed-up SPEEDUP: for the block, for a board that sends nothing."""
    return acquire_waits(AVERAGING, orbit, revolutions, lambda physical_s: physical_s / SPEEDUP)


def _under_way(rec) -> int:
    """Good revolutions so far in the block under way (the latest progress event)."""
    prog = [e for e in rec.events if isinstance(e, ProgressEvent)]
    return prog[-1].revolutions if prog else 0


async def test_a_board_gone_for_good_fails_the_run_naming_it_drives_stopped_first(tmp_path):
    async with running(tmp_path, small_matrix(revolutions=100)) as (sim, eng, rec, run):
        await wait_for(lambda: rec.blocks_done() >= 3, 60, what="three blocks")
        measured, t0 = rec.blocks_done() - 1, time.monotonic()
        sim.inject("adc_board_gone")
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
        took = time.monotonic() - t0
        stop = first_stop(sim, t0, STOP_WORDS)
        drives = sim.drive(1), sim.drive(2)
    assert outcome.status == "failed", outcome.message
    said = SILENT.search(outcome.message)
    assert said, outcome.message
    # every attempt (1 + retries) waited for the board, from the fault on: silent that long, at most `took`
    attempts = 1 + AVERAGING.retries
    assert attempts * 2.0 < float(said.group(1)) <= took + 0.1, (said.group(1), took)
    assert stop is not None and stop >= float(said.group(1)) - 0.5, stop  # no stop before it gave up
    assert [d["rpm"] for d in drives] == [0, 0] and [d["fault"] for d in drives] == [0, 0]
    assert len(list((tmp_path / "run" / "points" / "0000").glob("*_???.h5"))) >= measured >= 2
    log = (tmp_path / "run" / "run.log").read_text().splitlines()
    tries = [i for i, line in enumerate(log) if "[running]" in line and SILENT.search(line)]
    stopped = next(i for i, line in enumerate(log) if "drives:" in line and "standstill" in line)
    assert len(tries) == attempts and tries[-1] < stopped < len(log) - 1, log[-10:]
    assert outcome.message in log[-1]


async def test_a_long_block_gives_up_on_a_gone_board_long_before_its_timeout(tmp_path):
    revolutions = 3000  # the first block (orbit +1200 rpm) lasts 3.75 s wall: its timeout over 13 s
    orbit = 1200 * 2 * 3.141592653589793 / 60
    timeout, silence = _waits(orbit, revolutions)
    async with running(tmp_path, small_matrix(revolutions=revolutions)) as (sim, eng, rec, run):
        await wait_for(lambda: _under_way(rec) >= 30, 60, what="the first block under way")
        t0 = time.monotonic()
        sim.inject("adc_board_gone")
        outcome = await asyncio.wait_for(asyncio.shield(run), 90)
        took = time.monotonic() - t0
    assert outcome.status == "failed" and SILENT.search(outcome.message), outcome.message
    assert timeout > 13.0 and took < timeout, (took, timeout)  # both attempts within one attempt's timeout
    assert 2.0 < silence < 2.2 and took > (1 + AVERAGING.retries) * silence - 0.2, (took, silence)


async def test_a_board_back_within_the_wait_lets_the_block_complete(tmp_path):
    async with running(tmp_path, small_matrix(revolutions=600)) as (sim, eng, rec, run):
        await wait_for(lambda: _under_way(rec) >= 30, 60, what="the first block under way")
        sim.inject("adc_board_gone", back_after=0.5)
        await wait_for(lambda: rec.blocks_done() >= 2, 30, what="the next block")  # the first one stored
        eng.request_stop("test")
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
    assert outcome.status == "stopped", outcome.message
    blocks = list((tmp_path / "run" / "points" / "0000").glob("*_???.h5"))
    log = (tmp_path / "run" / "run.log").read_text()
    said = re.findall(r"\[(\w+)\]: A/D link dropped once during the block: (\d+) frames lost", log)
    assert len(said) == 1 and int(said[0][1]) > 0 and said[0][0] in {b.stem for b in blocks}, log[-2000:]
    assert not SILENT.search(log)  # back within the wait: no attempt failed

"""A run's closing stop while the drives' Modbus link is silent (a switch restarting, a cable
pulled and put back): the stop word a drive did not take for a reason that may pass (no answer,
a connection broken or refused) is sent again until it is taken or the stop's time is out
(drives/stop_again.py), for as long as the drives' comm-loss watchdog + 1 s. A link back within
that time: both drives take the word, the stop is confirmed at standstill and the run ends as it
was ending, run.log saying the word went again; it ended failed, "drives not confirmed stopped",
after three tries of 0.15 s. A link that never comes back: the run fails "drives not confirmed
stopped" once that time is out, the message saying the word was sent again and not taken, the
drives stopped by their own watchdog.

Real parts: the simulator in its own process, its drives behind its Modbus TCP server; the
silence is its `modbus_timeout` fault (both drives stop answering). The shipped link (0.15 s a
request), the drives' watchdog 5 s so that the silence is the link's, not a watchdog trip."""

import asyncio
import time

import pytest

from orbitrig.config import load_rig
from support.drives_testkit import CW_RAMP_STOP
from support.paths import ROOT
from support.sweep_helpers import running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(90)

SILENT_S = 2.5  # wall s: longer than the tries of the abort's first words and the closing stop's
# (three of 0.15 s a drive each, about 2 s), shorter than the drives' watchdog (5 s)


WATCHDOG_S = 5.0


def _rig():
    rig = load_rig(ROOT / "config" / "rig.toml")
    drives = rig.drives.model_copy(update={"comm_loss_timeout_s": WATCHDOG_S})
    return rig.model_copy(update={"drives": drives})


async def test_a_link_silent_for_a_moment_under_the_closing_stop_is_waited_out(tmp_path):
    matrix = small_matrix(revolutions=3000, spin_rpm=[1000.0])
    async with running(tmp_path, matrix, _rig(), speedup=10.0) as (sim, eng, rec, run):
        await wait_for(lambda: rec.blocks_done() >= 1, 60, what="a block")
        sim.inject("modbus_timeout", on=True)
        eng.request_stop_now("SIGTERM", by="test")
        await asyncio.sleep(SILENT_S)
        assert not run.done()
        sim.inject("modbus_timeout", on=False)
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
        drives = [sim.drive(dev) for dev in (1, 2)]
    assert outcome.status == "stopped", outcome.message
    assert outcome.message.startswith("stopped at once by SIGTERM")
    for d in drives:  # the word taken, at standstill, no watchdog trip
        assert (d["control_word"], d["rpm"], d["fault"]) == (CW_RAMP_STOP, 0.0, 0), d
    log = (tmp_path / "run" / "run.log").read_text()
    line = next((ln for ln in log.splitlines() if "drives: ramp stop (OFF1) (sent again " in ln), log[-2000:])
    assert "no answer within 0.15 s" in line and ": taken by both); standstill after " in line, line
    assert "spin ACT 0 rpm, fault 0; orbit ACT 0 rpm, fault 0" in line, line


async def test_a_link_that_stays_silent_fails_the_run_saying_the_word_was_not_taken(tmp_path):
    matrix = small_matrix(revolutions=3000, spin_rpm=[1000.0])
    async with running(tmp_path, matrix, _rig(), speedup=10.0) as (sim, eng, rec, run):
        await wait_for(lambda: rec.blocks_done() >= 1, 60, what="a block")
        sim.inject("modbus_timeout", on=True)
        t0 = time.monotonic()
        eng.request_stop_now("SIGTERM", by="test")
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
        took = time.monotonic() - t0
        drives = [sim.drive(dev) for dev in (1, 2)]
    assert outcome.status == "failed", outcome.message
    assert outcome.message.startswith("drives not confirmed stopped: DriveTimeoutError: "), outcome.message
    assert "no answer within 0.15 s" in outcome.message
    assert ", not taken)" in outcome.message and "(the stop word sent again " in outcome.message
    for d in drives:  # no word reached them: their own watchdog stopped them (7510), not the run
        assert d["fault"] == 7510 and d["control_word"] != CW_RAMP_STOP, d
    assert WATCHDOG_S < took < 30.0, took  # past the watchdog, well before the stop's wait (30 s + 5 s)

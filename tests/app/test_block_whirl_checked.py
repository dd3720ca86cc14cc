"""A block whose measured orbit turns against the whirl it asks for is not kept: the simulator's
orbit motor wired reversed (orbit_wired_reversed: the drive reads as commanded, only the probes
show it) fails each attempt, settled and acquired again [averaging] retries times, then the run
fails with both drives stopped first and the words of the whirl; wired right again between two
attempts, the block is acquired again and every stored block turns the way its name says."""

import asyncio
import re

import pytest

import orbitrig
from orbitrig import config as cfg
from orbitrig.run.events import NoteEvent, Severity
from support.sweep_helpers import first_stop, running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(120)

STOP_WORDS = (0x047E, 0x047B)  # spec control words (OFF1, OFF3), written out on purpose
WRONG = re.compile(
    r"point 0000 \[(\d\d)_(fwd|bwd)\]: acquisition failed: the measured orbit turns (forward|backward) "
    r"\(whirl sense ([+-]\d\.\d\d)\), the block asks (forward|backward) whirl"
)


def _whirl_warnings(rec) -> list[re.Match]:
    return [
        m
        for e in rec.events
        if isinstance(e, NoteEvent) and e.severity is Severity.WARNING and (m := WRONG.search(e.message))
    ]


async def test_an_orbit_turning_against_its_drive_fails_the_run_drives_stopped_first(tmp_path):
    rig = cfg.load_rig()
    async with running(tmp_path, small_matrix(revolutions=20), rig) as (sim, eng, rec, run):
        sim.inject("orbit_wired_reversed")
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
        drives = sim.drive(1), sim.drive(2)
        stopped = first_stop(sim, 0.0, STOP_WORDS)
    assert outcome.status == "failed", outcome.message
    said = WRONG.search(outcome.message)
    assert said, outcome.message
    # the first block (the highest ratio, forward) measured backward, as clear as a circle is
    assert said.groups()[1:3] == ("fwd", "backward") and float(said.group(4)) < -0.9, said.group(0)
    assert said.group(5) == "forward"
    assert len(_whirl_warnings(rec)) == rig.averaging.retries  # each retried attempt a warning
    assert stopped is not None and [d["rpm"] for d in drives] == [0, 0]
    assert not list((tmp_path / "run" / "points" / "0000").glob("*_???.h5"))  # nothing stored under a wrong name
    log = (tmp_path / "run" / "run.log").read_text().splitlines()
    standstill = next(i for i, line in enumerate(log) if "drives:" in line and "standstill" in line)
    assert standstill < len(log) - 1 and outcome.message in log[-1]


async def test_an_orbit_wired_right_again_between_attempts_is_acquired_again(tmp_path):
    base = cfg.load_rig()
    rig = base.model_copy(update={"averaging": base.averaging.model_copy(update={"retries": 10})})
    async with running(tmp_path, small_matrix(revolutions=20), rig) as (sim, eng, rec, run):
        sim.inject("orbit_wired_reversed")
        await wait_for(lambda: _whirl_warnings(rec), 60, what="an attempt refused for its whirl")
        sim.inject("orbit_wired_reversed", on=False)
        outcome = await asyncio.wait_for(asyncio.shield(run), 90)
    assert outcome.status == "completed", outcome.message
    assert 1 <= len(_whirl_warnings(rec)) <= 10
    table = orbitrig.open_run(tmp_path / "run").table(0)
    assert sorted(table.block) == sorted(f"{i:02d}_{d}" for i in range(5) for d in ("fwd", "bwd"))
    assert all(d == (1 if b.endswith("fwd") else -1) for b, d in zip(table.block, table.direction))

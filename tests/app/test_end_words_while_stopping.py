"""The end message of a run an abort or a cancellation makes aborted in its closing stop is built
once, right, where it is made (orbitrig.run.ending.while_stopping): how it was ending, but not a
completed run's own words; 'all points completed; ' is said ahead of it only where the store shows
every planned point complete (orbitrig.run.ending.asked_end), never when the plan's points are not
known. Before, the closing said 'aborted by ada while stopping (all points completed)' and the end
record cut those words out again; a run whose plan was not known kept the claim.

Real parts: a run's store with its one point of 8 blocks written and committed (run.h5 recorded)."""

from __future__ import annotations

import ast

import pytest

from drives import registers as R
from drives.drive import DriveStatus
from drives.rig import StopTripError
from orbitrig.run.ending import record_the_end, while_stopping
from orbitrig.run.safe_stop import tripped_in_closing_stop
from orbitrig.run.states import ABORTED, ALL_COMPLETED, COMPLETED, STOPPED
from orbitrig.store.reader import read_run
from support.paths import ROOT
from support.store_commits import commit_points

SPIN_TRIPPED = DriveStatus("spin", 1, R.CW_RAMP_STOP, 0.0, int(R.SWBit.TRIPPED), 0.0, 0.0, 2310, 1.0)
TRIP = StopTripError((SPIN_TRIPPED,), stop="ramp stop (OFF1)", standstill=True, end="at standstill")


def test_the_closing_says_how_the_run_was_ending_without_a_completed_runs_words():
    assert (
        while_stopping("aborted by ada (Ctrl-C)", COMPLETED, ALL_COMPLETED) == "aborted by ada (Ctrl-C) while stopping"
    )
    assert while_stopping("run cancelled", COMPLETED, ALL_COMPLETED) == "run cancelled while stopping"
    assert (
        while_stopping("aborted by ada", STOPPED, "stopped by bob") == "aborted by ada while stopping (stopped by bob)"
    )
    # a drive tripped in the closing stop of a completed run an abort arrived in: the trip, said once
    status, tripped = tripped_in_closing_stop(COMPLETED, ALL_COMPLETED, TRIP, aborting=True)
    said = while_stopping("aborted by ada", status, tripped)
    assert said.startswith("aborted by ada while stopping (drive tripped during the closing stop (fault 2310"), said
    assert ALL_COMPLETED not in said, said


@pytest.mark.parametrize(
    ("planned", "message"),
    [
        ({0: 8}, "all points completed; aborted by ada while stopping"),
        ({}, "aborted by ada while stopping"),  # the plan's points not known: no claim
    ],
    ids=["every-point-complete", "plan-not-known"],
)
def test_the_end_record_says_all_points_completed_only_where_the_store_shows_it(tmp_path, planned, message):
    store = commit_points(tmp_path / "run", 1)
    failures: list[str] = []
    ended = record_the_end(
        store,
        store.run_id,
        ABORTED,
        while_stopping("aborted by ada", COMPLETED, ALL_COMPLETED),
        lambda what, err: failures.append(what),
        planned,
    )
    assert ended == (ABORTED, message) and not failures, (ended, failures)
    stored = read_run(tmp_path / "run")
    assert (str(stored.status), stored.status_message) == ("aborted", message)
    assert f"ended: aborted: {message}\n" in (tmp_path / "run" / "run.log").read_text()


def _written(path, words: str) -> list[int]:
    """Lines of ``path`` whose code (docstrings and other bare strings left out) writes ``words``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    said = {id(n.value) for n in ast.walk(tree) if isinstance(n, ast.Expr)}
    return [
        n.lineno
        for n in ast.walk(tree)
        if isinstance(n, ast.Constant) and isinstance(n.value, str) and words in n.value and id(n) not in said
    ]


def test_a_completed_runs_words_have_one_owner():
    """'all points completed' is written by orbitrig.run.states.ALL_COMPLETED only: the engine's
    end, the end of a stop or abort with every point complete (ending) and a resume that only
    consolidated run.h5 (run_dir) all take it from there."""
    found = [
        f"{p.relative_to(ROOT)}:{line}"
        for p in sorted((ROOT / "orbitrig").rglob("*.py"))
        for line in _written(p, ALL_COMPLETED)
    ]
    assert [where.split(":")[0] for where in found] == ["orbitrig/run/states.py"], found

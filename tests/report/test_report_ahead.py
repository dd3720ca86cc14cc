"""Figures drawn during the sweep (orbitrig.analysis.report_ahead): what the drawing process
draws of a point the report reuses; the real process runs at the lowest CPU priority, ends with
`close` and never blocks the caller. (Its drawing is not awaited here: at SCHED_IDLE it gets no
processor while the suite keeps both busy.)"""

from __future__ import annotations

import os
import shutil
import time

import pytest

from orbitrig.analysis.report import ReportOptions, make_report
from orbitrig.analysis.report_ahead import FiguresAhead, draw_ahead
from orbitrig.analysis.report_cache import CACHE_DIR

KINDS = frozenset({"coherence", "lms"})  # two of the cheaper kinds: a point in about a second


@pytest.fixture()
def running(synthetic_run, tmp_path):
    """A copy of the session's synthetic run (points 0 and 1 complete, 2 not), without plots."""
    run = shutil.copytree(synthetic_run, tmp_path / "run")
    shutil.rmtree(run / "plots", ignore_errors=True)
    return run


def _figures(run):
    return {p.name: p.stat().st_mtime_ns for p in (run / "plots").glob("*.png")}


def test_points_drawn_ahead_are_reused_by_the_report(running):
    assert draw_ahead(running, 1, KINDS)  # what the process does with each index it reads
    drawn = _figures(running)
    assert sorted(drawn) == ["coherence_0001.png", "lms_0001.png"]
    assert sorted(p.name for p in (running / "plots" / CACHE_DIR).iterdir()) == ["0001.json"]
    report = make_report(running, options=ReportOptions(figures=KINDS))
    after = _figures(running)
    assert {name: after[name] for name in drawn} == drawn  # reused, not drawn again
    assert sorted(after) == ["coherence_0000.png", "coherence_0001.png", "lms_0000.png", "lms_0001.png", "summary.png"]
    assert [len(pr.plots) for pr in report.points] == [2, 2]


def test_the_drawing_process_runs_at_the_lowest_priority_and_ends_with_close(running):
    ahead = FiguresAhead(running)  # every kind: still drawing when closed
    ahead.point_complete(0)
    pid = ahead.pid
    deadline = time.monotonic() + 30

    def lowest() -> tuple[int, int]:
        return os.getpriority(os.PRIO_PROCESS, pid), os.sched_getscheduler(pid)

    while lowest() != (19, os.SCHED_IDLE) and time.monotonic() < deadline:
        time.sleep(0.05)  # the process sets both itself: at SCHED_IDLE on a busy machine that may take a while
    assert lowest() == (19, os.SCHED_IDLE)
    ahead.close()  # at once: the point being drawn keeps no record, the report draws it
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)
    assert not (running / "plots" / CACHE_DIR / "0000.json").exists()
    assert ahead.pid is None


def test_an_index_the_process_cannot_take_is_dropped_without_blocking(running):
    ahead = FiguresAhead(running, KINDS)
    ahead.point_complete(0)
    os.kill(ahead.pid, 9)
    os.waitpid(ahead.pid, 0)
    t0 = time.monotonic()
    ahead.point_complete(1)  # a broken pipe: the report will draw point 1
    assert time.monotonic() - t0 < 0.5
    assert ahead.dropped == [1]
    ahead.close()


def test_an_incomplete_or_missing_point_is_not_drawn(running):
    assert not draw_ahead(running, 2, KINDS)
    assert not draw_ahead(running, 7, KINDS)
    assert not draw_ahead(running / "nothing", 0, KINDS)
    assert not (running / "plots").exists() or not _figures(running)

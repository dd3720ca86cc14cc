"""The sweep's status lines at the operator's terminal: the time and the state's message, not
the source file and line that printed them."""

from __future__ import annotations

import io
import re

from orbitrig.cli.progress import SweepProgress
from orbitrig.cli.terminal import TerminalConsole
from orbitrig.run.engine import ResultEvent, StatusEvent
from orbitrig.run.states import RunState


def test_status_lines_carry_no_source_location():
    out = io.StringIO()
    console = TerminalConsole(file=out, width=140, force_terminal=False)
    with SweepProgress(console) as progress:
        progress(
            StatusEvent(
                RunState.PAUSED, "r1", "2026-12-02T00:00:00Z", "paused at a safe point (drives keep their speeds)"
            )
        )
    lines = [ln for ln in out.getvalue().splitlines() if "paused:" in ln]
    assert len(lines) == 1 and "paused: paused at a safe point (drives keep their speeds)" in lines[0]
    assert ".py" not in lines[0]


def test_bars_only_when_something_was_measured():
    """A resumed run whose every point was done measures nothing: no bars left at 0 of 1."""
    from orbitrig.run.engine import ProgressEvent

    def shown(events) -> str:
        out = io.StringIO()
        with SweepProgress(TerminalConsole(file=out, width=140, force_terminal=False)) as progress:
            for ev in events:
                progress(ev)
        return out.getvalue()

    assert "points" not in shown([StatusEvent(RunState.IDLE, "r1", "2026-12-02T00:00:00Z", "completed")])
    measured = shown([ProgressEvent("r1", 1, 2, 1, 10, 5, 30.0)])
    assert "points" in measured and "orbit blocks" in measured and "ETA" in measured


def test_eta_says_paused_while_the_run_is_paused_and_runs_again_after():
    """An operator's pause (or an interlock's) holds the rig time left as a setting's wait does;
    the ETA says so until the run goes on, and a progress during the hold keeps the words."""
    from orbitrig.run.engine import ProgressEvent

    progress = SweepProgress(TerminalConsole(file=io.StringIO(), width=140, force_terminal=False))
    progress(ProgressEvent("r1", 1, 2, 3, 10, 5, 750.0))
    assert progress.eta() == "ETA 12:30"
    progress(StatusEvent(RunState.PAUSED, "r1", "2026-12-02T00:00:00Z", "paused at a safe point"))
    assert progress.eta() == "ETA 12:30 (paused with the run)"
    progress(ProgressEvent("r1", 1, 2, 3, 10, 10, 745.0))  # a block's last revolutions, sent at the hold
    assert progress.eta() == "ETA 12:25 (paused with the run)"
    progress(StatusEvent(RunState.RUNNING, "r1", "2026-12-02T00:01:00Z", "resumed"))
    assert progress.eta() == "ETA 12:25"


def test_a_completed_point_is_logged_by_its_name():
    """The line of a completed point names it as the run's files do (store.layout.point_name)."""
    from orbitrig.run.engine import ResultEvent
    from orbitrig.store.layout import point_name

    out = io.StringIO()
    with SweepProgress(TerminalConsole(file=out, width=140, force_terminal=False)) as progress:
        progress(ResultEvent("r1", {"point": 3, "label": "w1000rpm_p0.48MPa"}))
    lines = [ln for ln in out.getvalue().splitlines() if "complete" in ln]
    assert len(lines) == 1 and f"point {point_name(3)} w1000rpm_p0.48MPa complete" in lines[0], lines
    assert point_name(3) == "0003"


def test_a_warning_note_is_one_line_and_a_routine_note_none():
    """The run's warnings (something gone wrong it survived) are log lines as the states are; its
    routine notes (speeds set) stay in run.log."""
    from orbitrig.run.engine import NoteEvent, Severity

    out = io.StringIO()
    dropped = "point 0000 [04_fwd]: A/D link dropped once during the block: 217 frames lost"
    with SweepProgress(TerminalConsole(file=out, width=200, force_terminal=False)) as progress:
        progress(NoteEvent("r1", Severity.INFO, "speeds set: spin 1000 rpm, orbit +300 rpm"))
        progress(NoteEvent("r1", Severity.WARNING, dropped))
    lines = [ln.rstrip() for ln in out.getvalue().splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].endswith(f"warning: {dropped}"), lines
    assert re.match(r"\[\d\d:\d\d:\d\d\] warning: ", lines[0]), lines


def test_the_orbit_blocks_bar_counts_a_block_acquired():
    """A block whose acquisition is done is counted on the orbit blocks bar at once (the event's
    blocks_done, as the dashboard's bar counts it), and the revolutions bar ends at the block's target."""
    from orbitrig.run.engine import ProgressEvent

    progress = SweepProgress(TerminalConsole(file=io.StringIO(), width=140, force_terminal=False))
    progress(ProgressEvent("r1", 1, 3, 4, 4, 20, 30.0, "w1000rpm", 40))
    bars = {t.description: (t.completed, t.total) for t in progress.progress.tasks}
    assert bars["orbit blocks"] == (3, 4) and bars["revolutions"] == (20, 40), bars
    progress(ProgressEvent("r1", 1, 3, 4, 4, 40, 25.0, "w1000rpm", 40, acquired=True))
    bars = {t.description: (t.completed, t.total) for t in progress.progress.tasks}
    assert bars["orbit blocks"] == (4, 4) and bars["revolutions"] == (40, 40), bars


def test_a_resumed_run_counts_the_points_measured_before_it():
    """A run of 5 resumed with 2 points left starts at 3 of 5 done, on the terminal's bar and in the
    progress MQTT sends (point 4 of 5, fraction 0.6), not at 0 of 2."""
    import json

    from orbitrig.run.events import ProgressEvent
    from orbitrig.run.progress import ProgressMeter
    from orbitrig.run.rig_io import TimeScale
    from orbitrig.service.protocol import progress_payload

    sent: list[ProgressEvent] = []
    meter = ProgressMeter(sent.append, TimeScale(), every=0.0)
    meter.start("r-resumed", 5, 120.0, before=3)
    meter.next_point(4, "w1000rpm")
    body = json.loads(progress_payload(sent[-1]))
    assert (body["point"], body["points"], body["fraction"]) == (4, 5, 0.6), body
    out = io.StringIO()
    with SweepProgress(TerminalConsole(file=out, width=140, force_terminal=False)) as progress:
        progress(sent[-1])
        points = progress.progress.tasks[progress.points]
        assert (points.completed, points.total) == (3, 5)
        meter.next_point(4, "w2000rpm")  # point 5 starts before point 4's result (identified in the background)
        progress(sent[-1])
        assert progress.progress.tasks[progress.points].completed == 3
        progress(ResultEvent("r-resumed", {"point": 3, "label": "w1000rpm"}))
        assert progress.progress.tasks[progress.points].completed == 4
    assert re.search(r"points\s.*4/5", out.getvalue()), out.getvalue()

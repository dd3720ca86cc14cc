"""The sweep's status lines at the operator's terminal: the time and the state's message, not
the source file and line that printed them."""

from __future__ import annotations

import io

from orbitrig.cli.progress import SweepProgress
from orbitrig.cli.terminal import TerminalConsole
from orbitrig.run.engine import StatusEvent
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

"""The sweep's ETA at the terminal while a manual setting waits for the operator, on the real
simulator: the plan's rig time left does not run down during the wait, and the bars say the ETA
is paused until the operator confirms; then it counts down again without the words."""

import asyncio
import io
import re

import pytest
from rich.console import Console

from orbitrig.cli.progress import SweepProgress
from orbitrig.cli.terminal import TerminalConsole
from orbitrig.run.engine import ProgressEvent
from rigunits import format_duration
from support.sweep_helpers import running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(120)

REVOLUTIONS = 10


def shown(bars: SweepProgress) -> str:
    """The bars as the operator's terminal draws them now."""
    screen = Console(file=io.StringIO(), width=160, record=True, force_terminal=False)
    screen.print(bars.progress.get_renderable())
    return screen.export_text()


def progress(rec) -> list[ProgressEvent]:
    return [e for e in rec.events if isinstance(e, ProgressEvent)]


def points_line(bars: SweepProgress) -> str:
    return next(line for line in shown(bars).splitlines() if line.startswith("points"))


async def test_eta_says_it_is_paused_while_the_operator_sets_by_hand(tmp_path):
    matrix = small_matrix(revolutions=REVOLUTIONS, dynamic_eccentricity=[0.096, 0.12])  # two radii, set by hand
    log = io.StringIO()
    async with running(tmp_path, matrix, confirm_mode="prompt") as (sim, eng, rec, run):
        with SweepProgress(TerminalConsole(file=log, width=160, force_terminal=False), REVOLUTIONS) as bars:
            eng.subscribe(bars)
            await wait_for(lambda: eng.waiting_step == "manual:0000", what="the first manual setting")
            eng.confirm("manual:0000")
            await wait_for(lambda: eng.waiting_step == "manual:0001", timeout=60, what="the second point's setting")
            before = progress(rec)[-1]
            assert (before.point, before.frequency) == (2, 0), before
            eta = f"ETA {format_duration(before.eta_s)}"
            waiting = points_line(bars)
            assert f"{eta} (paused: waiting for the operator)" in waiting, waiting
            await asyncio.sleep(1.0)  # the operator takes their time: the rig time left stands
            assert f"{eta} (paused: waiting for the operator)" in points_line(bars)
            said = " ".join(log.getvalue().split())
            assert "waiting: set by hand and confirm" in said and "'manual:0001'" in said, said
            eng.confirm("manual:0001")
            await wait_for(lambda: progress(rec)[-1].frequency >= 1, what="the second point's first block")
            after = progress(rec)[-1]
            going = points_line(bars)
            assert "paused" not in going and f"ETA {format_duration(after.eta_s)}" in going, going
            assert after.eta_s < before.eta_s  # the confirmed setting's estimate is spent
            assert re.search(r"ETA \d+:\d\d\s", going), going
            eng.request_abort()
            outcome = await asyncio.wait_for(run, 30)
    assert outcome.status == "aborted", outcome.message

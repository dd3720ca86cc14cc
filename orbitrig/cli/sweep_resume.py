"""`sweep --resume`: the run being resumed, opened once (its run.json read once) and handed to
everything that reads it (its configurations, point order, scenario, complete points, the
engine); and a resume whose every point is complete, finished without the rig: nothing left to
do when its run.h5 is written, else run.h5 consolidated from the stored pieces."""

from __future__ import annotations

import time

import typer

#: wall s between two lines of a consolidation's progress (the last point's line is always said)
EVERY_S = 2.0


def open_run(out):
    """The run in ``out`` that --resume continues (orbitrig.store.writer.RunStore, its header
    read): a BadParameter without --out, an UnusableRunDir when ``out`` holds no run to resume."""
    if out is None:
        raise typer.BadParameter("--resume needs --out DIR (the run to continue)", param_hint="--out")
    from orbitrig.store.writer import RunStore

    return RunStore.open_existing(out)


def all_complete(plan, store) -> bool:
    """Whether every point of the resumed run's ``plan`` is complete in ``store``."""
    done = set(store.completed_points())
    return all(p.index in done for p in plan.points)


def finish_without_the_rig(plan, store, operator: str):
    """A resume whose every point is complete, ended without starting the rig, the simulator or
    the drives: with run.h5 written, nothing left to do (said; None); without it (cut off after
    its last point, a full disk at its end), run.h5 consolidated from the stored pieces (said,
    with the run's closing line; its RunOutcome, completed, or failed if run.h5 cannot be written)."""
    from orbitrig.cli.terminal import say

    out, n = store.dir, len(plan.points)
    points = f"all {n} points of the run in {out} are" if n > 1 else f"the one point of the run in {out} is"
    if store.layout.run_file.is_file():
        say(f"resume: {points} complete and its run.h5 is written: nothing left to do")
        return None
    from orbitrig.run.run_dir import consolidate_resumed

    say(
        f"resume: {points} complete; its run.h5 is missing: consolidating it "
        "from the stored pieces (the rig, the simulator and the drives are not started)",
        err=True,
    )
    store.copied = Copying()
    outcome = consolidate_resumed(store, plan.rig, operator, n)
    say(
        f"run {outcome.status}: {outcome.message}  ({len(outcome.completed_points)} of {n} points complete in {out})",
        err=True,
    )
    return outcome


class Copying:
    """The progress of run.h5's consolidation, told to ``tell`` (default: standard error):
    'run.h5: 40 of 120 points copied (12 s)', at most one line per EVERY_S and always the last
    one. A resume's run copies the points completed before it when it ends."""

    def __init__(self, tell=None) -> None:
        self.tell = tell or _on_stderr
        self.start = self.said = time.monotonic()

    def __call__(self, done: int, total: int) -> None:
        now = time.monotonic()
        if done == 1:  # the copy starts when the run ends, not when this was made
            self.start = self.said = now
        if done == total or now - self.said >= EVERY_S:
            self.said = now
            self.tell(f"run.h5: {done} of {total} points copied ({now - self.start:.0f} s)")


def _on_stderr(line: str) -> None:
    from orbitrig.cli.terminal import say

    say(line, err=True)

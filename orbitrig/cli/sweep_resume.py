"""`sweep --resume`: the run being resumed, opened once (its run.json read once) and handed to
everything that reads it (its configurations, point order, scenario, complete points, the
engine); and a resume whose every point is complete, finished without the rig: nothing left to
do when its run.h5 is written, else run.h5 consolidated from the stored pieces."""

from __future__ import annotations

import typer


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
    if store.layout.run_file.is_file():
        say(f"resume: all {n} points of the run in {out} are complete and its run.h5 is written: nothing left to do")
        return None
    from orbitrig.run.run_dir import consolidate_resumed

    say(
        f"resume: all {n} points of the run in {out} are complete; its run.h5 is missing: consolidating it "
        "from the stored pieces (the rig, the simulator and the drives are not started)",
        err=True,
    )
    outcome = consolidate_resumed(store, plan.rig, operator, n)
    say(
        f"run {outcome.status}: {outcome.message}  ({len(outcome.completed_points)} of {n} points complete in {out})",
        err=True,
    )
    return outcome

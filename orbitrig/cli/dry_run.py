"""`orbitrig sweep --dry-run`: the plan's totals first, then every step with its start time."""

from __future__ import annotations

import os
import sys

import typer


def print_plan(plan) -> None:
    """Print `plan` (orbitrig.run.plan.Plan): a summary (points, orbit blocks, steps,
    estimated physical time, time per step kind), the predicted uncertainty of each model
    (orbitrig.cli.dry_run_predict), then one line per step (durations in s)."""
    try:
        _print(plan.steps, plan.name, plan.rig, plan.matrix)
    except BrokenPipeError:  # `| head`: the reader has what it wanted
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())


def _print(steps, name: str, rig, mat) -> None:
    from orbitrig.cli.dry_run_predict import prediction_lines
    from orbitrig.run.plan import format_duration, summarize

    sm = summarize(steps)
    typer.echo(f"matrix {name}: {sm.points} operating points, {sm.blocks} orbit blocks, "
               f"{len(steps)} steps, estimated {format_duration(sm.duration)} (physical time)")  # fmt: skip
    parts = ", ".join(f"{k} {format_duration(v)}" for k, v in sm.by_kind.items())
    typer.echo(f"by step: {parts}")
    for line in prediction_lines(rig, mat):
        typer.echo(line)
    typer.echo("")
    width = len(str(len(steps)))
    typer.echo(f"{'#':>{width}}  {'starts at':>8}  {'where':10}  {'duration':>10}  step  (times h:mm:ss from the start)")
    t = 0.0
    for i, s in enumerate(steps, 1):
        where = f"point {s.point:04d}" if s.point is not None else "end       "
        typer.echo(f"{i:>{width}}  {format_duration(t):>8}  {where}  {s.duration:8.2f} s  {s.describe()}")
        t += s.duration

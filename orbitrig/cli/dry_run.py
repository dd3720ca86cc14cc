"""`sweep --dry-run`: the plan's warnings (standard error, as at a sweep's start), the plan's
totals, the predicted uncertainty of each model (and every planned fit it predicts
undetermined), one line per operating point; `--steps` adds every step with its start time.
Lines for reading are folded to the terminal's width (80 columns when piped, or COLUMNS:
orbitrig.cli.plain_table.wrap), a step's description under its column."""

from __future__ import annotations

import typer

from orbitrig.cli.plain_table import unbroken, wrap


def print_plan(plan, *, steps: bool = False, done: list[int] | None = None) -> None:
    """Print `plan` (orbitrig.run.plan.Plan): a summary (points, orbit blocks, steps,
    estimated physical time, time per step kind), the predicted uncertainty of each model
    (orbitrig.cli.dry_run_predict), one line per operating point, and with `steps` one line
    per step (durations in s). ``done``: a resume's points complete already (each marked, and
    what is left said first)."""
    from orbitrig.cli.terminal import printing

    with printing():  # `| head`: the reader has what it wanted
        print_warnings(plan)
        if done is not None:
            typer.echo(wrap(resume_line(plan, done)))
        _print(plan, steps, done or [])


def resume_line(plan, done: list[int]) -> str:
    """'resume: 2 of 3 points complete (0000, 0002); left: 1 point, estimated 3:24 (physical time)'."""
    from orbitrig.store.layout import point_name
    from rigunits import format_duration

    left = [p for p in plan.points if p.index not in done]
    time = sum(s.duration for p in left for s in plan.point_steps(p.index)) + sum(s.duration for s in plan.final_steps)
    names = ", ".join(point_name(i) for i in sorted(done))
    what = (  # nothing left: the resume starts nothing, not even the closing stop of the drives
        f"{len(left)} point{'s' if len(left) != 1 else ''}, estimated {format_duration(time)} (physical time; "
        if left
        else "0 points, nothing to measure ("
    )
    return (
        f"resume: {len(plan.points) - len(left)} of {len(plan.points)} points complete"
        f"{f' ({names})' if names else ''}; left: {what}the totals below are the whole matrix's)"
    )


def print_warnings(plan) -> None:
    """The plan's warnings on standard error, each once for the matrix ('warning: FILE: line N:
    key ...': orbitrig.config.plan_warnings); the dry run and the sweep's start print them."""
    from orbitrig.config import warning_lines

    for line in warning_lines(plan.matrix, plan.rig.averaging.revolutions, plan.rig):
        typer.echo(line, err=True)


def _print(plan, steps: bool, done: list[int]) -> None:
    from orbitrig.cli.dry_run_predict import prediction_lines
    from orbitrig.config import age_lines
    from orbitrig.run.plan import summarize
    from rigunits import format_duration

    sm = summarize(plan.steps)
    parts = ", ".join(unbroken(f"{k} {format_duration(v)}") for k, v in sm.by_kind.items())
    lines = [
        f"matrix {plan.name}: {sm.points} operating point{'s' * (sm.points != 1)}, {sm.blocks} orbit blocks, "
        f"{len(plan.steps)} steps, estimated {format_duration(sm.duration)} (physical time)",
        f"by step: {parts}",
        *prediction_lines(plan.rig, plan.matrix),
        *age_lines(plan.rig),
        order_line(plan, sm.duration),
        *sequential_lines(plan, sm.duration),
    ]
    for line in lines:
        typer.echo(wrap(line))
    typer.echo("")
    _print_points(plan, done)
    if steps:
        typer.echo("")
        _print_steps(plan.steps)
    else:
        typer.echo(f"({len(plan.steps)} steps: --steps lists every one with its start time)")


def order_line(plan, duration: float) -> str:
    """The rig time of the points in the chosen order against the written order (matrix `order`)."""
    from orbitrig.run.plan import make_plan, summarize
    from rigunits import format_duration

    written = list(range(len(plan.points)))
    how = plan.matrix.order.value
    if list(plan.order) == written:
        return f"order of the points: {how}, as written: estimated {format_duration(duration)}"
    other = summarize(make_plan(plan.matrix, plan.rig, written).steps).duration
    return (
        f"order of the points: {how}: estimated {format_duration(duration)}; in the written order "
        f"{format_duration(other)} ({duration / other:.3f} of it)"
    )


def sequential_lines(plan, duration: float) -> list[str]:
    """The bounds of a sequential matrix: the plan's time with no chosen block and with every
    point at its cap, and each spin's candidate ratios (what the engine may choose from)."""
    from orbitrig.run.steps import ChooseBlocks
    from rigunits import format_duration

    chosen = [s for s in plan.steps if isinstance(s, ChooseBlocks)]
    if not chosen:
        return []
    least = duration - sum(s.duration for s in chosen)
    lines = [
        f"sequential: {len(chosen)} points; estimated {format_duration(least)} (no block chosen: the target met "
        f"by the initial list) to {format_duration(duration)} (every point at its cap of "
        f"{chosen[0].rule.cap_s:g} s of blocks)"
    ]
    spins = {p.index: p.spin_rpm for p in plan.points}
    for rpm in sorted(set(spins.values())):
        rule = next(s.rule for s in chosen if spins[s.point] == rpm)
        lines.append(f"  at {rpm:g} rpm: {rule.describe()}")
    return lines


def _print_points(plan, done: list[int]) -> None:
    """One line per operating point (named as the run's files and --steps name it, 0003): its start,
    duration, blocks and settings; a point in ``done`` (complete: a resume skips it) marked so."""
    from orbitrig.store.layout import point_name
    from rigunits import format_duration

    typer.echo(f"point  {'starts at':>9}  {'duration':>8}  blocks  settings  (times h:mm:ss)")
    t = 0.0
    for p in plan.points:
        d = sum(s.duration for s in plan.point_steps(p.index))
        typer.echo(
            f"{point_name(p.index):>5}  {format_duration(t, hours=True):>9}  {format_duration(d, hours=True):>8}  "
            f"{len(p.blocks):>6}  {p.label}{'  (complete)' if p.index in done else ''}"
        )
        t += d
    tail = sum(s.duration for s in plan.final_steps)
    if plan.final_steps:
        typer.echo(
            f"{'end':>5}  {format_duration(t, hours=True):>9}  {format_duration(tail, hours=True):>8}  {'':>6}  "
            + "; ".join(s.describe() for s in plan.final_steps)
        )


def _print_steps(steps) -> None:
    from orbitrig.store.layout import point_name
    from rigunits import format_duration

    width = len(str(len(steps)))
    typer.echo(
        f"{'#':>{width}}  {'starts at':>8}  {'where':10}  {'duration':>10}  step  (times h:mm:ss from the start)"
    )
    t = 0.0
    for i, s in enumerate(steps, 1):
        where = f"point {point_name(s.point)}" if s.point is not None else "end       "
        row = f"{i:>{width}}  {format_duration(t, hours=True):>8}  {where}  {s.duration:8.2f} s  "
        typer.echo(wrap(row + s.describe(), indent=" " * len(row)))
        t += s.duration

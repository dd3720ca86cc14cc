"""`orbitrig sweep`: run a test matrix on the rig or on the built-in simulator.

Exit status: 0 completed, 1 failed, 2 bad configuration or usage, 3 stopped,
4 aborted.
"""

from __future__ import annotations

from pathlib import Path

import typer

from orbitrig.cli import sweep_options as opt
from orbitrig.cli.plain_table import OutputFormat
from orbitrig.cli.sim_options import DEFAULT_SPEEDUP
from orbitrig.cli.sweep_configs import load_plan
from orbitrig.run.states import ConfirmMode, Outcome

EXIT = {Outcome.COMPLETED: 0, Outcome.FAILED: 1, Outcome.STOPPED: 3, Outcome.ABORTED: 4}


def register(app: typer.Typer) -> None:
    @app.command("sweep")
    def sweep(
        run_dir: opt.RunDir = None,
        out: opt.Out = None,
        sim: opt.Sim = False,
        config: opt.Config = None,
        matrix: opt.Matrix = None,
        resume: opt.Resume = False,
        dry_run: opt.DryRun = False,
        steps: opt.Steps = False,
        fmt: opt.Format = OutputFormat.TEXT,
        speedup: opt.Speedup = DEFAULT_SPEEDUP,
        sim_config: opt.SimConfig = None,
        operator: opt.Operator = None,
        draw_figures: opt.DrawFigures = True,
    ) -> None:
        """Run a test matrix: manual settings, speeds, settle, acquire, identify, store.

        Matrix units: speeds rpm (spin omega; orbit Omega = ratio * omega), pressures MPa, times s.

        Ctrl-C pauses at the next safe point and asks resume / stop / abort; a second Ctrl-C aborts.
        SIGTERM, SIGHUP or SIGQUIT stops at once with a ramp (exit 3); a second signal aborts (exit 4).
        A closed standard output (`| head`) does not change the exit status.

        Exit 0 completed, 1 failed, 2 bad configuration or usage, 3 stopped, 4 aborted.
        """
        _sweep_command(**locals())


def _sweep_command(
    *,
    run_dir,
    out,
    sim,
    config,
    matrix,
    resume,
    dry_run,
    steps,
    fmt,
    speedup,
    sim_config,
    operator,
    draw_figures,
) -> None:
    """`orbitrig sweep`, its options checked; raises typer.Exit with the run's exit status."""
    from orbitrig.errors import OrbitrigError

    if run_dir is not None and out is not None and run_dir != out:
        raise typer.BadParameter(f"two run directories: {run_dir} and --out {out}", param_hint="DIR")
    out = out or run_dir
    if sim_config is not None and not sim:
        raise typer.BadParameter("--sim-config needs --sim", param_hint="--sim-config")
    try:
        plan = load_plan(config, matrix, sim=sim, resume=resume, out=out, dry_run=dry_run)
        if dry_run:
            from orbitrig.cli.dry_run import print_plan

            if sim:  # the scenario the sweep would run (a bad --sim-config refused), as the sweep warns
                _record_scenario(plan.rig, _scenario(sim_config, resume=resume, out=out)[1])
            print_plan(plan, steps=steps, done=_completed(out) if resume else None)
            return
        outcome = _run_plan(
            plan,
            out=out,
            sim=sim,
            sim_config=sim_config,
            resume=resume,
            speedup=speedup,
            operator=operator or _login(),
            fmt=fmt,
            draw_figures=draw_figures,
        )
    except OrbitrigError as err:  # configuration or usage (2); the run directory cannot be written (1)
        typer.echo(f"error: {err}", err=True)
        raise typer.Exit(1 if _storage_failed(err) else 2) from None
    except OSError as err:  # a file the run needs cannot be written (disk full, permissions)
        typer.echo(f"error: {err.filename or out}: {err.strerror or err}", err=True)
        raise typer.Exit(1) from None
    raise typer.Exit(0 if outcome is None else EXIT[outcome.status])  # None: a resume with nothing left


def _storage_failed(err: Exception) -> bool:
    """A failure to write or read the run directory (exit 1, as an OSError), not a usage error."""
    from orbitrig.store.errors import StorageError, UnusableRunDir

    return isinstance(err, StorageError) and not isinstance(err, UnusableRunDir)


def _run_plan(plan, *, out, sim: bool, sim_config, resume: bool, speedup: float, operator: str, fmt, draw_figures):
    """Run a checked plan: the rig must answer and --out be writable before anything starts."""
    if out is None:
        raise typer.BadParameter("--out DIR is required (except with --dry-run)", param_hint="--out")
    if resume and _nothing_left(plan, out):
        return None
    if not sim:
        _check_rig_answers(plan.rig)
    scenario = _scenario(sim_config, resume=resume, out=out) if sim else None  # a bad one: no run directory made
    if scenario is not None:
        _record_scenario(plan.rig, scenario[1])
    if not resume:
        _check_out(out)
    from orbitrig.cli.dry_run import print_warnings

    print_warnings(plan)  # as the dry run, before anything starts
    import asyncio

    from orbitrig.cli.terminal import off_the_loop

    with off_the_loop():  # a terminal that stops reading (Ctrl-S) holds neither the drives' poll nor a signal
        outcome = asyncio.run(
            _sweep(
                plan,
                out=out,
                sim=scenario,
                resume=resume,
                speedup=speedup,
                operator=operator,
                draw_figures=draw_figures,
            )
        )
    print_table(outcome, out, fmt)  # the loop is done: straight to standard output
    return outcome


def _scenario(path, *, resume: bool, out):
    """(SimConfig, Scenario) of this --sim sweep: --sim-config or the default rig; on --resume
    the scenario the run recorded (a --sim-config given then must have the same text)."""
    from orbitrig.cli.scenarios import default_scenario, scenario_file
    from orbitrig.errors import ConfigError
    from orbitrig.run.scenario import Scenario
    from sim.config import sim_config_from_text  # parsing only: a dry run starts no simulator

    path = scenario_file(path)
    stored = None
    if resume:  # the run files (h5py) only then: a dry run loads nothing of the store's
        from orbitrig.store.writer import RunStore

        stored = RunStore.open_existing(out).stored_scenario()
    if stored is not None:
        name, text = stored
        if path is not None and _read(path) != text:
            raise ConfigError(
                str(path),
                [
                    f"differs from the simulator scenario of the run being resumed in {out} "
                    f"({name}); resume without --sim-config (the stored one is used)"
                ],
            )
        where = f"{out}/run.json: sim_scenario ({name})"
        typer.echo(f"simulator scenario of the run: {name}", err=True)
    else:
        if path is None:
            return None, default_scenario()  # the simulator's own default (sim.config.SimConfig())
        name, text = str(path), _read(path)
        where = str(path)
    try:
        return sim_config_from_text(text, where), Scenario(name, text)
    except ValueError as err:
        raise typer.BadParameter(str(err), param_hint="--sim-config") from None


def _record_scenario(rig, scenario) -> None:
    """A warning at the start of a --sim sweep (and its dry run) whose active record was measured on
    another simulator scenario than `scenario` (orbitrig.config.other_scenario): it runs, corrected
    with that one's."""
    from orbitrig.config import other_scenario

    warning = other_scenario(rig, scenario.name, scenario.text)
    if warning is not None:
        typer.echo(f"warning: {warning}", err=True)


def _completed(out) -> list[int]:
    """The points of the run in ``out`` that are complete (a resume does not measure them again)."""
    from orbitrig.store.writer import RunStore

    return RunStore.open_existing(out).completed_points()


def _nothing_left(plan, out) -> bool:
    """Whether the run in ``out`` being resumed has nothing left to do: every point of its plan is
    complete and its run.h5 is written (it ended); said, and nothing is started (not the rig, the
    simulator or the drives). A run whose run.h5 is missing (a full disk at its end) is resumed:
    the resume consolidates it."""
    from orbitrig.cli.terminal import say
    from orbitrig.store.writer import RunStore

    store = RunStore.open_existing(out)
    done = set(store.completed_points())
    if any(p.index not in done for p in plan.points) or not store.layout.run_file.is_file():
        return False
    n = len(plan.points)
    points = f"all {n} points of the run in {out} are" if n > 1 else f"the one point of the run in {out} is"
    say(f"resume: {points} complete and its run.h5 is written: nothing left to do")
    return True


def _read(path) -> str:
    try:
        return Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise typer.BadParameter(f"{path}: {err}", param_hint="--sim-config") from None


def _check_out(out: Path) -> None:
    """The run directory can be created and written, before anything is started."""
    import os

    from orbitrig.errors import ConfigError

    if out.exists() and not out.is_dir():
        raise ConfigError(str(out), ["--out is a file, not a directory"])
    if (out / "run.h5").exists():
        raise ConfigError(str(out / "run.h5"), ["already exists: use --resume to continue that run, or another --out"])
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ConfigError(str(out), [f"cannot create the run directory: {err.strerror or err}"]) from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise ConfigError(str(out), ["the run directory is not writable"])


def _check_rig_answers(rig) -> None:
    """On the rig: every transport must answer before the run directory is made (exit 2 if not)."""
    import asyncio

    from orbitrig.cli.preflight import RigUnreachable, require_rig_answers
    from orbitrig.cli.terminal import say

    try:
        asyncio.run(require_rig_answers(rig, "orbitrig sweep --sim ...", "no run directory was made"))
    except RigUnreachable as err:
        say(f"error: {err}", err=True)
        raise typer.Exit(2) from None


def _login() -> str:
    import getpass

    return getpass.getuser()


async def _sweep(
    plan,
    *,
    out: Path,
    sim,
    resume: bool,
    speedup: float,
    operator: str = "",
    subscribers=(),
    draw_figures: bool = False,
):
    """Run the plan, its progress and closing line on standard error (the console); ``sim`` the
    simulator's (SimConfig, Scenario) (None: the real rig); ``subscribers``: more event callbacks
    of the engine (bench/bench_soak.py samples memory); ``draw_figures``: the report's figures of
    each completed point drawn during the run. The closing table is `print_table`'s, once the
    event loop is done."""
    started = None
    if sim is not None:  # it boots in its own process while this one imports the engine
        from orbitrig.cli.simulated_rig import start_simulator

        started = start_simulator(speedup, sim[0])
    import contextlib
    import sys

    from orbitrig.cli.progress import SweepProgress
    from orbitrig.cli.terminal import TerminalConsole
    from orbitrig.run.heap import tune_heap
    from orbitrig.run.modbus_log import keep_pymodbus_off_the_terminal

    keep_pymodbus_off_the_terminal()
    tune_heap()  # bounded memory over months (orbitrig.run.heap)
    console = TerminalConsole(file=sys.stderr)  # off the loop in `orbitrig sweep` (terminal.off_the_loop)
    try:
        async with contextlib.AsyncExitStack() as stack:
            access = None
            if sim is not None:
                from orbitrig.cli.simulated_rig import simulated_rig

                _, access = await stack.enter_async_context(simulated_rig(speedup, sim[0], sim[1], started=started))
            engine, console_operator = _engine(plan, out=out, access=access, operator=operator, console=console)
            for callback in subscribers:
                engine.subscribe(callback)
            if draw_figures:  # the report's figures of each completed point, drawn at the lowest priority
                from orbitrig.analysis.report_ahead import FiguresAhead

                ahead = FiguresAhead(out)
                stack.callback(ahead.close)
                engine.subscribe(ahead.on_event)
            with SweepProgress(console, revolutions=plan.revolutions) as bars:
                engine.subscribe(bars)
                console_operator.install()
                try:
                    outcome = await engine.run(plan, resume=resume)
                finally:
                    console_operator.uninstall()
        console.print(_closing_line(outcome, out), markup=False)
    finally:
        console.written()  # on the terminal before anything else is said on standard error
    return outcome


def _engine(plan, *, out: Path, access, operator: str, console):
    """The run engine of this sweep (prompts confirmed by the operator on the rig, automatic on the
    simulator) and its console operator: Ctrl-C's pause, stop and abort, the prompts' answers."""
    from orbitrig.cli.operator import Operator
    from orbitrig.run.engine import RunEngine

    engine = RunEngine(
        plan.rig,
        out_dir=out,
        access=access,
        confirm_mode=ConfirmMode.AUTO if access else ConfirmMode.PROMPT,
        operator=operator,
    )
    engine.console_user = operator
    console_operator = Operator(engine, console)
    engine.subscribe(console_operator.on_event)
    return engine, console_operator


def _closing_line(outcome, out: Path) -> str:
    """The run's closing line on the console: its status, why, and the points complete."""
    return (
        f"run {outcome.status}: {outcome.message}  ({len(outcome.completed_points)} of "
        f"{outcome.points} points complete in {out})"
    )


def print_table(outcome, out: Path, fmt=OutputFormat.TEXT) -> None:
    """When a point completed, the table of its coefficients on standard output: a reader gone
    (`| head`) ends the table, not the run's exit status; another failure (ENOSPC) is raised as
    an OutputError."""
    if outcome.completed_points:
        from orbitrig.cli.sweep_summary import print_coefficients
        from orbitrig.cli.terminal import printing

        with printing():
            print_coefficients(out, fmt)

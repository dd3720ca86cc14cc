"""`orbitrig sweep`: run a test matrix on the rig or on the built-in simulator.

Exit status: 0 completed, 1 failed, 2 bad configuration or usage, 3 stopped,
4 aborted.
"""

from __future__ import annotations

from pathlib import Path

import typer

from orbitrig.cli import sweep_options as opt
from orbitrig.cli.failure import fail
from orbitrig.cli.plain_table import OutputFormat
from orbitrig.cli.sim_options import DEFAULT_SPEEDUP
from orbitrig.cli.sweep_configs import load_plan
from orbitrig.cli.sweep_resume import Copying, all_complete, finish_without_the_rig, open_run
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
        Once every point is measured (from the last point's identification on) nothing is left to pause:
        Ctrl-C says so and asks stop / abort.
        SIGTERM, SIGHUP or SIGQUIT stops at once with a ramp (exit 3); a second signal aborts (exit 4),
        and so does any signal while the run already stops (a stop asked, the end of the plan).
        A stop or an abort that leaves every point complete (it came as the drives ramped down at
        the end) ends the run stopped (3) or aborted (4) all the same, its message 'all points completed; ...'.
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
    from orbitrig.cli.scenarios import needs_sim
    from orbitrig.errors import OrbitrigError

    if run_dir is not None and out is not None and run_dir != out:
        raise typer.BadParameter(f"two run directories: {run_dir} and --out {out}", param_hint="DIR")
    out = out or run_dir
    needs_sim(sim, sim_config)
    try:
        store = open_run(out) if resume else None  # the run resumed: its run.json read once, here
        plan = load_plan(config, matrix, sim=sim, store=store, dry_run=dry_run)
        if dry_run:
            from orbitrig.cli.dry_run import print_plan

            if sim:  # the scenario the sweep would run (a bad --sim-config refused), as the sweep warns
                _record_scenario(plan.rig, sweep_scenario(sim_config, store=store)[1])
            print_plan(plan, steps=steps, done=store.completed_points() if store is not None else None)
            return
        outcome = _run_plan(
            plan,
            out=out,
            sim=sim,
            sim_config=sim_config,
            store=store,
            speedup=speedup,
            operator=operator or _login(),
            fmt=fmt,
            draw_figures=draw_figures,
        )
    except OrbitrigError as err:  # configuration or usage (2); the run directory cannot be written (1)
        fail(str(err), 1 if _storage_failed(err) else 2)
    except OSError as err:  # a file the run needs cannot be written (disk full, permissions)
        fail(f"{err.filename or out}: {err.strerror or err}", 1)
    raise typer.Exit(0 if outcome is None else EXIT[outcome.status])  # None: a resume with nothing left


def _storage_failed(err: Exception) -> bool:
    """A failure to write or read the run directory (exit 1, as an OSError), not a usage error."""
    from orbitrig.store.errors import StorageError, UnusableRunDir

    return isinstance(err, StorageError) and not isinstance(err, UnusableRunDir)


def _run_plan(plan, *, out, sim: bool, sim_config, store, speedup: float, operator: str, fmt, draw_figures):
    """Run a checked plan: the rig must answer and --out be writable before anything starts;
    ``store``: the run a resume continues (None: a new run). A resume whose every point is
    complete starts nothing (sweep_resume.finish_without_the_rig)."""
    if out is None:
        raise typer.BadParameter("--out DIR is required (except with --dry-run)", param_hint="--out")
    if store is not None:
        store.hold()  # refused while another process runs it, before anything is started
    if store is not None and all_complete(plan, store):
        ended = finish_without_the_rig(plan, store, operator)
        if ended is not None:
            print_table(ended, out, fmt)
        return ended
    if not sim:
        _check_rig_answers(plan.rig)
    scenario = sweep_scenario(sim_config, store=store) if sim else None  # a bad one: no run directory made
    if scenario is not None:
        _record_scenario(plan.rig, scenario[1])
    if store is None:
        _check_out(out)
    from orbitrig.cli.dry_run import print_warnings

    print_warnings(plan)  # as the dry run, before anything starts
    import asyncio

    from orbitrig.cli.terminal import off_the_loop

    with off_the_loop():  # a terminal that stops reading (Ctrl-S) holds neither the drives' poll nor a signal
        outcome = asyncio.run(
            run_sweep(
                plan,
                out=out,
                sim=scenario,
                store=store,
                speedup=speedup,
                operator=operator,
                draw_figures=draw_figures,
            )
        )
    print_table(outcome, out, fmt)  # the loop is done: straight to standard output
    return outcome


def sweep_scenario(path, *, store=None):
    """(SimConfig, Scenario) of this --sim sweep: --sim-config or the default rig; on --resume
    (``store``: the run resumed) the scenario the run recorded (a --sim-config given then must
    have the same text)."""
    from orbitrig.cli.scenarios import scenario_file, scenario_of, sim_config_of, sim_scenario
    from orbitrig.errors import ConfigError
    from orbitrig.run.scenario import Scenario

    stored = store.stored_scenario() if store is not None else None
    if stored is None:
        return sim_scenario(path)  # --sim-config, or the simulator's own default
    path, scenario = scenario_file(path), Scenario(*stored)
    if path is not None and scenario_of(path).text != scenario.text:
        raise ConfigError(
            str(path),
            [
                f"differs from the simulator scenario of the run being resumed in {store.dir} "
                f"({scenario.name}); resume without --sim-config (the stored one is used)"
            ],
        )
    typer.echo(f"simulator scenario of the run: {scenario.name}", err=True)
    return sim_config_of(scenario, f"{store.layout.header}: sim_scenario ({scenario.name})"), scenario


def _record_scenario(rig, scenario) -> None:
    """A warning at the start of a --sim sweep (and its dry run) whose active record was measured on
    another simulator scenario than `scenario` (orbitrig.config.other_scenario): it runs, corrected
    with that one's."""
    from orbitrig.config import other_scenario

    warning = other_scenario(rig, scenario.name, scenario.text)
    if warning is not None:
        typer.echo(f"warning: {warning}", err=True)


def _check_out(out: Path) -> None:
    """The run directory can be created and written, before anything is started."""
    import os

    from orbitrig.errors import ConfigError
    from orbitrig.store.errors import RUN_EXISTS

    if out.exists() and not out.is_dir():
        raise ConfigError(str(out), ["--out is a file, not a directory"])
    if (out / "run.h5").exists():
        raise ConfigError(str(out / "run.h5"), [RUN_EXISTS])
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ConfigError(str(out), [f"cannot create the run directory: {err.strerror or err}"]) from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise ConfigError(str(out), ["the run directory is not writable"])


def _check_rig_answers(rig) -> None:
    """On the rig: every transport must answer before the run directory is made (exit 2 if not)."""
    import asyncio

    from orbitrig.run.rig_answers import RigUnreachable, require_rig_answers

    try:
        asyncio.run(require_rig_answers(rig, "orbitrig sweep --sim ...", "no run directory was made"))
    except RigUnreachable as err:
        fail(str(err), 2)


def _login() -> str:
    import getpass

    return getpass.getuser()


async def run_sweep(
    plan,
    *,
    out: Path,
    sim,
    speedup: float,
    store=None,
    operator: str = "",
    subscribers=(),
    draw_figures: bool = False,
):
    """Run the plan, its progress and closing line on standard error (the console); ``sim`` the
    simulator's (SimConfig, Scenario) (None: the real rig); ``store``: the run a resume continues
    (None: a new run); ``subscribers``: more event callbacks of the engine (bench/bench_soak.py
    samples memory); ``draw_figures``: the report's figures of each completed point drawn during
    the run. The closing table is `print_table`'s, once the event loop is done."""
    started = None
    if sim is not None:  # it boots in its own process while this one imports the engine
        from orbitrig.cli.simulated_rig import start_simulator

        started = start_simulator(speedup, sim[0], plan.rig.transports.can_node_id)  # the node rig.toml reads
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
            _say_copying(store, console)
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
                    outcome = await engine.run(plan, resume=store is not None, store=store)
                finally:
                    console_operator.uninstall()
        console.print(_closing_line(outcome, out), markup=False)
    finally:
        console.written()  # on the terminal before anything else is said on standard error
    return outcome


def _say_copying(store, console) -> None:
    """A resume's end copies the points complete before it into run.h5: its progress said on the console."""
    if store is not None:
        store.copied = Copying(lambda line: console.print(line, markup=False))


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

        # run.h5 written: its points were checked just before, as the outcome lists them (not again)
        verified = outcome.completed_points if (Path(out) / "run.h5").is_file() else None
        with printing():
            print_coefficients(out, fmt, verified)

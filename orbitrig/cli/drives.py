"""`orbitrig drives status|run|stop`: the spindle drives from the command line.

Speeds are rpm here (the command line is an edge); the drive API underneath
is rad/s. The rig configuration (`--config`, default config/rig.toml) gives
the Modbus URL (`transports.modbus_url`; an explicit `--modbus` wins), the
device ids, the request timeout, the poll interval, link_loss_polls and the
limits (`[drives]`): `--max-spin/--max-orbit/--min-ratio/--max-ratio` may
only tighten those. Exit status: 0 done, 2 failed or interrupted (the reason is
printed on standard error; `run` has stopped both drives and confirmed them at
standstill by then, or, interrupted while opening the drives, sent the stop words to each
drive that answers, named; output that cannot be written, a full disk, is such a failure),
4 ended by an emergency stop (`run`: a second signal during its ramp or those stop words;
`stop`: a signal during its ramp, or a second one during the stop words sent while opening), 1 `run` could not confirm both drives at standstill ("drives not confirmed
stopped"), 3 `status`/`stop` done with a rig configuration that has errors (drives_despite). Signals:
orbitrig.cli.signals.SIGNALS. `run` gives both drives [drives] comm_loss_timeout_s and leaves
them running only if both read it back armed (nonzero).
"""

from __future__ import annotations

from pathlib import Path

import typer

from orbitrig.cli import drives_options as opt
from orbitrig.cli.drives_checks import (  # effective_limits is part of this command's API
    ID_FROM_DEFAULT,
    check_seconds,
    effective_limits,
    ids_said,
    open_config,
    said_aside,
)
from orbitrig.cli.drives_despite import config_errors_code
from orbitrig.cli.drives_stop import stop_drives
from orbitrig.cli.help_text import command_group


def register(app: typer.Typer) -> None:
    """Add the `drives` sub-app to the `orbitrig` command."""
    drives_app = command_group(
        "Spindle drives over Modbus: status, run to a setpoint (and hold), stop.", no_args_is_help=True
    )
    for add in (_add_status, _add_run, _add_stop):
        add(drives_app)
    app.add_typer(drives_app, name="drives")


def _add_status(drives_app: typer.Typer) -> None:
    @drives_app.command("status")
    def status(
        modbus: opt.Modbus = None,
        config: opt.Config = None,
        json_out: opt.JsonOut = False,
        spin_id: opt.SpinId = None,
        orbit_id: opt.OrbitId = None,
    ) -> None:
        """Print both drives' state, reference and actual speed (rpm), torque and fault.

        Only reads: running drives keep running. A rig configuration with errors elsewhere than its
        [transports] modbus_url and [drives] ids: read all the same, its errors said, exit 3.
        """
        url, d, id_from, errors = open_config("status", config, modbus, spin_id, orbit_id, required=False)
        from orbitrig.cli.drives_loop import run_async
        from orbitrig.cli.drives_status import status_of

        code = run_async(lambda intr: status_of(url, json_out, d, id_from), "status")
        raise typer.Exit(config_errors_code("status", code, errors))


def _add_run(drives_app: typer.Typer) -> None:
    @drives_app.command("run")
    def run(
        spin: opt.Spin,
        orbit: opt.Orbit,
        modbus: opt.Modbus = None,
        config: opt.Config = None,
        max_spin: opt.MaxSpin = None,
        max_orbit: opt.MaxOrbit = None,
        min_ratio: opt.MinRatio = None,
        max_ratio: opt.MaxRatio = None,
        settle: opt.Settle = 1.0,
        timeout: opt.Timeout = 120.0,
        hold: opt.Hold = False,
        status_every: opt.StatusEvery = 5.0,
        spin_id: opt.SpinId = None,
        orbit_id: opt.OrbitId = None,
    ) -> None:
        """Bring both drives to speed; exit 0 once both hold their setpoint.

        Limits (the rig configuration's, tightened by the options) are checked
        before anything is sent. On any failure (limit, fault, timeout, link,
        Ctrl-C, SIGTERM, SIGHUP, SIGQUIT before the setpoint) both drives are ramped
        to zero and the command exits 2 with the reason once both are at standstill
        (a second signal during the ramp: emergency stop, exit 4; standstill not
        confirmed: "drives not confirmed stopped", exit 1). A signal while it opens the
        drives sends the ramp stop words to each drive that answers and names those (exit 2;
        a second signal meanwhile: the emergency stop, exit 4). Both drives are given
        [drives] comm_loss_timeout_s as their comm-loss watchdog (COMM_LOSS_TIMEOUT)
        on entry; a drive that reads it back as 0 (disabled) is not left running:
        both ramped to zero, exit 2, naming the drive and the register. Without --hold
        the drives are left at their setpoint once both read an armed watchdog;
        with no client polling them, it ramps them down that many seconds after the
        last request (said once on standard error); a failure the poll finds (a trip), a signal, or
        output that cannot be written (a full disk) as the command leaves them there ramps both to
        zero after all, confirmed at standstill (exit 2). With --hold the
        command keeps polling until Ctrl-C/SIGTERM/SIGHUP/SIGQUIT (a closed standard
        output does not end it), then ramps both to zero (exit 0; a second signal
        during the ramp: emergency stop, exit 4); if another client stops a drive or
        changes its reference meanwhile, it says which, ramps both to zero and exits 2.
        A rig with a CAN node ([interlocks] check_*) is watched as a sweep is: the supply or the node
        lost for its limit gives both the emergency stop (OFF3), exit 2 naming the interlock.
        """
        _run_command(
            spin=spin,
            orbit=orbit,
            modbus=modbus,
            config=config,
            max_spin=max_spin,
            max_orbit=max_orbit,
            min_ratio=min_ratio,
            max_ratio=max_ratio,
            settle=settle,
            timeout=timeout,
            hold=hold,
            status_every=status_every,
            spin_id=spin_id,
            orbit_id=orbit_id,
        )


def _run_command(
    *,
    spin: float,
    orbit: float,
    modbus: str | None,
    config: Path | None,
    max_spin: float | None,
    max_orbit: float | None,
    min_ratio: float | None,
    max_ratio: float | None,
    settle: float,
    timeout: float,
    hold: bool,
    status_every: float,
    spin_id: int | None,
    orbit_id: int | None,
) -> None:
    """`drives run` after typer: checks (exit 2, nothing sent), then the run."""
    check_seconds("run", settle=(settle, True), timeout=(timeout, False), status_every=(status_every, False))
    url, d, _, _ = open_config("run", config, modbus, spin_id, orbit_id, required=True)
    try:
        limits = effective_limits(
            d,
            max_spin=max_spin,
            max_orbit=max_orbit,
            min_ratio=min_ratio,
            max_ratio=max_ratio,
            file=_config_name(config),
        )
    except ValueError as err:
        from orbitrig.cli.failure import fail

        fail(f"{err}; nothing sent", 2, part="limit", command="drives run")
    from orbitrig.cli.drives_hold import Interrupt, stop_after_release
    from orbitrig.cli.drives_loop import run_async
    from orbitrig.cli.drives_run import run_drives
    from orbitrig.cli.signals import take_late_signals
    from orbitrig.config import RPM, load_rig

    interrupt, rig = Interrupt(), load_rig(config)  # read already by open_config: its interlocks and CAN node
    code = run_async(
        lambda intr: run_drives(
            url, rig, d, limits, spin * RPM, orbit * RPM, settle, timeout, hold, status_every, intr
        ),
        "run",
        interrupt,
    )
    late = take_late_signals()
    if interrupt.released and (late or interrupt.unsaid):  # a signal, or its output failed (a full disk behind
        # standard error: its warning that the drives run on), once they were left at the setpoint
        code = run_async(lambda intr: stop_after_release(url, d, intr, interrupt.unsaid), "run", Interrupt(late[:1]))
    raise typer.Exit(code)


def _add_stop(drives_app: typer.Typer) -> None:
    @drives_app.command("stop")
    def stop(
        modbus: opt.Modbus = None,
        config: opt.Config = None,
        emergency: opt.Emergency = False,
        timeout: opt.StopTimeout = None,
        spin_id: opt.SpinId = None,
        orbit_id: opt.OrbitId = None,
    ) -> None:
        """Stop both drives; returns once both read zero speed.

        Once the drives are open, Ctrl-C, SIGTERM, SIGHUP or SIGQUIT during the ramp makes it the
        emergency stop (OFF3), still waited for; exit 4 once both are at standstill. A signal while
        opening them sends the stop words to each drive that answers (exit 2; a second one
        meanwhile: the emergency stop, exit 4). A rig configuration with errors elsewhere still gives
        its [transports] modbus_url and [drives] ids: the stop goes out, its errors said, exit 3
        once both are stopped. With --modbus and one whose ids cannot be read it goes on with the
        built-in [drives] defaults (ids 1 and 2 unless given), said by a WARNING before and after."""
        check_seconds("stop", timeout=(timeout, False))
        url, d, id_from, errors = open_config("stop", config, modbus, spin_id, orbit_id, required=False)
        from orbitrig.cli.drives_loop import run_async

        code = run_async(lambda intr: stop_drives(url, d, emergency, timeout, intr), "stop")
        if ID_FROM_DEFAULT in id_from.values():  # said again after the outcome: not the rig's ids, maybe
            said_aside(
                "stop",
                f"WARNING: the stop was addressed to device ids not from the rig configuration: {ids_said(d, id_from)}",
            )
        raise typer.Exit(config_errors_code("stop", code, errors))


def _config_name(config: Path | None) -> str:
    if config is not None:
        return str(config)
    from orbitrig.config import default_rig_path

    return str(default_rig_path())

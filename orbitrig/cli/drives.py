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
from orbitrig.cli.drives_stop import reason, report, stop_drives, stop_outcome
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
        from orbitrig.cli.drives_status import status_of

        code = _run_async(lambda intr: status_of(url, json_out, d, id_from), "status")
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
    from orbitrig.cli.signals import take_late_signals
    from orbitrig.config import RPM, load_rig

    interrupt, rig = Interrupt(), load_rig(config)  # read already by open_config: its interlocks and CAN node
    code = _run_async(
        lambda intr: _run(url, rig, d, limits, spin * RPM, orbit * RPM, settle, timeout, hold, status_every, intr),
        "run",
        interrupt,
    )
    late = take_late_signals()
    if interrupt.released and (late or interrupt.unsaid):  # a signal, or its output failed (a full disk behind
        # standard error: its warning that the drives run on), once they were left at the setpoint
        code = _run_async(lambda intr: stop_after_release(url, d, intr, interrupt.unsaid), "run", Interrupt(late[:1]))
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
        code = _run_async(lambda intr: stop_drives(url, d, emergency, timeout, intr), "stop")
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


def _rig_drives(url, d, limits=None, *, watchdog: bool = False):
    """RigDrives with the configuration's ids, timeout, poll interval and link_loss_polls;
    ``watchdog``: both drives given [drives] comm_loss_timeout_s on entry (`run`)."""
    from orbitrig.run.drive_setup import UNLIMITED, rig_drives

    return rig_drives(url, d, UNLIMITED if limits is None else limits, watchdog=watchdog)


def _run_async(make_coro, command: str, interrupt=None) -> int:
    """Run `make_coro(interrupt)`; the first of orbitrig.cli.signals.SIGNALS cancels it -> exit 2
    (`run` stops and confirms both drives itself: drives_hold.way_out, stop_after_release), except
    while it holds (`run --hold`), where it ends the hold, and once a stop is under way (`stop` with
    the drives open, a way out's ramp), where it makes it the emergency stop (drives_hold.Interrupt,
    a new one unless given). Signals after it are recorded only (orbitrig.cli.signals.hand_over)."""
    import asyncio

    from drives.errors import DriveError
    from orbitrig.cli.drives_hold import Interrupt
    from orbitrig.cli.signals import hand_over, refuse_suspension, take_late_signals, watched
    from orbitrig.cli.terminal import OutputError, off_the_loop, say, say_aside

    _quiet_logging(command)
    interrupt = Interrupt() if interrupt is None else interrupt
    take_late_signals()  # those of an earlier command in this process (its own were acted on)

    async def main() -> int:
        task = asyncio.current_task()
        assert task is not None
        loop = asyncio.get_running_loop()
        for sig in watched():
            loop.add_signal_handler(sig, interrupt.on_signal, sig, task)
        if command != "status":  # `run` and `stop` command the drives
            refuse_suspension(loop, f"drives {command}", say_aside)
        try:
            return await make_coro(interrupt)
        except asyncio.CancelledError:
            if not interrupt.received:
                raise
            task.uncancel()
            after = {"status": "", "stop": "; stop sent to both drives"}.get(command, "; nothing commanded")
            say(f"orbitrig drives {command}: interrupted by {interrupt.received[-1].name}{after}", err=True)
            return 2
        except (DriveError, OutputError) as err:
            report(command, err)
            return 2
        finally:
            hand_over(loop)

    code = 0
    try:
        with off_the_loop():  # a terminal that stops reading (Ctrl-S) holds neither the poll nor a signal
            code = asyncio.run(main())
    except OutputError as err:
        if interrupt.released:  # the drives left at the setpoint: `run` stops them first (_run_command)
            interrupt.unsaid = err
            return 2
        report(command, err)
        return code or 2  # a failure's own status stands: 1 (not confirmed stopped), 4 (emergency stop)
    return code


def _quiet_logging(command: str) -> None:
    """The drives' log warnings (link loss) on stderr under the command's name, `orbitrig drives
    stop: stop command not delivered: ...` (the drives left running are said by the terminal's writer: `_release`);
    pymodbus' own error lines repeat what our messages say, so they are silenced."""
    import logging

    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    if not logging.getLogger().handlers:
        logging.basicConfig(level=logging.WARNING, format=f"orbitrig drives {command}: %(message)s")


async def _run(url, rig_config, d, limits, spin, orbit, settle, timeout, hold, status_every, interrupt) -> int:
    """The limits checked, the rig's CAN node opened and watched (drives_watch; the configuration has
    none: not watched), then `_run_open`."""
    import contextlib

    from daq.errors import DaqError
    from drives.errors import DriveError
    from orbitrig.cli.drives_watch import opened_watch, unopened_node
    from orbitrig.cli.failure import say_error

    try:
        limits.check(spin, orbit, spin_id=d.spin_id, orbit_id=d.orbit_id)
    except DriveError as err:
        report("run", err, "nothing sent")  # refused before connecting at all
        return 2
    async with contextlib.AsyncExitStack() as node:
        try:
            watch = await opened_watch(node, rig_config)
        except DaqError as err:
            say_error(unopened_node(err, rig_config), "can", "drives run")
            return 2
        return await _run_open(url, d, limits, spin, orbit, (settle, timeout, hold, status_every), interrupt, watch)


async def _run_open(url, d, limits, spin, orbit, how, interrupt, watch) -> int:
    """The drives opened, watched (`watch`: the rig's interlocks, None without a CAN node), to the
    setpoint and released or held (`how`: settle, timeout, hold, status_every)."""
    import asyncio

    from drives.errors import DriveError
    from orbitrig.cli.drives_hold import armed_watchdog, stop_after_entry, stop_after_release, way_out
    from orbitrig.cli.terminal import OutputError

    settle, timeout, hold, status_every = how
    rig, code = _rig_drives(url, d, limits, watchdog=True), None
    released = opened = False
    try:
        async with rig:
            opened = True
            if watch is not None:
                watch.start(rig, interrupt)
            try:
                armed_watchdog(rig, d.comm_loss_timeout_s)  # before anything is commanded
                code = await _to_setpoint(rig, spin, orbit, settle, timeout, hold, status_every, interrupt)
                if not hold:  # at the setpoint
                    await _release(rig, d.comm_loss_timeout_s)
                    released = interrupt.released = True
            except BaseException as err:  # noqa: BLE001 - every way out but the release: both drives stopped first
                code = await way_out(rig, err, interrupt, reason)
            return code
    except asyncio.CancelledError:
        if not opened and interrupt.received:  # a signal while opening the drives: found turning, not left so
            return await stop_after_entry(url, d, interrupt)
        if not (released and interrupt.received):
            raise
        return await stop_after_release(url, d, interrupt)  # a signal during the rig's exit
    except (DriveError, OutputError) as err:
        if released:  # the poll found a failure, or the exit's warning could not be written (a full disk
            # behind standard error): the exit stopped both as it left them; confirmed stopped here
            return await stop_after_release(url, d, interrupt, err)
        if isinstance(err, OutputError):
            raise
        if code is not None:  # the exit's repeated stop word failed after the way out said how the drives ended
            return code
        report("run", err, stop_outcome(rig) + _refused_watchdog(err))  # the rig could not be opened: its entry's stop
        return 2


def _refused_watchdog(err) -> str:
    """A hint when a drive refused [drives] comm_loss_timeout_s on entry (exception 03)."""
    from drives.errors import DriveExceptionResponse
    from drives.registers import COMM_LOSS_TIMEOUT

    if not isinstance(err, DriveExceptionResponse) or err.register != COMM_LOSS_TIMEOUT:
        return ""
    return (
        "; the drive did not take [drives] comm_loss_timeout_s as its COMM_LOSS_TIMEOUT (a drive takes one only "
        "at standstill and within its range; one found turning was given the ramp stop, as said above)"
    )


async def _to_setpoint(rig, spin, orbit, settle, timeout, hold, status_every, interrupt) -> int:
    """Both drives to the setpoint (exit 0: `_release` follows) and held there (`--hold`)."""
    from orbitrig.cli.drives_hold import _hold, _state_lines
    from orbitrig.cli.terminal import output_taken

    await rig.set_speeds(spin, orbit)
    state = await rig.wait_settled(hold=settle, timeout=timeout)
    _state_lines(state)
    if not hold:  # the lines written (or their reader gone) before the drives are left running: a full disk fails here
        await output_taken()
        return 0
    return await _hold(rig, status_every, interrupt)


async def _release(rig, wanted: float) -> None:
    """Leave both drives at the setpoint, only if each one's comm-loss watchdog, read back now, is
    armed (else WatchdogOff: the way out stops both). The rig's exit says once that it left them
    running, with the seconds their watchdog gives (as read now), unless the poll stopped them: on
    standard error by the terminal's writer, so that one that cannot be written (a full disk) is an
    OutputError at the command's boundary (`_run_command`), which stops both and says how they ended."""
    from orbitrig.cli.drives_hold import armed_watchdog
    from orbitrig.cli.terminal import say

    for drive in (rig.spin, rig.orbit):
        await drive.read_parameters()  # what each holds now, not what it held on entry
    armed_watchdog(rig, wanted)
    rig.release(said=lambda words: say(f"orbitrig drives run: WARNING: {words}", err=True))

"""`orbitrig drives status|run|stop`: the spindle drives from the command line.

Speeds are rpm here (the command line is an edge); the drive API underneath
is rad/s. Exit status: 0 done, 2 failed (the reason is printed on standard
error, and `run` has stopped both drives by then).
"""

from __future__ import annotations

import math

import typer

_REQUEST_TIMEOUT = 0.5  # s; well below the drives' default 1.0 s comm-loss watchdog
_MODBUS_HELP = "Modbus URL of the drives: tcp://host:port or rtu:///dev/ttyX?baud=19200"


def register(app: typer.Typer) -> None:
    """Add the `drives` sub-app to the `orbitrig` command."""
    drives_app = typer.Typer(
        help="Spindle drives over Modbus: status, run to a setpoint, stop.",
        no_args_is_help=True,
    )

    @drives_app.command("status")
    def status(
        modbus: str = typer.Option(..., "--modbus", help=_MODBUS_HELP),
        json_out: bool = typer.Option(False, "--json", help="One JSON object on standard output."),
        spin_id: int = typer.Option(1, help="Device id of the spin drive."),
        orbit_id: int = typer.Option(2, help="Device id of the orbit drive."),
    ) -> None:
        """Print both drives' state, reference and actual speed (rpm), torque and fault.

        Only reads: running drives keep running.
        """
        raise typer.Exit(_run_async(lambda: _status(modbus, json_out, spin_id, orbit_id), "status"))

    @drives_app.command("run")
    def run(
        modbus: str = typer.Option(..., "--modbus", help=_MODBUS_HELP),
        spin: float = typer.Option(..., "--spin", help="Spin speed omega, rpm (>= 0)."),
        orbit: float = typer.Option(
            ..., "--orbit", help="Orbit speed Omega, rpm; negative = backward whirl."
        ),
        max_spin: float = typer.Option(
            math.inf, "--max-spin", help="Refuse a spin speed above this, rpm."
        ),
        max_orbit: float = typer.Option(
            math.inf, "--max-orbit", help="Refuse an |orbit| speed above this, rpm."
        ),
        min_ratio: float = typer.Option(None, "--min-ratio", help="Smallest |Omega|/omega."),
        max_ratio: float = typer.Option(None, "--max-ratio", help="Largest |Omega|/omega."),
        settle: float = typer.Option(
            1.0, "--settle", help="Seconds both drives must hold AT_SETPOINT."
        ),
        timeout: float = typer.Option(120.0, "--timeout", help="Seconds to reach the setpoint."),
        spin_id: int = typer.Option(1, help="Device id of the spin drive."),
        orbit_id: int = typer.Option(2, help="Device id of the orbit drive."),
    ) -> None:
        """Bring both drives to speed; exit 0 once both hold their setpoint.

        Limits are checked before anything is sent. On any failure (limit,
        fault, timeout, link, Ctrl-C, SIGTERM) both drives are ramped to zero
        and the command exits 2 with the reason. On success the drives are
        left at their setpoint; without a polling client their comm-loss
        watchdog then ramps them down after COMM_LOSS_TIMEOUT.
        """
        from drives.drive import RPM
        from drives.rig import DriveLimits

        limits = DriveLimits(
            max_spin=max_spin * RPM,
            max_orbit=max_orbit * RPM,
            min_ratio=min_ratio,
            max_ratio=max_ratio,
        )
        raise typer.Exit(
            _run_async(
                lambda: _run(modbus, limits, spin * RPM, orbit * RPM, settle, timeout,
                             spin_id, orbit_id),
                "run",
            )
        )

    @drives_app.command("stop")
    def stop(
        modbus: str = typer.Option(..., "--modbus", help=_MODBUS_HELP),
        emergency: bool = typer.Option(
            False, "--emergency", help="Emergency stop (OFF3, fastest ramp) instead of OFF1."
        ),
        timeout: float = typer.Option(
            None, "--timeout", help="Seconds to reach zero (default: from the ramp times)."
        ),
        spin_id: int = typer.Option(1, help="Device id of the spin drive."),
        orbit_id: int = typer.Option(2, help="Device id of the orbit drive."),
    ) -> None:
        """Stop both drives; returns once both read zero speed."""
        raise typer.Exit(
            _run_async(lambda: _stop(modbus, emergency, timeout, spin_id, orbit_id), "stop")
        )

    app.add_typer(drives_app, name="drives")


def _reason(err: BaseException) -> str:
    from drives.errors import (
        DriveExceptionResponse,
        DriveFaultError,
        DriveLimitError,
        DriveLinkError,
        DriveTimeoutError,
    )

    for cls, word in (
        (DriveLimitError, "limit"),
        (DriveFaultError, "fault"),
        (DriveTimeoutError, "timeout"),
        (DriveLinkError, "link"),
        (DriveExceptionResponse, "refused"),
    ):
        if isinstance(err, cls):
            return word
    return "error"


def _run_async(make_coro, command: str) -> int:
    """Run a command coroutine; SIGINT/SIGTERM cancel it (so its drives stop) -> exit 2."""
    import asyncio
    import signal

    from drives.errors import DriveError

    _quiet_logging()

    async def main() -> int:
        task = asyncio.current_task()
        loop = asyncio.get_running_loop()
        received: list[signal.Signals] = []

        def on_signal(sig: signal.Signals) -> None:
            received.append(sig)
            task.cancel()

        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(sig, on_signal, sig)
        try:
            return await make_coro()
        except asyncio.CancelledError:
            if not received:
                raise
            task.uncancel()
            after = "" if command == "status" else "; stop sent to both drives"
            typer.echo(
                f"orbitrig drives {command}: interrupted by {received[0].name}{after}", err=True
            )
            return 2
        except DriveError as err:
            _report(command, err)
            return 2
        finally:
            for sig in (signal.SIGINT, signal.SIGTERM):
                loop.remove_signal_handler(sig)

    return asyncio.run(main())


def _quiet_logging() -> None:
    """Our warnings (link loss, drives left running) on stderr; pymodbus' own
    error lines repeat what our messages say, so they are silenced."""
    import logging

    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    if not logging.getLogger().handlers:
        logging.basicConfig(level=logging.WARNING, format="orbitrig %(name)s: %(message)s")


def _stop_outcome(rig) -> str:
    """What became of the stop a failed RigDrives session sent on its way out."""
    if rig is None or rig.link.connects == 0:
        return "nothing sent"
    if rig.stop_errors:
        return (
            f"stop NOT delivered ({rig.stop_errors[0]}); the drives' comm-loss watchdog "
            "stops them"
        )
    return "stop sent to both drives"


def _report(command: str, err: BaseException, after: str = "") -> None:
    tail = f"; {after}" if after else ""
    typer.echo(f"orbitrig drives {command} failed ({_reason(err)}): {err}{tail}", err=True)


def _drive_line(d: dict) -> str:
    flags = ", at setpoint" if d["at_setpoint"] else ""
    return (
        f"{d['state']}{flags}; REF {d['reference_rpm']:.1f} rpm, ACT {d['actual_rpm']:.1f} rpm, "
        f"torque {d['torque_pct']:.1f} %, fault {d['fault_code']} ({d['fault']}), "
        f"CW {d['control_word']}, SW {d['status_word']}"
    )


async def _status(url: str, json_out: bool, spin_id: int, orbit_id: int) -> int:
    import json

    from drives.drive import Drive, rad_s_to_rpm
    from drives.link import ModbusLink

    out: dict = {"modbus": url}
    async with ModbusLink(url, names={spin_id: "spin", orbit_id: "orbit"}) as link:
        for name, device_id, bidirectional in (("spin", spin_id, False), ("orbit", orbit_id, True)):
            drive = Drive(link, device_id, name, bidirectional=bidirectional)
            params = await drive.read_parameters()
            d = (await drive.read_status()).to_dict()
            d["parameters"] = {
                "speed_scale_rpm": round(rad_s_to_rpm(params.speed_scale), 3),
                "max_speed_rpm": round(rad_s_to_rpm(params.max_speed), 3),
                "accel_time_s": params.accel_time,
                "decel_time_s": params.decel_time,
                "comm_loss_timeout_s": params.comm_loss_timeout,
                "at_setpoint_band_rpm": round(rad_s_to_rpm(params.at_setpoint_band), 3),
            }
            out[name] = d
    if json_out:
        typer.echo(json.dumps(out))
    else:
        for name in ("spin", "orbit"):
            d = out[name]
            typer.echo(f"{name:5s} (id {d['device_id']}): {_drive_line(d)}")
    return 0


async def _run(url, limits, spin, orbit, settle, timeout, spin_id, orbit_id) -> int:
    from drives.errors import DriveError
    from drives.rig import RigDrives

    try:
        limits.check(spin, orbit, spin_id=spin_id, orbit_id=orbit_id)
    except DriveError as err:
        _report("run", err, "nothing sent")  # refused before connecting at all
        return 2
    rig = None
    try:
        async with RigDrives(
            url, limits, spin_id=spin_id, orbit_id=orbit_id, timeout=_REQUEST_TIMEOUT
        ) as rig:
            await rig.set_speeds(spin, orbit)
            state = await rig.wait_settled(hold=settle, timeout=timeout)
            rig.release()
    except DriveError as err:
        _report("run", err, _stop_outcome(rig))
        return 2
    for s in (state.spin, state.orbit):
        typer.echo(f"{s.name:5s} (id {s.device_id}): {_drive_line(s.to_dict())}")
    return 0


async def _stop(url, emergency, timeout, spin_id, orbit_id) -> int:
    from drives.errors import DriveError
    from drives.rig import DriveLimits, RigDrives

    try:
        async with RigDrives(
            url,
            DriveLimits(math.inf, math.inf),
            spin_id=spin_id,
            orbit_id=orbit_id,
            timeout=_REQUEST_TIMEOUT,
        ) as rig:
            await rig.stop(emergency=emergency, wait=True, timeout=timeout)
            state = rig.state
    except DriveError as err:
        # The controller could not be opened (or the wait failed): still put the
        # stop word on the line for each drive that answers, without reading first.
        sent = await _stop_words_best_effort(url, emergency, spin_id, orbit_id)
        _report("stop", err, f"stop word delivered to: {', '.join(sent) or 'no drive'}")
        return 2
    for s in (state.spin, state.orbit):
        typer.echo(f"{s.name:5s} (id {s.device_id}): {_drive_line(s.to_dict())}")
    return 0


async def _stop_words_best_effort(url, emergency, spin_id, orbit_id) -> list[str]:
    from drives.drive import Drive
    from drives.link import ModbusLink
    from drives.rig import send_stop

    link = ModbusLink(url, timeout=_REQUEST_TIMEOUT, names={spin_id: "spin", orbit_id: "orbit"})
    drives = [
        Drive(link, spin_id, "spin", bidirectional=False),
        Drive(link, orbit_id, "orbit", bidirectional=True),
    ]
    try:
        missed = {err.drive for err in await send_stop(drives, emergency=emergency)}
    finally:
        await link.close()
    return [f"{d.name} (id {d.device_id})" for d in drives if d.device_id not in missed]

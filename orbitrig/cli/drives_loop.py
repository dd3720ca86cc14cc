"""The event loop a `drives` command runs in: the first signal cancels it, ends the hold, or makes
a stop under way the emergency stop (drives_hold.Interrupt); a drive's failure or output that
cannot be written is said once under the command's name (drives_stop.report), with its exit status."""

from __future__ import annotations

from orbitrig.cli.drives_stop import report


def run_async(make_coro, command: str, interrupt=None) -> int:
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
        if interrupt.released:  # the drives left at the setpoint: `run` stops them first (drives._run_command)
            interrupt.unsaid = err
            return 2
        report(command, err)
        return code or 2  # a failure's own status stands: 1 (not confirmed stopped), 4 (emergency stop)
    return code


def _quiet_logging(command: str) -> None:
    """The drives' log warnings (link loss) on stderr under the command's name, `orbitrig drives
    stop: stop command not delivered: ...` (the drives left running are said by the terminal's writer: drives_run._release);
    pymodbus' own error lines repeat what our messages say, so they are silenced."""
    import logging

    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    if not logging.getLogger().handlers:
        logging.basicConfig(level=logging.WARNING, format=f"orbitrig drives {command}: %(message)s")

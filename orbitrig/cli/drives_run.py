"""What `orbitrig drives run` does once its options are read (drives._run_command): the limits
checked, the rig's CAN node opened and watched, both drives to the setpoint and released there
(each with an armed comm-loss watchdog) or held (`--hold`); every other way out stops both first
(drives_hold.way_out). Speeds are rad/s here."""

from __future__ import annotations

from orbitrig.cli.drives_stop import reason, report, stop_outcome


def _rig_drives(url, d, limits=None, *, watchdog: bool = False):
    """RigDrives with the configuration's ids, timeout, poll interval and link_loss_polls;
    ``watchdog``: both drives given [drives] comm_loss_timeout_s on entry (`run`)."""
    from orbitrig.run.drive_setup import UNLIMITED, rig_drives

    return rig_drives(url, d, UNLIMITED if limits is None else limits, watchdog=watchdog)


async def run_drives(url, rig_config, d, limits, spin, orbit, settle, timeout, hold, status_every, interrupt) -> int:
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
    from orbitrig.cli.drives_hold import hold_at_setpoint, say_drive_states
    from orbitrig.cli.terminal import output_taken

    await rig.set_speeds(spin, orbit)
    state = await rig.wait_settled(hold=settle, timeout=timeout)
    say_drive_states(state)
    if not hold:  # the lines written (or their reader gone) before the drives are left running: a full disk fails here
        await output_taken()
        return 0
    return await hold_at_setpoint(rig, status_every, interrupt)


async def _release(rig, wanted: float) -> None:
    """Leave both drives at the setpoint, only if each one's comm-loss watchdog, read back now, is
    armed (else WatchdogOff: the way out stops both). The rig's exit says once that it left them
    running, with the seconds their watchdog gives (as read now), unless the poll stopped them: on
    standard error by the terminal's writer, so that one that cannot be written (a full disk) is an
    OutputError at the command's boundary (`drives._run_command`), which stops both and says how they ended."""
    from orbitrig.cli.drives_hold import armed_watchdog
    from orbitrig.cli.terminal import say

    for drive in (rig.spin, rig.orbit):
        await drive.read_parameters()  # what each holds now, not what it held on entry
    armed_watchdog(rig, wanted)
    rig.release(said=lambda words: say(f"orbitrig drives run: WARNING: {words}", err=True))

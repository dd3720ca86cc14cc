"""An abort that no run carries out: both drives' emergency stop (OFF3) over a Modbus link of
the service's own, best effort, sent as `orbitrig drives stop` sends its stop words when it
cannot open the drives' controller (a `drives.stop.StopSender` of the bare pair of
orbitrig.run.drive_setup: no status read first, each drive tried even if the other is silent).

The rig service sends it when an abort arrives and no run holds the drives: the run has ended
(its cleanup closed their link, also when it could not confirm them stopped: "drives not
confirmed stopped") or is not holding them yet. A first connect that fails is tried once more
(`_open_again`): a gateway refusing or slow for a moment does not leave the stop unsent. An abort is never answered ok with nothing
sent (docs/protocols/mqtt.md, "Commands"). A second signal to `orbitrig serve` that no run takes
(RigService.abort_run), and a signal or an abort at the terminal of `orbitrig sweep` that its run
no longer carries out (orbitrig.cli.operator), send the same, from here; so does the first signal
to `orbitrig serve` with no run to stop the drives (its outcome decides serve's exit status). A
`stop` that no run carries out sends the ramp stop (OFF1) the same way, after one read of each
drive's status word (`drives.read_first.read_first`: one exchange, no retries): a drive turning in its
emergency ramp (an emergency stop another link or process sent) makes it the emergency stop (OFF3),
the service records it as such before its words go out (`decided`: an abort meanwhile is answered
by it, as by an abort's emergency stop under way) and the reply says so, failed or not; a drive
that cannot be read leaves it the ramp stop, said as not read. An
abort while that ramp stop goes out makes it the emergency stop (`escalate`: its words still to go
out OFF3, a drive that took its OFF1 given OFF3 next, orbitrig.run.stop_words.sent_escalating),
beside the abort's own emergency stop: no ramp stop word follows the abort's OFF3."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable

from drives.errors import DriveError
from drives.link import ModbusLink
from drives.read_first import read_first
from drives.stop import StopSender
from drives.stop_said import stop_kind, took_it
from orbitrig.config import Drives
from orbitrig.run.drive_setup import bare_drives, modbus_link
from orbitrig.run.stop_words import sent_escalating

log = logging.getLogger("orbitrig.service.rig_service")

ESTOP = "use the rig's emergency stop"
#: said of a stop sent over the service's own link, unless a run held the drives (cancelled)
NO_RUN = "no run held them"
#: the reply's error when the service was built without a drive link (`orbitrig serve` gives one)
NO_DRIVE_LINK = f"not sent: no run holds the drives and the service was given no drive link; {ESTOP}"

#: (error, detail) of an abort's reply: error None is ok: true
Outcome = tuple[str | None, str | None]
#: (Modbus URL, [drives]) of the rig's drives
DriveLink = tuple[str, Drives]
#: the drive link of the rig configuration loaded last, asked at the time of each stop
DriveLinkSource = Callable[[], DriveLink]
#: wall s a shutdown waits for the emergency stop its signal sent with no run to stop the drives
SIGNAL_STOP_S = 30.0

#: wall s an abort's stop waits for a run it cancelled (one being opened) to let go of the
#: drives' link, when that link cannot be opened beside it (an RTU port is opened exclusively)
LET_GO_S = 5.0
#: wall s between two tries to open that link meanwhile
RETRY_S = 0.05


async def emergency_stop(
    url: str,
    d: Drives,
    holder: asyncio.Future[object] | None = None,
    *,
    own: str = "the service's",
    emergency: bool = True,
    escalate: asyncio.Event | None = None,
    decided: Callable[[], None] | None = None,
    who: str | None = None,
    log_outcome: bool = True,
    held: str | None = None,
) -> Outcome:
    """OFF3 (``emergency``; else OFF1, a `stop`'s ramp stop, made OFF3 if a drive reads in its
    emergency ramp first: `read_first`, `decided()` called then, before its words go out, or once
    `escalate` is set: an abort meanwhile, its words
    still to go out OFF3 and a drive that took OFF1 given OFF3 next, so that no OFF1 follows the
    abort's OFF3) to both drives of [drives] `d` at `url` over a fresh link
    (`own`: whose), then zero references: (None, what was sent) if both took it, else (why not,
    naming the drives that took it, None); never raises but a cancellation. `holder`:
    the task of a run the abort cancelled before it held the drives (it may hold their port while
    being opened): if the link cannot be opened, it is tried again once that run has ended (at most
    LET_GO_S). `who`: the request it carries out as its log lines name it (None: ``abort``/``stop``).
    `log_outcome`: the outcome (sent, or not sent at all) logged here; False: its caller logs it, once.
    `held`: why no run carried it out, said instead of 'no run held them' (a run cancelled)."""
    name, word, cmd = _words(emergency)
    what = f"{name} ({word})"
    cmd = who or cmd
    log.warning("%s: %s: %s to both over a link of its own (%s)", cmd, held or "no run holds the drives", what, url)
    link: ModbusLink | None = None
    going = emergency  # the stop going out (a read in an emergency ramp, an abort: the emergency stop)
    try:
        link = modbus_link(url, d)
        pair = bare_drives(link, d)
        not_open = await _open(link, holder)
        if not_open is not None:
            if log_outcome:
                log.error("%s: %s not sent: %s", cmd, what, not_open)
            return f"{name} NOT sent (no run holds the drives): {not_open}; {ESTOP}", None
        read = None if emergency else await read_first(pair)
        early = not emergency and escalate is not None and escalate.is_set()  # an abort during the reads
        if not emergency and read is not None and read.emergency and decided is not None:
            decided()  # the emergency stop from now on, as recorded by whoever asked
        emergency = emergency or early or (read is not None and read.emergency)
        what, going = stop_kind(emergency, None if early else read), emergency  # the words going out
        errors, escalated = await sent_escalating(StopSender(pair), emergency, escalate)
        what = f"{stop_kind(True)}, by an abort during the {name}," if early or escalated else what
    except Exception as err:  # an outcome, never the end of its caller
        log.exception("%s: the %s over a link of its own failed", cmd, what)
        return f"{_words(going)[0]} NOT confirmed sent: {type(err).__name__}: {err}; {ESTOP}", None
    finally:
        if link is not None:
            await link.close()
    if not errors:
        if log_outcome:
            log.warning("%s: %s sent to both drives (%s)", cmd, what, held or NO_RUN)
        return None, f"{what} sent to both drives over a link of {own} own ({held or NO_RUN})"
    sent = took_it(pair, errors)
    why = "; ".join(str(err) for err in errors)
    return f"{what} delivered to {', '.join(sent) or 'no drive'} only: {why}; {ESTOP}", None


def _words(emergency: bool) -> tuple[str, str, str]:
    """(the stop's name, its control word, the command it answers) of an emergency or a ramp stop."""
    return ("emergency stop", "OFF3", "abort") if emergency else ("ramp stop", "OFF1", "stop")


async def _open(link: ModbusLink, holder: asyncio.Future[object] | None) -> str | None:
    """Open `link`; if that fails while `holder` runs, again every RETRY_S until it opens, for at
    most LET_GO_S (the port is taken the moment the run lets go of it, not when the run has ended);
    once more after a failure with no run holding it (`_open_again`); None if open, else why not."""
    try:
        await link.connect()
        return None
    except DriveError as err:
        if holder is None or holder.done():
            return await _open_again(link, err)
        log.warning(
            "abort: the drives' link is busy (%s): waiting up to %.0f s for the run (or a start's check) to let go",
            err,
            LET_GO_S,
        )
        busy = err
    end = asyncio.get_running_loop().time() + LET_GO_S
    while not holder.done() and (left := end - asyncio.get_running_loop().time()) > 0:
        await asyncio.wait([holder], timeout=min(RETRY_S, left))
        try:
            await link.connect()
            return None
        except DriveError as err:
            busy = err
    if not holder.done():
        return f"cannot open their link: a run being opened still holds it after {LET_GO_S:g} s ({busy})"
    return await _open_again(link, busy)


async def _open_again(link: ModbusLink, first: DriveError) -> str | None:
    """One more try at opening `link` RETRY_S after a failed one (`first`): a connect that timed
    out on a host or gateway busy for a moment is no reason to leave the stop unsent; None if
    open, else why not (both failures)."""
    log.warning("stop: cannot open the drives' link (%s): trying once more", first)
    await asyncio.sleep(RETRY_S)
    try:
        await link.connect()
        return None
    except DriveError as err:
        return f"cannot open their link (tried twice): {first}; then {err}"


def start(
    group: asyncio.TaskGroup | None,
    drive_link: DriveLink | None,
    holder,
    why: str | None = None,
    *,
    emergency: bool = True,
    escalate: asyncio.Event | None = None,
    decided: Callable[[], None] | None = None,
    held: str | None = None,
) -> asyncio.Task[Outcome] | str:
    """`emergency_stop` (``emergency``: OFF3, else OFF1, made OFF3 once `escalate` is set, or by a
    drive read in its emergency ramp: `decided()` called) to
    `drive_link` in a task of its own
    (delivered even if whoever asked is cancelled), which `group` (the service's; None: none) waits
    for (`_held`: a cancellation of the group, a fault in another of its tasks among them, does not
    cut the stop short); ``why``: the request of the service's own it carries out (a signal), its
    outcome then logged. Else (logged) why it cannot be sent: no drive link known, or nothing to
    run it any more (the service has ended). Each outcome is logged once. `held`: as `emergency_stop`'s."""
    name, _, cmd = _words(emergency)
    who = f"{cmd} ({why})" if why else cmd
    if drive_link is None:
        log.error("%s: %s", who, NO_DRIVE_LINK)
        return NO_DRIVE_LINK
    stop = emergency_stop(
        *drive_link,
        holder,
        emergency=emergency,
        escalate=escalate,
        decided=decided,
        who=who,
        log_outcome=not why,
        held=held,
    )
    task: asyncio.Task[Outcome] | None = None
    try:
        task = asyncio.get_running_loop().create_task(stop, name=f"drives-{name.replace(' ', '-')}")
        if group is not None:
            waits = _held(task)
            try:
                group.create_task(waits, name=f"awaiting-drives-{name.replace(' ', '-')}")
            except RuntimeError:
                waits.close()
                raise
    except RuntimeError as err:  # the service's TaskGroup has finished, or no loop runs
        if task is None:
            stop.close()
        else:
            task.cancel()  # before its first step: nothing was sent
        log.error("%s: %s NOT sent: %s; %s", who, name, err, ESTOP)
        return f"not sent: {err}; {ESTOP}"
    if why:
        task.add_done_callback(lambda done: _log_outcome(done, who))
    return task


async def _held(task: asyncio.Task[Outcome]) -> None:
    """Wait for the stop `task` (in the service's task group: the service leaves once it is over);
    cancelled meanwhile (the group ends: a fault in another of its tasks), the stop goes on and is
    waited for, at most SIGNAL_STOP_S, before the cancellation is raised again."""
    try:
        await asyncio.wait([task])
    except asyncio.CancelledError:
        await asyncio.wait([task], timeout=SIGNAL_STOP_S)
        raise


def _log_outcome(task: asyncio.Task[Outcome], who: str) -> None:
    if task.cancelled():
        log.error("%s: stop not confirmed sent: cancelled; %s", who, ESTOP)
        return
    error, detail = task.result()
    if error is None:
        log.warning("%s: %s", who, detail)
    else:
        log.error("%s: %s", who, error)


async def outcome_within(task: asyncio.Task[Outcome], seconds: float) -> Outcome:
    """The outcome of `task` (an `emergency_stop`), waited for at most `seconds` (wall): beyond
    that the task is cancelled and the outcome says the stop is not confirmed sent."""
    done, _ = await asyncio.wait([task], timeout=seconds)
    if not done:
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)
        return f"emergency stop not confirmed sent within {seconds:g} s; {ESTOP}", None
    if task.cancelled():
        return f"emergency stop not confirmed sent: cancelled; {ESTOP}", None
    return task.result()

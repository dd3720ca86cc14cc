"""An abort that no run carries out: both drives' emergency stop (OFF3) over a Modbus link of
the service's own, best effort, sent as `orbitrig drives stop` sends its stop words when it
cannot open the drives' controller (`drives.stop.send_stop` to the bare pair of
orbitrig.run.drive_setup: no status read first, each drive tried even if the other is silent).

The rig service sends it when an abort arrives and no run holds the drives: the run has ended
(its cleanup closed their link, also when it could not confirm them stopped: "drives not
confirmed stopped") or is not holding them yet. An abort is never answered ok with nothing
sent (docs/protocols/mqtt.md, "Commands")."""

from __future__ import annotations

import asyncio
import logging

from drives.errors import DriveError
from drives.link import ModbusLink
from drives.stop import send_stop, took_it
from orbitrig.config import Drives
from orbitrig.run.drive_setup import bare_drives, modbus_link

log = logging.getLogger("orbitrig.service.rig_service")

ESTOP = "use the rig's emergency stop"
#: the reply's error when the service was built without a drive link (`orbitrig serve` gives one)
NO_DRIVE_LINK = f"not sent: no run holds the drives and the service was given no drive link; {ESTOP}"

#: (error, detail) of an abort's reply: error None is ok: true
Outcome = tuple[str | None, str | None]

#: wall s an abort's stop waits for a run it cancelled (one being opened) to let go of the
#: drives' link, when that link cannot be opened beside it (an RTU port is opened exclusively)
LET_GO_S = 5.0


async def emergency_stop(url: str, d: Drives, holder: asyncio.Future[object] | None = None) -> Outcome:
    """OFF3 to both drives of [drives] `d` at `url` over a fresh link, then zero references:
    (None, what was sent) if both took it, else (why not, None). `holder`: the task of a run
    the abort cancelled before it held the drives (it may hold their port while being opened):
    if the link cannot be opened, it is tried again once that run has ended (at most LET_GO_S)."""
    link = modbus_link(url, d)
    pair = bare_drives(link, d)
    log.warning("abort: no run holds the drives: emergency stop (OFF3) to both over a link of its own (%s)", url)
    try:
        not_open = await _open(link, holder)
        if not_open is not None:
            log.error("abort: emergency stop not sent: %s", not_open)
            return f"emergency stop NOT sent (no run holds the drives): {not_open}; {ESTOP}", None
        errors = await send_stop(pair, emergency=True)
    finally:
        await link.close()
    if not errors:
        log.warning("abort: emergency stop (OFF3) sent to both drives (no run held them)")
        return None, "emergency stop (OFF3) sent to both drives over a link of the service's own (no run held them)"
    sent = took_it(pair, errors)
    why = "; ".join(str(err) for err in errors)
    return f"emergency stop (OFF3) delivered to {', '.join(sent) or 'no drive'} only: {why}; {ESTOP}", None


async def _open(link: ModbusLink, holder: asyncio.Future[object] | None) -> str | None:
    """Open `link`, once more after `holder` ends if the first try fails while it runs; None if
    open, else why not."""
    try:
        await link.connect()
        return None
    except DriveError as err:
        if holder is None or holder.done():
            return f"cannot open their link: {err}"
        log.warning("abort: the drives' link is busy (%s): waiting up to %.0f s for the run to let go", err, LET_GO_S)
    await asyncio.wait([holder], timeout=LET_GO_S)
    if not holder.done():
        return f"cannot open their link: a run being opened still holds it after {LET_GO_S:g} s"
    try:
        await link.connect()
        return None
    except DriveError as err:
        return f"cannot open their link: {err}"

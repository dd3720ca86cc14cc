"""A drive the poll finds running while a stop is owed and that refuses the stop sent again in
local control (drives/local_control.py: its keypad has it), said at a pace a reader can follow.
The rig's stop that sends its word again until taken (drives/stop_again.py, a refusal that may
pass: a keypad that answers busy) is said at the same pace, through the same holds (RigStop).

The poll sends the owed stop again at every poll for as long as the drive runs (drives/owed.py);
that does not change here. What is said of it does: the first refusal in local control is said
as before (the finding, the refusal, ERROR) and once more that the stop keeps going out at every
poll while the keypad holds it (WARNING); from then on each poll's finding and refusal of that
drive is a DEBUG line, and every `STILL_HELD_S` s a WARNING says it still holds (how long, how
many stops refused); the stop it takes at last (the keypad gave it back), or its keypad's own stop
(no stop owed any more), is said once (WARNING). A refusal for another reason, a stop sent by
anyone but the poll, is said as always.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Sequence

from drives.errors import DriveError, DriveExceptionResponse
from drives.local_control import LOCAL, DriveInLocalControl

log = logging.getLogger("drives.poll")  # the poll's messages keep its logger's name

#: s between the WARNINGs that a drive in local control still refuses the stop sent again
STILL_HELD_S = 30.0


@dataclasses.dataclass
class _Held:
    """One drive held in local control: since (monotonic s), last said (monotonic s), stops refused."""

    name: str
    since: float
    said: float
    refused: int = 1


class LocalHolds:
    """The drives the poll's stop sent again found held in local control (by device id)."""

    def __init__(self) -> None:
        self._held: dict[int, _Held] = {}

    def quiet(self, err: DriveError) -> bool:
        """Whether `err` of a stop sent again is said already: a refusal (an exception answer: in
        local control, or not read as such yet, its retry's) by a drive known held (DEBUG, not ERROR). The
        stop's own line of a refusal is DEBUG only once read as local control (drives/stop.py `_stop`)."""
        return isinstance(err, DriveExceptionResponse) and err.drive in self._held

    def known(self, problem: DriveError | None) -> bool:
        """Whether the poll's finding `problem` is of a drive known held (its ERROR said already)."""
        return problem is not None and problem.drive in self._held

    def outcome(self, errors: Sequence[DriveError], word: str) -> None:
        """The poll's stop sent again (`word`: 'ramp stop (OFF1)') ended with delivery errors
        `errors`: a drive's refusal in local control starts or continues its hold,
        said at the start and every STILL_HELD_S s; none from a drive held: it took the stop."""
        now = time.monotonic()
        refused = {e.drive: e for e in errors if isinstance(e, DriveInLocalControl)}
        for dev, held in list(self._held.items()):
            if dev not in refused and not any(e.drive == dev for e in errors):
                del self._held[dev]
                log.warning(
                    "%s took the %s sent again, %.1f s after it refused the first in local control (%d refused)",
                    held.name,
                    word,
                    now - held.since,
                    held.refused,
                )
        for refusing, err in refused.items():
            known = self._held.get(refusing) if refusing is not None else None
            if known is None:
                if refusing is not None:
                    self._held[refusing] = _Held(err.who, now, now)
                    log.warning(
                        "%s %s: the %s goes again at every poll until it takes it; said again every %g s while it holds",
                        err.who,
                        LOCAL,
                        word,
                        STILL_HELD_S,
                    )
                continue
            known.refused += 1
            if now - known.said >= STILL_HELD_S:
                known.said = now
                log.warning(
                    "%s still %s, %.1f s since it first refused the %s (%d refused); the stop goes again at every poll",
                    known.name,
                    LOCAL,
                    now - known.since,
                    word,
                    known.refused,
                )

    def not_owed(self) -> None:
        """No stop is owed any more (the drives found stopping or stopped: its keypad's own stop, a
        new speed commanded): a hold known ends, said once."""
        for held in self._held.values():
            log.warning(
                "%s no longer refuses a stop owed: none is owed any more (%.1f s after its first refusal in "
                "local control, %d refused)",
                held.name,
                time.monotonic() - held.since,
                held.refused,
            )
        self._held.clear()

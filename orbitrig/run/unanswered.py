"""A wait nobody can answer: a pause or a confirmation while no terminal and no MQTT can answer
it (`limit`, wall s) stops the run that long after the wait began, or after the limit was set if
that is later. The wait's status says when it stops the run (`held`); a wait under way when the
limit is lifted (the service's broker back) keeps its deadline until its next wake, and its stop
says that nobody answered (`stop_words`); a sweep brought to the foreground of its terminal wakes
it at once (RunEngine.attended_again: someone is there to answer). orbitrig.run.control's waits keep one of these,
and so does a calibration's prompt with the drives turning (orbitrig.cli.calibrate_prompt: its limit set
while its read fails as a background job's, lifted on `fg`); both wait with `until_woken`.
"""

from __future__ import annotations

import asyncio
import time

from drives.waits import first_set
from orbitrig.run.states import WAITING, RunState
from rigunits import now_iso, utc_iso

#: who asks for the stop when a wait nobody can answer times out (the commands log's sender)
UNANSWERED = "orbitrig"
#: who could have answered a wait that stops the run: said after the wait and its limit
NOBODY = "no terminal and no MQTT"


class UnansweredWait:
    """The limit on waits nobody can answer and the deadline the wait under way states."""

    def __init__(self) -> None:
        self.limit: float | None = None  # wall s; None: someone can answer a pause
        self._since = 0.0  # time.monotonic() when the limit was set
        self._answerable_since = ""  # when the limit was last lifted (ISO time)
        self._hold = ("", "")  # the wait under way: (its message without a deadline, what answers it)
        self.deadline: float | None = None  # the deadline its status states (time.monotonic())

    def set_limit(self, limit: float | None) -> None:
        """Nobody can answer from now on (`limit` wall s), or someone can (None)."""
        self.limit, self._since = limit, time.monotonic()
        if limit is None:
            self._answerable_since = now_iso()

    def deadline_of(self, t0: float) -> float | None:
        """When a wait begun at `t0` stops the run (time.monotonic()), or None: someone can answer."""
        return None if self.limit is None else max(t0, self._since) + self.limit

    async def until_woken(self, wake: asyncio.Event, t0: float) -> bool:
        """Until `wake` is set, or the deadline of a wait begun at `t0` (`deadline_of`, read now: a
        limit lifted meanwhile without a wake keeps it) has passed: True then, nobody answered in time."""
        deadline = self.deadline_of(t0)
        await first_set(wake, timeout=None if deadline is None else max(0.0, deadline - time.monotonic()))
        return deadline is not None and time.monotonic() >= deadline

    def held(self, message: str, answer: str, t0: float) -> str:
        """The status message of a wait begun at `t0` (`answer`: what ends it): with the time it
        stops the run if nobody can answer."""
        self._hold, self.deadline = (message, answer), self.deadline_of(t0)
        if self.deadline is None:
            return message
        at = utc_iso(time.time() + self.deadline - time.monotonic())
        return f"{message}; the run stops at {at} unless {answer} (nobody could answer: limit {self.limit:g} s)"

    def restated(self, t0: float) -> str | None:
        """The status message of the wait under way (begun at `t0`) again if its deadline changed
        (the limit set or lifted meanwhile), else None."""
        if self.deadline_of(t0) == self.deadline:
            return None
        return self.held(*self._hold, t0)

    def stop_words(self, state: RunState, limit: float) -> tuple[str, str]:
        """(who asks the stop, why) once nobody answered the wait (`state`) within `limit` s:
        nobody can answer, or the limit was lifted meanwhile (the broker back) and nobody did."""
        if self.limit is None:
            answer = "confirmed" if state == WAITING else "resumed"
            why = f"nobody {answer} within {limit:g} s: no terminal; MQTT back since {self._answerable_since}"
            return f"{UNANSWERED} ({why})", why
        waited = f"{state} for {limit:g} s, {NOBODY}"
        return f"{UNANSWERED} (nobody can answer: {waited})", f"nobody can answer ({waited})"

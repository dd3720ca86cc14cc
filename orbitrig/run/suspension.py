"""The run held by an interlock's suspension (RunControl.hold_while_suspended).

A suspend trip in force pauses the run (state paused, status `suspended by interlock: <cause>`)
until the supervisor says the condition cleared, for at most `limit` wall s (then RunFailed, naming
the cause in force then). The cause is looked at every RECHECK_S: a new one is noted in the run's
events (a warning, once per change of cause); the status keeps the cause it said first. A pause
asked meanwhile (or before, not reached yet) is said by the suspension's status, said again with
the same `since` ('...; pause requested by ada: the run stays paused once the interlock clears',
RunControl.held_words; again without it when a resume withdraws it), and holds the run once the
interlock clears; a stop or an abort asked meanwhile ends the suspension (StopRun, cancelled),
also one asked in the loop turn in which the interlock cleared.
"""

from __future__ import annotations

import time

from drives.waits import first_set
from orbitrig.run.control import RunControl, StopRun
from orbitrig.run.events import NoteKind, RunFailed, Severity
from orbitrig.run.states import CLEARED, SUSPENDED
from orbitrig.run.supervision import InterlockSupervisor

#: wall s between looks at the cause of a suspension in force (a new cause is noted in the run's events)
RECHECK_S = 0.5


async def hold(control: RunControl, sup: InterlockSupervisor, limit: float) -> None:
    """`control` paused while the trip `sup` holds is in force (see the module docstring); held on
    at a safe point once it clears if a pause was asked meanwhile."""
    trip = sup.trip
    if trip is None:
        return
    if control.stop_requested:
        raise StopRun
    t0 = time.monotonic()
    control.suspension, kind = trip, trip.kind
    control.holding = f"{SUSPENDED} {trip.message}"
    try:
        control.fire("suspend", control.held_words())  # with who asked a pause not reached yet
        while not sup.clear.is_set():
            control.end_if_aborted()
            if control.stop_requested:
                raise StopRun
            left = limit - (time.monotonic() - t0)
            if left <= 0:
                raise RunFailed(f"interlock: {(sup.trip or trip).message} for more than {limit:g} s")
            control.wake.clear()
            await first_set(sup.clear, control.wake, timeout=min(left, RECHECK_S))
            now = sup.trip
            if now is not None and now.kind != kind:  # another cause came first to the check
                kind = now.kind
                control.note(f"still {SUSPENDED} {now.message}", Severity.WARNING, NoteKind.INTERLOCK_CHANGED)
        control.end_if_aborted()  # an abort or a stop asked as the interlock cleared: honoured here
        if control.stop_requested:
            raise StopRun
    finally:
        control.suspension = None
    control.add_time("suspended", t0)
    if control.pause_requested and not control.stop_requested:
        control.fire("clear", f"{CLEARED} ({trip.kind}); the pause asked for meanwhile holds the run")
        await control.safe_point()
        return
    control.fire("clear", f"{CLEARED} ({trip.kind}): settling and acquiring the block again")

"""Who asked a run to end, and the words its end is recorded with (run.log, run.h5's and
run.json's status_message, the closing line of `orbitrig sweep`, the service's closing status).

A stop or an abort carries its sender as the commands log records it: an operator's name
('ada'), the service's own requests ('service (supervision lost)'), the terminal's user with
the signal that asked ('ada (SIGHUP: the terminal was closed)'), or orbitrig itself when nobody
can answer a wait ('orbitrig (nobody can answer: ...)'). The end message names it: 'stopped
by ada', 'aborted by service (SIGTERM; a second signal while shutting down)'; a stop at once keeps its
wording ('stopped at once by SIGTERM'). A stopped or aborted run that left a point incomplete
adds that `orbitrig sweep --resume` measures it again from its start (its blocks so far kept in aside/).

A stop or an abort that leaves every point of the run complete (it arrived as the run ended: all
points measured and stored, both drives ramping down at the end; or a cancellation of the run then,
which is an abort: the service shutting down) ends the run stopped or aborted, as
the MQTT contract says of every stop and abort: the drives get what the request does (a stop at once
ramps them, an abort turns the ramp into the emergency stop). Its end message starts with
'all points completed; ' ('all points completed; aborted by ada (Ctrl-C) while stopping',
`asked_end`), so nobody looks for points that are not missing; run.log's event before it says the same.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from types import MappingProxyType

from orbitrig.run.control import RunControl
from orbitrig.run.provenance import UNNAMED
from orbitrig.run.run_dir import record_end
from orbitrig.run.states import ABORTED, ALL_COMPLETED, COMPLETED, STOPPED, Outcome
from orbitrig.store.layout import point_name
from orbitrig.store.writer import RunStore


def stopped(control: RunControl) -> str:
    """The end message of a stopped run: who asked (a stop at once: why)."""
    if control.stop_now is not None:
        return f"stopped at once by {control.stop_now}"
    return f"stopped by {control.stop_by or UNNAMED}"


def aborted(control: RunControl) -> str:
    """The end message of an aborted run: who asked."""
    return f"aborted by {control.abort_by or UNNAMED}"


def closing_why(status: Outcome, message: str) -> str:
    """What the service's closing status says after 'run <status>': '' for a completed run, else
    ': <message>' (who stopped it and why: ': all points completed; stopped by ada')."""
    return "" if status == COMPLETED else f": {message}"


def every_point_complete(store: RunStore, planned: Mapping[int, int | None]) -> bool:
    """Every point of the run's plan (``planned``) is complete in ``store`` (not known: False)."""
    if not planned:
        return False
    try:
        complete = set(store.completed_points())
    except Exception:  # noqa: BLE001 - not known complete: no 'all points completed'
        return False
    return set(planned) <= complete


def while_stopping(how: str, status: Outcome, message: str) -> str:
    """The message of a run an abort or a cancellation (`how`: 'aborted by ada (Ctrl-C)', 'run
    cancelled') made aborted during its closing stop, as it was ending (`status`, `message`): '<how>
    while stopping (stopped by bob)'. A completed run's own words (ALL_COMPLETED) are not said
    inside: whether every point is complete is said once, ahead, by `asked_end`, from the store
    ('all points completed; aborted by ada while stopping'), and not when the plan is not known."""
    if status == COMPLETED and message == ALL_COMPLETED:
        return f"{how} while stopping"
    return f"{how} while stopping ({message})"


def asked_end(store: RunStore, message: str, planned: Mapping[int, int | None]) -> str:
    """The end message of a stopped or aborted run (`message`: who asked, or what cut it short, and
    how it was ending), its status kept: 'all points completed; <message>' with every planned point
    complete, else `message` and the points it left incomplete (`incomplete_note`)."""
    if every_point_complete(store, planned):
        return f"{ALL_COMPLETED}; {message}"
    return message + incomplete_note(store, planned)


def incomplete_note(store: RunStore, planned: Mapping[int, int | None] = MappingProxyType({})) -> str:
    """'; point 0003 (4 of 20 blocks stored) is incomplete (...)': the points begun and not
    completed ('' if none); ``planned``: each point's blocks (None or absent: not known, a
    sequential point's)."""
    layout = store.layout
    try:
        left = [(i, len(layout.block_tags(i))) for i in layout.point_indexes() if not layout.commit_file(i).is_file()]
    except OSError:
        return ""
    if not left:
        return ""

    def stored(i: int, n: int) -> str:
        of = planned.get(i)
        return f"{n} of {of} blocks stored" if of else f"{n} block{'' if n == 1 else 's'} stored"

    named = ", ".join(f"{point_name(i)} ({stored(i, n)})" for i, n in left)
    one = len(left) == 1
    point, verb, them, their = ("point", "is", "it", "its") if one else ("points", "are", "them", "their")
    return (
        f"; {point} {named} {verb} incomplete: orbitrig sweep --resume measures {them} again from {their} start "
        f"({their} blocks so far kept in aside/)"
    )


def record_the_end(
    store: RunStore,
    run_id: str | None,
    status: Outcome,
    message: str,
    failed: Callable[[str, BaseException], None],
    planned: Mapping[int, int | None] = MappingProxyType({}),
) -> tuple[Outcome, str]:
    """`record_end` (in the storage thread). A stopped or aborted run (a stop, an abort, or a
    cancellation, which is an abort, ended it) keeps its status; its message starts with 'all
    points completed; ' with every point of ``planned`` complete, else it names the points it left
    incomplete (of how many blocks: ``planned``) (`asked_end`)."""
    if status in (STOPPED, ABORTED):
        message = asked_end(store, message, planned)
    return record_end(store, run_id, status, message, failed)

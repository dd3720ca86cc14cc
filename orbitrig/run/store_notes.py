"""The store's own warnings (a journal.jsonl deleted during the run, orbitrig.store.journal_file) as
warnings of the run: the store says them on the thread that wrote (its storage thread, run.log's),
`on_loop` hands each to the engine's event loop (``loop.call_soon_threadsafe``), where the engine
tells its subscribers a `NoteEvent` of kind ``storage warning``: `orbitrig sweep`'s console shows
it, `orbitrig serve` publishes it on ``<prefix>/note`` (the dashboard lists it). run.log and
run.h5's events have it from the store already."""

from __future__ import annotations

import asyncio
import logging
import threading
from collections.abc import Callable

from orbitrig.run.events import Event, NoteEvent, NoteKind, Severity

log = logging.getLogger(__name__)


def on_loop(loop: asyncio.AbstractEventLoop, emit: Callable[[Event], None], run_id: str) -> Callable[[str], None]:
    """What the store of run `run_id` tells its warnings (`RunStore.warned`): each one `emit`ted as
    the run's warning on `loop` (at once when said on the loop's own thread, the caller's)."""
    thread = threading.get_ident()

    def warned(warning: str) -> None:
        event = NoteEvent(run_id, Severity.WARNING, warning, NoteKind.STORAGE)
        if threading.get_ident() == thread:
            emit(event)
            return
        try:
            loop.call_soon_threadsafe(emit, event)
        except RuntimeError:  # the loop has closed: the run is over (run.log has the warning)
            log.info("run %s: a storage warning said after its loop closed: %s", run_id, warning)

    return warned

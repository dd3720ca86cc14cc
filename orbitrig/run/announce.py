"""What the run engine tells (mixin of `RunEngine`): its events to the subscribers (the terminal UI
of `orbitrig sweep`, MQTT in `orbitrig serve`), its state changes and notes to run.log and run.h5's
events, and each revolution to the progress meter and the revolution taps (the live feed). A
subscriber or a tap that fails never disturbs the run."""

from __future__ import annotations

import functools
import logging
import time
from collections.abc import Callable

from daq.revolutions import Revolution

from orbitrig.run.control import RunControl
from orbitrig.run.events import Event, NoteEvent, NoteKind, Severity, StatusEvent, Subscriber
from orbitrig.run.progress import ProgressMeter
from orbitrig.run.states import PAUSED, RUNNING, STOPPING, WAITING, RunState
from orbitrig.store.writer import RunStore

log = logging.getLogger("orbitrig.run.engine")


class RunAnnouncements:
    """The events, log lines and notes of `RunEngine`."""

    run_id: str | None
    revolution_taps: list[Callable[[Revolution], None]]
    _subs: list[Subscriber]
    _control: RunControl
    _progress: ProgressMeter
    _store: RunStore | None
    _log_t0: float
    _write_later: Callable[[Callable[[], None]], None]

    def _emit(self, ev: Event) -> None:
        for cb in list(self._subs):
            try:
                cb(ev)
            except Exception:  # a subscriber must not break the run
                log.exception("event subscriber failed")

    def _state_changed(self, state: RunState, message: str) -> None:
        self._log_event(message, state)
        label, between = self._progress.label, False
        if (ahead := self._control.next_label) is not None:  # between points: paused before the next, resuming
            label, between = (ahead, True) if state in (RUNNING, PAUSED) else (None, False)
        label = label if state in (RUNNING, PAUSED, WAITING, STOPPING) else None
        self._emit(StatusEvent(state, self.run_id, self._control.since, message, label, between))

    def _log_event(self, message: str, state: RunState | None = None) -> None:
        state = state or self._control.state
        log.info("[%s] %s", state, message)
        if self._store is not None:
            self._store.logs.add("events", (time.monotonic() - self._log_t0, state, message))
            self._write_later(functools.partial(self._store.log, f"[{state}] {message}"))

    def _note(self, message: str, severity: Severity = Severity.INFO, kind: NoteKind = NoteKind.OTHER) -> None:
        """A note of the run: in run.log and run.h5's events, and to the subscribers (the sweep's
        console shows the warnings)."""
        self._log_event(message)
        self._emit(NoteEvent(self.run_id, severity, message, kind))

    def _on_revolution(self, rev: Revolution) -> None:
        self._progress.revolution()
        for tap in list(self.revolution_taps):
            try:
                tap(rev)
            except Exception as err:  # the live view must never disturb the run: detached
                log.exception("revolution tap %r failed; detached", tap)
                self.revolution_taps.remove(tap)
                self._note(
                    f"live feed detached: its revolution hook failed ({type(err).__name__}: {err})",
                    Severity.WARNING,
                    NoteKind.LIVE_FEED_DETACHED,
                )

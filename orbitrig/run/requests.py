"""The operator's requests to a running engine (pause, resume, stop, abort, stop at once,
confirm), each logged with who sent it and when (run.log and run.h5's command log)."""

from __future__ import annotations

import asyncio

from orbitrig.config import RigConfig
from orbitrig.run.control import RunControl
from orbitrig.run.provenance import UNNAMED, RunCommand
from orbitrig.run.states import Outcome
from orbitrig.store.writer import RunStore


class OperatorRequests:
    """Mixin of `RunEngine`: what an operator (terminal, MQTT, dashboard) may ask of a run.
    ``by`` names the sender; without it the console user (or UNNAMED)."""

    rig: RigConfig
    console_user: str | None
    _control: RunControl
    _body: asyncio.Task[Outcome] | None
    _store: RunStore | None

    def request_pause(self, by: str | None = None) -> None:
        self._control.request_pause()
        self._command(RunCommand.PAUSE, by)

    def request_resume(self, by: str | None = None) -> None:
        self._control.request_resume()
        self._command(RunCommand.RESUME, by)

    def request_stop(self, by: str | None = None) -> None:
        self._control.request_stop()
        self._command(RunCommand.STOP, by)

    def request_abort(self, by: str | None = None) -> None:
        if self._control.request_abort() and self._body is not None and not self._body.done():
            self._body.cancel()
        self._command(RunCommand.ABORT, by)

    def request_stop_now(self, why: str, by: str | None = None) -> None:
        """Stop at once (`why`, e.g. 'SIGTERM'): the block under way is dropped, both drives ramp
        to zero (OFF1, not an emergency), the run ends stopped and can be resumed."""
        if self._control.request_stop_now(why) and self._body is not None and not self._body.done():
            self._body.cancel()
        self._command(RunCommand.STOP, by, why)

    @property
    def unattended(self) -> bool:
        """Nobody can answer a pause or a confirmation (no terminal, no MQTT): such a wait
        stops the run after [interlocks] unanswered_pause_s."""
        return self._control.unanswered_limit is not None

    @unattended.setter
    def unattended(self, value: bool) -> None:
        self._control.unanswered_limit = self.rig.interlocks.unanswered_pause_s if value else None

    def confirm(self, step: str, by: str | None = None) -> None:
        """Confirm the manual setting `step` (e.g. 'manual:0003'); raises if not waiting for it.
        `by`: who sent each request (logged with the time in run.log and run.h5)."""
        self._control.confirm(step)
        self._command(RunCommand.CONFIRM, by, step)

    def _command(self, command: RunCommand, by: str | None, detail: str = "") -> None:
        if self._store is not None:
            self._store.command(command, by or self.console_user or UNNAMED, detail)


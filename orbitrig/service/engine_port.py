"""The run executor as the rig service sees it (orbitrig.run.engine.RunEngine satisfies it),
and the factories the service is built with."""

from __future__ import annotations

from collections.abc import Callable, Coroutine
from pathlib import Path
from typing import Any, Protocol

from orbitrig.config import RigConfig
from orbitrig.run.engine import RunOutcome
from orbitrig.run.rig_io import RigAccess
from orbitrig.run.states import RunState


class Engine(Protocol):
    out_dir: Path  # the run directory
    rig: RigConfig
    access: RigAccess  # its time_scale turns the rig's physical seconds into wall seconds
    state: RunState
    run_id: str | None
    waiting_step: str | None
    pause_pending: bool  # a pause requested, not yet reached at a safe point
    let_go: bool  # its cleanup past its closing stop: no stop asked of it reaches the drives any more
    waiting_for_disk: bool  # past its closing stop, still waiting for its storage (orbitrig.run.closing)
    standstill_confirmed: bool  # its drives' closing stop ended with both at standstill (orbitrig.run.closing)
    stop_words: Any  # the asyncio.Task of its abort's stop words still going out, or None

    async def run(self, matrix: Any, *, resume: bool = False) -> RunOutcome: ...
    def unwritten(self) -> list[str]: ...  # what the run has not written yet (orbitrig.run.closing)
    def subscribe(self, callback: Callable[[Any], None]) -> None: ...

    operator: str
    #: nobody can answer: a pause or a confirmation stops the run after [interlocks]
    #: unanswered_pause_s (one under way: that long after this was set)
    unattended: bool

    def request_pause(self, by: str | None = None) -> str: ...  # when it takes effect, in words
    def request_resume(self, by: str | None = None) -> None: ...
    def request_stop(self, by: str | None = None) -> bool: ...  # False: the run has let go of the drives
    def request_stop_now(self, why: str, by: str | None = None) -> None: ...
    def request_abort(self, by: str | None = None) -> bool: ...  # False: nothing reached the drives
    def confirm(self, step: str, by: str | None = None) -> None: ...


#: Makes the executor of one run: ``factory(matrix_name, matrix) -> Engine``.
EngineFactory = Callable[[str, Any], Engine]
#: Loads and checks a matrix file: ``loader(path) -> Plan`` (orbitrig.run.plan; raises ConfigError).
MatrixLoader = Callable[[Path], Any]
#: Asks the rig's transports before a start: ``await check()`` raises an OrbitrigError in the words
#: of orbitrig.run.rig_answers (RigUnreachable) when one does not answer; nothing is moved.
RigCheck = Callable[[], Coroutine[Any, Any, None]]

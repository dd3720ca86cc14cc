"""The stops of both drives that no run carries out (a mixin of the rig service): a ``stop`` or
``abort`` while no run holds the drives, and the first shutdown signal with no run active. An
abort's is the emergency stop (a stop's the ramp stop, but the emergency stop again within [drives]
stop_timeout_s of any emergency stop sent to them, a run's or the service's:
drives.emergency_sent.emergency_within, or if a drive reads in its emergency ramp first, whoever
sent it: drives.read_first.read_first), sent over a link of the service's own to the drives of the
rig configuration loaded last (orbitrig.service.idle_stop)."""

from __future__ import annotations

import asyncio
import functools

from drives.emergency_sent import emergency_within
from orbitrig.service import idle_stop
from orbitrig.service.engine_port import Engine


class DriveStopping:
    """The stops no run carries out, of :class:`orbitrig.service.rig_service.RigService` (a
    mixin: the attributes below are the service's)."""

    _engine: Engine | None
    _run_task: asyncio.Task | None
    #: a start whose rig check is under way (orbitrig.service.run_handling; its thread may hold the
    #: drives' port, a serial one exclusively, for up to 2 s), None: none
    _start_checked: asyncio.Task | None = None
    #: the start-up's look at the rig's transports (`port_asked_by`), which may hold the port likewise
    _port_asked: asyncio.Task | None = None
    #: the stop of an abort (or stop) that no run carried out, while it is being sent
    _idle_stop: asyncio.Task[idle_stop.Outcome] | None = None
    #: whether that stop is the emergency stop (OFF3), not a stop's ramp stop (OFF1)
    _idle_emergency: bool = False
    #: set by an abort while that stop is a ramp stop: it becomes the emergency stop (no OFF1 after OFF3)
    _idle_escalate: asyncio.Event | None = None
    #: a ramp stop made so, which may go on after the abort's own stop beside it has ended
    _idle_escalated: asyncio.Task[idle_stop.Outcome] | None = None
    #: the emergency stop the first shutdown signal sent with no run to stop the drives, or why not sent
    _signal_stop: asyncio.Task[idle_stop.Outcome] | str | None = None
    #: why that emergency stop did not reach both drives (None: it did, or none was sent)
    signal_stop_failed: str | None = None
    #: the signal and why no run carried it to the drives ('SIGTERM with no run active')
    signal_stop_why: str = ""
    _tg: asyncio.TaskGroup | None
    #: the (Modbus URL, [drives]) of the rig configuration loaded last, asked at each stop no run
    #: carries out (None: not known, not sent)
    drive_link: idle_stop.DriveLinkSource | None = None

    def port_asked_by(self, task: asyncio.Task) -> None:
        """`task` asks the rig's transports (orbitrig serve's start-up look, in a thread of its own): a
        stop or abort no run carries out meanwhile waits for it to let go of the drives' port."""
        self._port_asked = task

    @property
    def run_active(self) -> bool:
        return self._run_task is not None and not self._run_task.done()

    def stop_idle_drives(
        self, *, emergency: bool, why: str | None = None, held: str | None = None
    ) -> asyncio.Task[idle_stop.Outcome] | str:
        """Both drives' stop (``emergency``: OFF3, else OFF1) over a link of the service's own to the
        drive link asked now, for a stop or abort no run carries out (``why``: the service's own request,
        its outcome logged; ``held``: said instead of 'no run held them'); the task sending it, or why it is not sent. One under way is its answer,
        unless it is a ramp stop and this an emergency stop: that goes out beside it, and makes the
        ramp stop under way the emergency stop too (no OFF1 of it after the OFF3). A ramp stop
        within [drives] stop_timeout_s of any emergency stop sent to those drives (a run's, the
        service's; no speed commanded since: drives.emergency_sent.emergency_within) is the emergency stop
        again: an OFF1 would turn their emergency ramp back into their (ten times slower) ramp stop."""
        link = self._drive_link_now()
        emergency = emergency or (link is not None and emergency_within(link[0], link[1].stop_timeout_s))
        pending = self._idle_stop
        busy = pending is not None and not pending.done()
        if pending is not None and busy and (self._idle_emergency or not emergency):
            return pending
        if busy and self._idle_escalate is not None:  # the ramp stop under way: none of its OFF1 after this OFF3
            self._idle_escalate.set()
            self._idle_escalated = pending
        # (holder: a run the abort cancelled before it held the drives, the ramp stop under way, or a
        # start's rig check, which may hold their port: the stop goes out the moment it lets go)
        holder = pending if busy else (self._run_task if self.run_active else self._start_checked or self._port_asked)
        escalate = None if emergency else asyncio.Event()
        decided = None if escalate is None else functools.partial(self._read_emergency, escalate)
        sent = idle_stop.start(
            self._tg, link, holder, why, emergency=emergency, escalate=escalate, decided=decided, held=held
        )
        if not isinstance(sent, str):
            self._idle_stop, self._idle_emergency, self._idle_escalate = sent, emergency, escalate
        return sent

    def _read_emergency(self, escalate: asyncio.Event) -> None:
        """The ramp stop of `escalate` read a drive in its emergency ramp: the emergency stop goes out,
        recorded as one while it is the stop under way (an abort now is answered by it)."""
        if self._idle_escalate is escalate:
            self._idle_emergency, self._idle_escalate = True, None

    def idle_stops(self) -> set[asyncio.Task[idle_stop.Outcome]]:
        """The stops no run carried out still going out: the last one, and a ramp stop an abort made
        the emergency stop (its silent drive's tries may outlast the abort's own stop)."""
        return {t for t in (self._idle_stop, self._idle_escalated) if t is not None and not t.done()}

    def _drive_link_now(self) -> idle_stop.DriveLink | None:
        """The drive link of the rig configuration loaded last (None: none known)."""
        return self.drive_link() if self.drive_link is not None else None

    def stop_drives_on_signal(self, name: str) -> None:
        """The first shutdown signal (``name``) with no run active, or with the run past its closing
        stop (also one that could not confirm the drives stopped, while it records its end): an
        abort no run carries out (both drives' emergency stop, its outcome logged);
        `settle_signal_stop` waits for it. An active run stops them itself (`_end_run`)."""
        engine = self._engine if self.run_active else None
        if engine is not None and not engine.let_go:
            return
        self.signal_stop_why = f"{name} with no run active" if engine is None else f"{name} with the run past its stop"
        self._signal_stop = self.stop_idle_drives(emergency=True, why=self.signal_stop_why)

    async def settle_signal_stop(self) -> None:
        """Wait (at most idle_stop.SIGNAL_STOP_S, wall s) for the emergency stop of
        `stop_drives_on_signal`; `signal_stop_failed` then says why it did not reach both drives."""
        sent = self._signal_stop
        if isinstance(sent, str):
            self.signal_stop_failed = sent
        elif sent is not None:
            self.signal_stop_failed, _ = await idle_stop.outcome_within(sent, idle_stop.SIGNAL_STOP_S)

"""The rig service under MQTT control (docs/protocols/mqtt.md), with aiomqtt.

One :class:`RigService` owns the broker connection and at most one run. The
run is executed by the same executor as ``orbitrig sweep``
(:class:`orbitrig.run.engine.RunEngine`, made by an ``engine_factory``; started, followed
and summarised by orbitrig.service.run_handling); its events become MQTT messages:

- ``<prefix>/status``: retained, QoS 1; republished on every (re)connection; a run's names
  the run's latest progress (so a subscriber that comes while the run waits learns where it is);
  the last will (registered at every connection) is ``offline``, retained, QoS 1;
- ``<prefix>/progress``: QoS 0, dropped while disconnected;
- ``<prefix>/result``: QoS 1, kept and delivered after a reconnection;
- ``<prefix>/reply``: QoS 1, one per command, delivered at least once (one handed over as
  the link dropped is sent again: match replies by id).

The session is persistent (MQTT 5, clean start off, a session expiry of
``session_expiry`` s): QoS 1 commands published while the service reconnects
are kept by the broker and delivered once it is back; commands read before a
lost link are carried out after it; the broker's redelivery (DUP, the same
packet id) is dropped, except a stop or an abort: carried out each time.
``offline`` is published on every way out of :meth:`RigService.serve`
(shutdown, a fault in the service) and is the last will for the others.

The broker may go away: the run goes on, the service reconnects with jittered
exponential backoff (reset only after a connection carried traffic for a while)
and republishes the status. A loss of supervision longer
than ``supervision_timeout`` applies ``supervision_policy`` to a running run
once: ``keep`` (go on), ``pause`` or ``stop``, and makes a wait nobody can answer
stop the run after ``unanswered_pause_s`` (orbitrig.service.supervision). ``stop`` and ``abort`` are
always accepted and go straight to the executor as they are read off the
connection, whatever it is doing and however many commands wait (also on
``<prefix>/abort``; orbitrig.service.inbox), and ``<prefix>/abort`` has a broker
connection of its own besides (orbitrig.service.abort_link), so that no flood on
the main connection is ahead of an abort. A matrix is chosen by name only,
from the configured matrix folder.

Background work runs in named tasks owned by one TaskGroup.
"""

from __future__ import annotations

import asyncio
import collections
import functools
import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from drives.waits import first_set
from orbitrig.analysis.report_ahead import FiguresAhead
from orbitrig.run.states import RunCommand
from orbitrig.run.states import RunState
from orbitrig.store.errors import StorageError
from orbitrig.service import idle_stop, live as live_feed
from orbitrig.service.engine_port import Engine, EngineFactory, MatrixLoader, RigCheck  # the service's seams
from orbitrig.service.inbox import CommandTriage
from orbitrig.service.last_run import READ_S as LAST_RUN_READ_S, read_last_run_within
from orbitrig.service.leaving import LeavingWithoutDisk
from orbitrig.service.note_budget import NoteBudget
from orbitrig.service.abort_link import AbortLink
from orbitrig.service.catalog_feed import CatalogFeed
from orbitrig.service.commands import Later, Request
from orbitrig.service.run_handling import RunHandling
from orbitrig.service.supervision import SupervisionHandling
from orbitrig.service.flood_read import STOP_HOLD_MAX_S, STOP_HOLD_S
from orbitrig.service import protocol as proto
from orbitrig.service.link import BrokerLink
from orbitrig.service.settings import (  # noqa: F401 - the service's public names
    SUPERVISION_POLICIES,
    BrokerSettings,
    CommandRefused,
    ServiceError,
    ServiceSettings,
    SupervisionPolicy,
    default_client_id,
    run_end_timeout,
)

log = logging.getLogger("orbitrig.service.rig_service")


class RigService(RunHandling, SupervisionHandling, LeavingWithoutDisk):
    """MQTT front end of one rig. ``await service.serve(shutdown)`` runs until
    ``shutdown`` is set (then nothing that moves the drives is accepted, an active
    run is stopped at once, ``offline`` is published and the connection closed) or
    a fatal error."""

    def __init__(
        self,
        settings: ServiceSettings,
        broker: BrokerSettings,
        *,
        engine_factory: EngineFactory,
        load_matrix: MatrixLoader,
        drive_link: idle_stop.DriveLinkSource | None = None,
        rig_check: RigCheck | None = None,
    ):
        """`drive_link`: (Modbus URL, [drives]) of the drives as configured now, for a stop or abort no run
        carries out (orbitrig.service.idle_stop; None: "not sent"). `rig_check`: the rig's transports,
        asked before each start's run folder is made (a failure refuses the start; None: not asked)."""
        self.drive_link, self._rig_check = drive_link, rig_check
        self.settings, self.broker = settings, broker
        self.topics = proto.topics(settings.rig_id, settings.prefix)
        self._engine_factory = engine_factory
        self._load_matrix = load_matrix
        self._engine: Engine | None = None
        self._run_task: asyncio.Task | None = None
        self._cut_short = False  # the run was cancelled before its drives' closing stop had ended
        self._fit_warnings: list = []  # FitWarnings of the run's completed points (grouped in each result)
        self._notes = NoteBudget()  # the run's warnings published on <prefix>/note (a new one per run)
        self._live: live_feed.LiveFeed | None = None
        self._ahead: FiguresAhead | None = None  # the run's figures drawn as its points complete
        self._status = proto.status_payload(RunState.IDLE, None, None, "service ready")
        self._state: proto.StatusState = RunState.IDLE
        self._run_id: str | None = None
        self.triage = CommandTriage(
            self._on_message, functools.partial(self._reply, behind=True), lambda: self.link.reply_backlog
        )
        self._catalog = CatalogFeed(settings.catalog_url) if settings.catalog_url else None
        self.link = BrokerLink(
            broker,
            settings,
            self.topics,
            status=lambda: self._status,
            offline=self._offline_status,
            on_command=self._on_message,
            triage=self.triage,
        )
        #: the second connection, for <prefix>/abort alone (None: not configured)
        self.abort_link = AbortLink(broker, broker.abort, settings, self.topics, self.triage) if broker.abort else None
        self.triage.after_at_once = self._let_the_stop_go_first
        self._tg: asyncio.TaskGroup | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread = threading.get_ident()
        #: (id, bytes) of recent commands -> number of the connection they came on
        self._handled: collections.OrderedDict[tuple[str, bytes], int] = collections.OrderedDict()
        self._stops_done: collections.OrderedDict[tuple[str | None, bytes], None] = collections.OrderedDict()
        #: command name -> handler: raises CommandRefused to refuse; returns a Later (its reply follows) or the reply's detail
        self._handlers: dict[proto.CommandName, Callable[[proto.Command], Later | str | None]] = {
            RunCommand.START: self._cmd_start,
            RunCommand.PAUSE: self._cmd_pause,
            RunCommand.RESUME: self._cmd_resume,
            RunCommand.STOP: self._cmd_stop,
            RunCommand.ABORT: self._cmd_abort,
            RunCommand.CONFIRM: self._cmd_confirm,
            proto.Query.STATUS: self._cmd_status,
        }

    # -- public state -----------------------------------------------------------

    @property
    def state(self) -> proto.StatusState:
        return self._state

    @property
    def connections(self) -> int:
        """Successful connections to the broker so far."""
        return self.link.connections

    # -- main -------------------------------------------------------------------

    async def serve(self, shutdown: asyncio.Event | None = None) -> None:
        shutdown = shutdown or asyncio.Event()
        self._loop = asyncio.get_running_loop()
        self._thread = threading.get_ident()
        last = await self._last_run()
        self._status = proto.status_payload(RunState.IDLE, None, None, "service ready", {"last_run": last})
        async with asyncio.TaskGroup() as tg:
            self._tg = tg
            conn = self._connection = tg.create_task(self.link.run(), name="mqtt-connection")
            sup = tg.create_task(self._supervision_loop(), name="supervision-watchdog")
            stop = tg.create_task(shutdown.wait(), name="shutdown-signal")
            tasks = [conn, sup, stop]
            if self.abort_link is not None:
                tasks.append(tg.create_task(self.abort_link.run(), name="mqtt-abort-connection"))
            else:
                log.warning(
                    "no abort connection: stop and abort come through the main connection only, "
                    "where a flood of commands may hold them back (orbitrig serve --abort-username)"
                )
            await asyncio.wait({conn, stop}, return_when=asyncio.FIRST_COMPLETED)
            await self._shut_down()
            for task in tasks:
                task.cancel()
        # (a fault inside the group cancels the connection task, whose session
        # publishes offline on its way out: BrokerLink._leave)
        await self.link.discard_session()
        await self._catalog_finished()

    async def _shut_down(self) -> None:
        """The run stopped (drives first), then ``offline`` delivered. From the start
        nothing that moves the drives is accepted (``closing``); ordinary commands are
        no longer read before ``offline`` is sent, and a run left over is ended before
        the service leaves."""
        log.info("shutting down")
        self.closing = True
        await self._end_run("service shutting down")
        await self.settle_signal_stop()  # the signal's emergency stop when no run was active
        await self._start_check_over()  # its thread ended, its refusal said before offline
        self.link.stop_commands()  # stop and abort are still carried out as they arrive
        await self._end_run("a run left over at shutdown")  # none: start is refused once closing
        self._set_status(proto.OFFLINE, self._run_id, "service stopped")
        self.link.leaving = True
        if self.link.online.is_set() and await first_set(self.link.drained, timeout=5.0) is None:
            log.warning("could not deliver every message before shutdown")
        if self.run_active:  # cannot happen (closing, commands unread): never leave drives turning
            log.error("a run is active after the shutdown's stop: stopping it")
            await self._end_run("a run left over at shutdown")
            self._set_status(proto.OFFLINE, self._run_id, "service stopped")

    def _let_the_stop_go_first(self, name: str) -> None:
        """After a stop or abort ``name``: while the abort connection is up to take the next one,
        and after an abort in any case (nothing the main connection brings outranks it), the
        main connection (a flood, maybe) is left unread until the run's stop words are out (at
        most STOP_HOLD_MAX_S; STOP_HOLD_S when the run sends none now), so that the drives' stop
        words get the processor first, however busy the host."""
        if name == RunCommand.ABORT or (self.abort_link is not None and self.abort_link.up):
            words = self._engine.stop_words if self._engine is not None else None
            held = self.link.hold_reading(STOP_HOLD_S if words is None else STOP_HOLD_MAX_S, words)
            if held and words is not None:
                t0 = time.monotonic()
                words.add_done_callback(lambda _: _say_words_out(name, time.monotonic() - t0))

    async def _last_run(self) -> dict[str, Any] | None:
        """The ``last_run`` of the first status: the last run in the runs folder as the store recorded
        it; None when there is none, or it cannot be read or is not read within last_run.READ_S
        (logged: the service starts all the same)."""
        where = self.settings.runs_dir
        if where is None:
            return None
        try:
            last = await read_last_run_within(where)
        except TimeoutError:
            log.warning("the runs folder %s did not answer within %.0f s: last_run null", where, LAST_RUN_READ_S)
            return None
        except (OSError, StorageError) as err:
            log.warning("the last run in %s could not be read (last_run null): %s", where, err)
            return None
        return None if last is None else last.payload()

    def _offline_status(self, message: str) -> bytes:
        return proto.status_payload(proto.OFFLINE, self._run_id, None, message)

    async def _end_run(self, why: str) -> None:
        """Abort an active run and wait (bounded) until the executor has finished."""
        task = self._run_task
        if not self.run_active or task is None:
            return
        log.warning("stopping run %s at once, both drives ramp to zero: %s", self._run_id, why)
        self._request(Request.STOP_NOW, f"service ({why})")
        timeout = self._run_end_timeout()
        try:
            async with asyncio.timeout(timeout):  # (3.11's wait_for can lose a cancellation)
                await asyncio.shield(task)
        except TimeoutError:
            held = self._engine is None or not self._engine.let_go  # its closing stop not over: it goes on
            done = "its drives' closing stop goes on" if held else "its drives' closing stop was done (run.log)"
            log.error("run did not end within %.0f s; cancelling it: %s", timeout, done)
            self._cut_short = held
            task.cancel()
            await asyncio.gather(task, return_exceptions=True)
        except asyncio.CancelledError:
            current = asyncio.current_task()
            if not task.cancelled() or (current is not None and current.cancelling()):
                raise  # this task is being cancelled, not only the run it waited for
        except Exception:  # noqa: BLE001 - reported by _run itself
            pass

    def _run_end_timeout(self) -> float:
        """s the active run may take to end once stopped (ServiceSettings.shutdown_timeout)."""
        if self.settings.shutdown_timeout is not None or self._engine is None:
            return self.settings.shutdown_timeout or run_end_timeout(0.0)
        engine = self._engine
        return run_end_timeout(engine.access.time_scale.wall(engine.rig.drives.stop_timeout_s))

    def abort_run(self, why: str) -> None:
        """Abort the active run (emergency ramp; during its closing ramp stop: an emergency stop),
        recorded as sent by ``service (why)``. An abort no run takes (none is active, or the run no
        longer holds the drives: closed by its cleanup, also unconfirmed) sends both the emergency
        stop over the service's own link, as an MQTT abort (idle_stop); its outcome is logged."""
        if self.run_active:
            log.warning("aborting run %s: %s", self._run_id, why)
            if self._request(Request.ABORT, f"service ({why})"):
                return
        self.stop_idle_drives(emergency=True, why=why)  # (one under way: its outcome is logged)

    def _send(self, topic: str, payload: bytes, qos: int, retain: bool = False) -> None:
        self.link.send(topic, payload, qos, retain)


def _say_words_out(name: str, elapsed: float) -> None:
    """Log when an abort's stop words were out, ``elapsed`` s after it, and whether the main
    connection was left unread all that time or read again at STOP_HOLD_MAX_S before they were."""
    if elapsed < STOP_HOLD_MAX_S:
        held = f"the main connection left unread meanwhile ({STOP_HOLD_MAX_S:g} s at most)"
    else:
        held = f"the main connection read again after {STOP_HOLD_MAX_S:g} s, before they were"
    log.info("%s: the drives' stop words out after %.0f ms, %s", name, elapsed * 1e3, held)

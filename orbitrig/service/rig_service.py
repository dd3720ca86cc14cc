"""The rig service under MQTT control (docs/protocols/mqtt.md), with aiomqtt.

One :class:`RigService` owns the broker connection and at most one run. The
run is executed by the same executor as ``orbitrig sweep``
(:class:`orbitrig.run.engine.RunEngine`, made by an ``engine_factory``); its
events become MQTT messages:

- ``<prefix>/status``: retained, QoS 1; republished on every (re)connection;
  the last will (registered at every connection) is ``offline``, retained, QoS 1;
- ``<prefix>/progress``: QoS 0, dropped while disconnected;
- ``<prefix>/result``: QoS 1, kept and delivered after a reconnection;
- ``<prefix>/reply``: QoS 1, exactly one per command.

The broker may go away: the run goes on, the service reconnects with jittered
exponential backoff and republishes the status. A loss of supervision longer
than ``supervision_timeout`` applies ``supervision_policy`` to a running run
once: ``keep`` (go on), ``pause`` or ``stop``. ``stop`` and ``abort`` are
always accepted and go straight to the executor, whatever it is doing (also
while it waits for an operator confirmation). A matrix is chosen by name only,
from the configured matrix folder.

Background work runs in named tasks owned by one TaskGroup.
"""

from __future__ import annotations

import asyncio
import collections
import dataclasses
import logging
import random
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal, Protocol
from urllib.parse import urlsplit

from orbitrig.service import live as live_feed
from orbitrig.service import protocol as proto
from orbitrig.errors import ConfigError, OrbitrigError

log = logging.getLogger("orbitrig.service.rig_service")

SupervisionPolicy = Literal["keep", "pause", "stop"]
SUPERVISION_POLICIES: tuple[str, ...] = ("keep", "pause", "stop")
#: CONNACK reason codes meaning "your credentials are refused" (MQTT 3.1.1 and 5).
_AUTH_REFUSED = {4, 5, 134, 135}


class ServiceError(OrbitrigError):
    """The service cannot run (bad broker URL, credentials refused, ...)."""


# -- settings -----------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class BrokerSettings:
    """Where and how to connect. ``keepalive`` (s): the broker publishes the last
    will after 1.5 x keepalive without traffic (at once when the socket closes)."""

    host: str
    port: int = 1883
    username: str | None = None
    password: str | None = dataclasses.field(default=None, repr=False)
    tls: bool = False
    tls_ca: Path | None = None
    keepalive: int = 10
    timeout: float = 10.0

    @classmethod
    def from_url(cls, url: str, **kw: Any) -> BrokerSettings:
        """``mqtt://host:port`` (default port 1883) or ``mqtts://host:port`` (TLS, 8883).
        TLS is also used with ``mqtt://`` when ``tls_ca`` is given."""
        parts = urlsplit(url)
        if parts.scheme not in ("mqtt", "mqtts") or not parts.hostname:
            raise ServiceError(f"broker URL {url!r}: expected mqtt://host:port or mqtts://host:port")
        if parts.username or parts.password:
            raise ServiceError(f"broker URL {url!r}: credentials do not belong in the URL "
                               "(use --username and --password-file or ORBITRIG_MQTT_PASSWORD)")
        if parts.path not in ("", "/") or parts.query:
            raise ServiceError(f"broker URL {url!r}: no path or query expected")
        try:
            port = parts.port
        except ValueError as err:
            raise ServiceError(f"broker URL {url!r}: {err}") from None
        tls = parts.scheme == "mqtts" or kw.get("tls_ca") is not None
        return cls(host=parts.hostname, port=port or (8883 if parts.scheme == "mqtts" else 1883),
                   tls=tls, **kw)


@dataclasses.dataclass(frozen=True)
class ServiceSettings:
    """Behaviour of the service (times in s)."""

    rig_id: str
    matrices_dir: Path
    prefix: str | None = None
    supervision_policy: SupervisionPolicy = "keep"
    supervision_timeout: float = 60.0
    reconnect_initial: float = 0.2
    reconnect_max: float = 30.0
    shutdown_timeout: float = 60.0

    def __post_init__(self) -> None:
        if self.supervision_policy not in SUPERVISION_POLICIES:
            raise ServiceError(f"supervision policy {self.supervision_policy!r}: "
                               f"one of {', '.join(SUPERVISION_POLICIES)}")
        if self.supervision_timeout <= 0:
            raise ServiceError("supervision timeout must be > 0 s")


class Backoff:
    """Jittered exponential backoff: attempt n waits a uniform random time in
    ``[d/2, d]`` with ``d = min(maximum, initial * 2**n)`` (s)."""

    def __init__(self, initial: float, maximum: float, *, rng: Callable[[], float] = random.random):
        self.initial, self.maximum, self._rng = initial, maximum, rng
        self.attempt = 0

    def next(self) -> float:
        d = min(self.maximum, self.initial * 2.0 ** self.attempt)
        self.attempt += 1
        return d * (0.5 + 0.5 * self._rng())

    def reset(self) -> None:
        self.attempt = 0


# -- the executor as seen from here (orbitrig.run.engine.RunEngine) --------------

class Engine(Protocol):
    state: str
    run_id: str | None
    waiting_step: str | None

    async def run(self, matrix: Any, *, resume: bool = False) -> Any: ...
    def subscribe(self, callback: Callable[[Any], None]) -> None: ...
    def request_pause(self) -> None: ...
    def request_resume(self) -> None: ...
    def request_stop(self) -> None: ...
    def request_abort(self) -> None: ...
    def confirm(self, step: str) -> None: ...


#: Makes the executor of one run: ``factory(matrix_name, matrix) -> Engine``.
EngineFactory = Callable[[str, Any], Engine]
#: Loads and checks a matrix file: ``loader(path) -> Plan`` (orbitrig.run.plan; raises ConfigError).
MatrixLoader = Callable[[Path], Any]


@dataclasses.dataclass
class _Out:
    topic: str
    payload: bytes
    qos: int
    retain: bool = False


class RigService:
    """MQTT front end of one rig. ``await service.serve(shutdown)`` runs until
    ``shutdown`` is set (then an active run is aborted, ``offline`` is
    published and the connection closed) or a fatal error."""

    def __init__(self, settings: ServiceSettings, broker: BrokerSettings, *,
                 engine_factory: EngineFactory, load_matrix: MatrixLoader):
        self.settings = settings
        self.broker = broker
        self.topics = proto.topics(settings.rig_id, settings.prefix)
        self._engine_factory = engine_factory
        self._load_matrix = load_matrix
        self._engine: Engine | None = None
        self._run_task: asyncio.Task | None = None
        self._live: live_feed.LiveFeed | None = None
        self._status = proto.status_payload("idle", None, None, "service ready")
        self._state = "idle"
        self._run_id: str | None = None
        self._out: collections.deque[_Out] = collections.deque(maxlen=10_000)
        self._wake = asyncio.Event()
        self._drained = asyncio.Event()
        self._online = asyncio.Event()
        self._offline = asyncio.Event()
        self._offline.set()
        self._tg: asyncio.TaskGroup | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread = threading.get_ident()
        self.connections = 0  # successful connections so far

    # -- public state -----------------------------------------------------------

    @property
    def run_active(self) -> bool:
        return self._run_task is not None and not self._run_task.done()

    @property
    def state(self) -> str:
        return self._state

    # -- main -------------------------------------------------------------------

    async def serve(self, shutdown: asyncio.Event | None = None) -> None:
        shutdown = shutdown or asyncio.Event()
        self._loop = asyncio.get_running_loop()
        self._thread = threading.get_ident()
        async with asyncio.TaskGroup() as tg:
            self._tg = tg
            conn = tg.create_task(self._connection_loop(), name="mqtt-connection")
            sup = tg.create_task(self._supervision_loop(), name="supervision-watchdog")
            stop = tg.create_task(shutdown.wait(), name="shutdown-signal")
            await asyncio.wait({conn, stop}, return_when=asyncio.FIRST_COMPLETED)
            log.info("shutting down")
            await self._end_run("service shutting down")
            self._set_status("offline", self._run_id, "service stopped")
            if self._online.is_set():
                try:
                    await asyncio.wait_for(self._drained.wait(), 5.0)
                except TimeoutError:
                    log.warning("could not deliver every message before shutdown")
            for task in (conn, sup, stop):
                task.cancel()

    async def _end_run(self, why: str) -> None:
        """Abort an active run and wait (bounded) until the executor has finished."""
        if not self.run_active:
            return
        log.warning("aborting run %s: %s", self._run_id, why)
        self._request("abort")
        try:
            await asyncio.wait_for(asyncio.shield(self._run_task), self.settings.shutdown_timeout)
        except TimeoutError:
            log.error("run did not end within %.0f s; cancelling it", self.settings.shutdown_timeout)
            self._run_task.cancel()
            await asyncio.gather(self._run_task, return_exceptions=True)
        except Exception:  # noqa: BLE001 - reported by _run itself
            pass

    # -- connection -------------------------------------------------------------

    def _client(self) -> Any:
        import aiomqtt

        b = self.broker
        will = aiomqtt.Will(self.topics.status,
                            proto.status_payload("offline", self._run_id, None,
                                                 "connection to the rig service lost"),
                            qos=proto.QOS_STATUS, retain=True)
        tls = aiomqtt.TLSParameters(ca_certs=str(b.tls_ca) if b.tls_ca else None) if b.tls else None
        return aiomqtt.Client(b.host, b.port, username=b.username, password=b.password,
                              identifier=f"orbitrig-serve-{self.settings.rig_id}", will=will,
                              clean_session=True, keepalive=b.keepalive, timeout=b.timeout,
                              tls_params=tls)

    async def _connection_loop(self) -> None:
        import aiomqtt

        backoff = Backoff(self.settings.reconnect_initial, self.settings.reconnect_max)
        where = f"{self.broker.host}:{self.broker.port}"
        while True:
            t_connected = None
            try:
                async with self._client() as client:
                    t_connected = time.monotonic()
                    await client.subscribe(self.topics.cmd, qos=proto.QOS_CMD)
                    self.connections += 1
                    log.info("connected to %s as %r; commands on %s", where, self.broker.username,
                             self.topics.cmd)
                    self._offline.clear()
                    self._online.set()
                    async with asyncio.TaskGroup() as session:
                        session.create_task(self._publish_loop(client), name="mqtt-publish")
                        session.create_task(self._command_loop(client), name="mqtt-commands")
            except* aiomqtt.MqttError as group:
                err = group.exceptions[0]
                rc = getattr(getattr(err, "rc", None), "value", getattr(err, "rc", None))
                if self.connections == 0 and isinstance(err, aiomqtt.MqttCodeError) and rc in _AUTH_REFUSED:
                    raise ServiceError(f"broker {where} refused the credentials of "
                                       f"{self.broker.username!r}: {err}") from None
                if t_connected is None:
                    log.warning("cannot connect to %s: %s", where, err)
                else:
                    log.warning("connection to %s lost: %s", where, err)
            finally:
                self._online.clear()
                self._offline.set()
            if t_connected is not None and time.monotonic() - t_connected > 5.0:
                backoff.reset()
            delay = backoff.next()
            log.info("reconnecting in %.2f s", delay)
            await asyncio.sleep(delay)

    async def _publish_loop(self, client: Any) -> None:
        """Deliver the outgoing queue in order; the current status first."""
        pending = [m for m in self._out if m.topic != self.topics.status]
        self._out.clear()
        self._out.append(_Out(self.topics.status, self._status, proto.QOS_STATUS, True))
        self._out.extend(pending)
        while True:
            while self._out:
                msg = self._out[0]
                await client.publish(msg.topic, msg.payload, qos=msg.qos, retain=msg.retain)
                if self._out and self._out[0] is msg:
                    self._out.popleft()
            self._drained.set()
            self._wake.clear()
            await self._wake.wait()

    def _send(self, topic: str, payload: bytes, qos: int, retain: bool = False) -> None:
        if not self._online.is_set() and (qos == 0 or topic == self.topics.status):
            return  # progress is of no use later; the status is republished on connection
        self._out.append(_Out(topic, payload, qos, retain))
        self._drained.clear()
        self._wake.set()

    async def _command_loop(self, client: Any) -> None:
        async for message in client.messages:
            if str(message.topic) != self.topics.cmd:
                continue
            payload = message.payload if isinstance(message.payload, (bytes, bytearray)) else \
                str(message.payload or "").encode()
            self.handle_command(bytes(payload), retained=bool(getattr(message, "retain", False)))

    # -- supervision --------------------------------------------------------------

    async def _supervision_loop(self) -> None:
        """Apply the policy once per outage longer than ``supervision_timeout``."""
        s = self.settings
        while True:
            await self._offline.wait()
            try:
                await asyncio.wait_for(self._online.wait(), s.supervision_timeout)
                continue
            except TimeoutError:
                pass
            if self.run_active:
                log.warning("no broker for %.0f s: supervision lost, policy %r", s.supervision_timeout,
                            s.supervision_policy)
                if s.supervision_policy == "pause" and self._state in ("running", "waiting"):
                    self._request("pause")
                elif s.supervision_policy == "stop":
                    self._request("stop")
            await self._online.wait()

    # -- commands ---------------------------------------------------------------

    def handle_command(self, payload: bytes, *, retained: bool = False) -> None:
        """Validate and execute one command; publish exactly one reply.

        A retained command (spec: ``<prefix>/cmd`` is not retained) is stale: the broker
        hands it to every new subscription, so executing it would, e.g., start a run at
        each reconnection. It is refused (one reply) and changes nothing."""
        try:
            cmd = proto.parse_command(payload)
        except proto.CommandError as err:
            log.info("refused command %r: %s", payload[:200], err.reason)
            self._reply(err.id, err.reason)
            return
        if retained:
            log.warning("refused retained command %s (id %r)", cmd.cmd, cmd.id)
            self._reply(cmd.id, f"retained command {cmd.cmd!r} refused: publish commands without the "
                                "retain flag (a retained command is replayed on every reconnection); "
                                "clear it with an empty retained message")
            return
        t0 = time.monotonic()
        log.info("command %s (id %r)", cmd.cmd, cmd.id)
        if cmd.ignored:
            log.warning("%s accepted despite: %s", cmd.cmd, "; ".join(cmd.ignored))
        try:
            error = getattr(self, f"_cmd_{cmd.cmd}")(cmd)
        except Exception as err:  # noqa: BLE001 - a command must never kill the service
            log.exception("command %s failed", cmd.cmd)
            error = f"{cmd.cmd} failed: {err}"
        if cmd.cmd == "abort":
            log.info("abort requested of the executor %.1f ms after the message arrived",
                     (time.monotonic() - t0) * 1e3)
        self._reply(cmd.id, error)

    def _reply(self, cid: str | None, error: str | None) -> None:
        payload = proto.reply_ok(cid) if error is None else proto.reply_error(cid, error)
        self._send(self.topics.reply, payload, proto.QOS_REPLY)

    def _cmd_status(self, cmd: proto.Command) -> str | None:
        self._send(self.topics.status, self._status, proto.QOS_STATUS, True)
        return None

    def _cmd_start(self, cmd: proto.Command) -> str | None:
        if self.run_active:
            return (f"a run is active (run {self._run_id}, state {self._state}): "
                    "stop or abort it before starting another")
        folder = self.settings.matrices_dir
        path = folder / f"{cmd.matrix}.toml"
        if not path.is_file():
            names = sorted(p.stem for p in folder.glob("*.toml")) if folder.is_dir() else []
            return f"no matrix {cmd.matrix!r} in the matrix folder (available: {', '.join(names) or 'none'})"
        try:
            matrix = self._load_matrix(path)
        except ConfigError as err:
            return f"matrix {cmd.matrix!r} is invalid: {'; '.join(err.problems)}"
        engine = self._engine_factory(cmd.matrix, matrix)
        engine.subscribe(self._on_event)
        self._engine = engine
        self._run_id = getattr(engine, "run_id", None)
        assert self._tg is not None
        self._run_task = self._tg.create_task(self._run(engine, cmd.matrix, matrix), name=f"run-{cmd.matrix}")
        self._live = live_feed.attach(engine, matrix, lambda p: self._send(self.topics.live, p, proto.QOS_LIVE))
        if self._live is not None:
            self._tg.create_task(self._live.run(self._run_task), name=f"live-{cmd.matrix}")
        return None

    def _cmd_pause(self, cmd: proto.Command) -> str | None:
        return self._control("pause", lambda e: e.request_pause(), allowed=("running", "waiting"))

    def _cmd_resume(self, cmd: proto.Command) -> str | None:
        return self._control("resume", lambda e: e.request_resume(), allowed=("paused",))

    def _cmd_confirm(self, cmd: proto.Command) -> str | None:
        return self._control("confirm", lambda e: e.confirm(cmd.step), allowed=None)

    def _cmd_stop(self, cmd: proto.Command) -> str | None:
        self._request("stop")
        return None  # always accepted

    def _cmd_abort(self, cmd: proto.Command) -> str | None:
        self._request("abort")
        return None  # always accepted

    def _control(self, what: str, call: Callable[[Engine], None], allowed: tuple[str, ...] | None) -> str | None:
        if not self.run_active or self._engine is None:
            return f"no run is active: nothing to {what}"
        state = getattr(self._engine, "state", self._state)
        if allowed is not None and state not in allowed:
            return f"cannot {what} while the run is {state}"
        try:
            call(self._engine)
        except (OrbitrigError, ValueError, RuntimeError) as err:
            return f"cannot {what}: {err}"
        return None

    def _request(self, what: Literal["pause", "stop", "abort"]) -> None:
        """Ask the executor to pause/stop/abort; never raises. If the executor
        refuses a stop or abort, the run task is cancelled (its cleanup ramps
        both drives to zero)."""
        engine, task = self._engine, self._run_task
        if task is None or task.done() or engine is None:
            return
        if what in ("stop", "abort") and getattr(engine, "state", None) == "idle":
            task.cancel()  # the run task has not started yet: it never touches the drives
            return
        try:
            getattr(engine, f"request_{what}")()
        except Exception:  # noqa: BLE001
            log.exception("executor refused %s", what)
            if what in ("stop", "abort"):
                task.cancel()

    async def _run(self, engine: Engine, name: str, matrix: Any) -> None:
        log.info("run of matrix %r starting", name)
        try:
            outcome = await engine.run(matrix)
        except asyncio.CancelledError:
            self._set_status("idle", self._run_id, f"run of {name!r} cancelled; drives stopped")
            raise
        except Exception as err:  # noqa: BLE001 - reported, the service goes on
            log.exception("run of matrix %r failed", name)
            if self._state != "faulted":
                self._set_status("faulted", self._run_id, f"run of {name!r} failed: {err}")
            return
        status = getattr(outcome, "status", outcome)
        log.info("run %s of matrix %r ended: %s", self._run_id, name, status)
        if self._state not in ("idle", "faulted"):
            self._set_status("idle", self._run_id, f"run {status}")

    # -- executor events --------------------------------------------------------

    def _on_event(self, event: Any) -> None:
        """Executor event -> MQTT message (thread-safe)."""
        if threading.get_ident() != self._thread and self._loop is not None:
            self._loop.call_soon_threadsafe(self._on_event, event)
            return
        if hasattr(event, "state"):
            extra = self._live.waiting_fields(event.state) if self._live is not None else None
            self._set_status(event.state, event.run_id, event.message or "", event.since, extra)
        elif hasattr(event, "payload"):
            self._send(self.topics.result, proto.result_payload(event.run_id, event.payload), proto.QOS_RESULT)
        elif hasattr(event, "point"):
            self._send(self.topics.progress, proto.progress_payload(
                event.run_id, event.point, event.points, event.frequency, event.frequencies,
                event.revolutions, event.eta_s), proto.QOS_PROGRESS)
        else:
            log.debug("ignored event %r", event)

    def _set_status(self, state: str, run_id: str | None, message: str | None, since: Any = None,
                    extra: dict[str, Any] | None = None) -> None:
        self._state, self._run_id = state, run_id
        self._status = proto.status_payload(state, run_id, since, message, extra)
        self._send(self.topics.status, self._status, proto.QOS_STATUS, True)

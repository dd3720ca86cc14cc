"""How the rig service connects and behaves: broker settings, service
settings and the client id. Light (the standard library and orbitrig.errors): the command line
reads the service's defaults from here at its start."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from enum import StrEnum
from typing import Any
from urllib.parse import urlsplit

from orbitrig.errors import OrbitrigError


class SupervisionPolicy(StrEnum):
    """What the service does to a run when the executor's supervision times out."""

    KEEP = "keep"
    PAUSE = "pause"
    STOP = "stop"


SUPERVISION_POLICIES: tuple[SupervisionPolicy, ...] = tuple(SupervisionPolicy)
#: s the broker may be away before the supervision policy applies to a running run (serve's default)
SUPERVISION_TIMEOUT_S = 60.0
#: the rig id of a service (and of a dashboard watching it) not given one: topic prefix orbitrig/rig1
DEFAULT_RIG_ID = "rig1"


class ServiceError(OrbitrigError):
    """The service cannot run (bad broker URL, credentials refused, ...)."""


class CommandRefused(OrbitrigError):
    """A command handler's refusal; ``reason`` is the reply's error text (the service goes on)."""

    def __init__(self, reason: str):
        self.reason = reason
        super().__init__(reason)


def supervision_policy(name: str) -> SupervisionPolicy:
    """The policy called `name` (keep, pause, stop); ServiceError naming the choices otherwise."""
    if name not in SUPERVISION_POLICIES:
        raise ServiceError(f"supervision policy {name!r}: one of {', '.join(SUPERVISION_POLICIES)}")
    return SupervisionPolicy(name)


# -- settings -----------------------------------------------------------------

#: s the engine allows beyond the drives' stop timeout before it gives up waiting for standstill
STOP_MARGIN_S = 5.0
#: s for what follows the drives' stop: the links closed, the storage in flight finished and the
#: run's end recorded (run.h5's consolidation and fsync, coefficients.csv, run.log)
RECORD_END_S = 120.0


def run_end_timeout(stop_timeout_wall_s: float) -> float:
    """s a run stopped by the service may take to end: the drives' stop timeout (wall s),
    the engine's margin and the recording of the run's end. Only beyond it is the run
    cancelled, and its drives' stop is then not confirmed."""
    return stop_timeout_wall_s + STOP_MARGIN_S + RECORD_END_S


@dataclasses.dataclass(frozen=True)
class AbortAccount:
    """The broker account of the service's second connection, which reads
    ``<prefix>/abort`` alone (orbitrig.service.abort_link); ``username`` None: an
    anonymous connection (a broker without authentication)."""

    username: str | None
    password: str | None = dataclasses.field(default=None, repr=False)


#: The abort connection's account name beside the service's (``orbitrig serve --abort-username``).
ABORT_ACCOUNT_SUFFIX = "-abort"


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
    #: the account of the abort connection; None: no second connection (stop and abort
    #: then come through the main connection only, behind any flood of commands there)
    abort: AbortAccount | None = None

    @classmethod
    def from_url(cls, url: str, **kw: Any) -> BrokerSettings:
        """``mqtt://host:port`` (default port 1883) or ``mqtts://host:port`` (TLS, 8883).
        TLS is also used with ``mqtt://`` when ``tls_ca`` is given."""
        parts = urlsplit(url)
        if parts.scheme not in ("mqtt", "mqtts") or not parts.hostname:
            raise ServiceError(f"broker URL {url!r}: expected mqtt://host:port or mqtts://host:port")
        if parts.username or parts.password:
            raise ServiceError(
                f"broker URL {url!r}: credentials do not belong in the URL "
                "(use --username and --password-file or ORBITRIG_MQTT_PASSWORD)"
            )
        if parts.path not in ("", "/") or parts.query:
            raise ServiceError(f"broker URL {url!r}: no path or query expected")
        try:
            port = parts.port
        except ValueError as err:
            raise ServiceError(f"broker URL {url!r}: {err}") from None
        tls = parts.scheme == "mqtts" or kw.get("tls_ca") is not None
        return cls(host=parts.hostname, port=port or (8883 if parts.scheme == "mqtts" else 1883), tls=tls, **kw)


@dataclasses.dataclass(frozen=True)
class ServiceSettings:
    """Behaviour of the service (times in s)."""

    rig_id: str
    matrices_dir: Path
    prefix: str | None = None
    supervision_policy: SupervisionPolicy = SupervisionPolicy.KEEP
    supervision_timeout: float = SUPERVISION_TIMEOUT_S
    reconnect_initial: float = 0.2
    reconnect_max: float = 30.0
    #: s a run may take to end when the service stops it (shutdown); None: derived from the
    #: run's rig, the drives' stop timeout as wall time and a margin (``run_end_timeout``)
    shutdown_timeout: float | None = None
    #: MQTT client id asked for; None: ``default_client_id(rig_id, prefix)``. A broker
    #: configured as config/mosquitto/ replaces it with the account's user name.
    client_id: str | None = None
    #: s the broker keeps the session (subscription, queued QoS 1 commands) after a disconnect
    session_expiry: int = 120
    #: campaign catalog URL each completed point is added to (orbitrig.service.catalog_feed); None: none
    catalog_url: str | None = None
    #: each completed point's report figures drawn during the run (orbitrig.analysis.report_ahead)
    draw_figures: bool = True
    #: the folder the service's runs are written to: its last run is read from it at the start, for
    #: the ``last_run`` of the first status (orbitrig.service.last_run); None: not read (``last_run`` null)
    runs_dir: Path | None = None

    @property
    def mqtt_client_id(self) -> str:
        return self.client_id or default_client_id(self.rig_id, self.prefix)

    @property
    def abort_client_id(self) -> str:
        """The abort connection's client id: the service's with ``-abort`` (a broker
        configured as config/mosquitto/ replaces it with the abort account's name)."""
        suffix = ABORT_ACCOUNT_SUFFIX
        return self.mqtt_client_id.encode()[: 128 - len(suffix)].decode(errors="ignore") + suffix

    def __post_init__(self) -> None:
        object.__setattr__(self, "supervision_policy", supervision_policy(self.supervision_policy))
        if not 0 < self.supervision_timeout < math.inf:
            raise ServiceError(
                f"supervision timeout must be a finite number of seconds > 0, not {self.supervision_timeout!r}"
            )
        if self.shutdown_timeout is not None and not 0 < self.shutdown_timeout < math.inf:
            raise ServiceError(
                f"shutdown timeout must be a finite number of seconds > 0, not {self.shutdown_timeout!r}"
            )
        if self.client_id is not None and not 0 < len(self.client_id.encode()) <= 128:
            raise ServiceError("client id must have 1 to 128 bytes")


#: Client ids of people's clients start with this on the shipped broker config
#: (mosquitto's own tools' prefix and its ``auto_id_prefix`` there).
CLIENT_ID_PREFIX = "mosq-"


def default_client_id(rig_id: str, prefix: str | None = None) -> str:
    """A stable client id per service instance (its topic prefix): the same on
    every reconnection, so the broker's session and queued commands are found."""
    from orbitrig.service.protocol import DEFAULT_PREFIX_ROOT

    where = (prefix or f"{DEFAULT_PREFIX_ROOT}/{rig_id}").replace("/", "-")
    return f"{CLIENT_ID_PREFIX}orbitrig-serve-{where}"[:128]

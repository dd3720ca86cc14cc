"""`orbitrig dashboard`: the live view of a rig in the browser (orbitrig.dashboard)."""

from __future__ import annotations

import ipaddress
from pathlib import Path
from typing import NoReturn, Optional

import typer

from orbitrig.cli.serve_options import BrokerOpt, PrefixOpt, RigIdOpt, TlsCaOpt
from orbitrig.cli.signals import log_ignored, refuse_suspension, signal_cause, watched
from orbitrig.dashboard import defaults as d  # light: the command's defaults without the server
from orbitrig.dashboard.throttle import ADDRESS_FACTOR
from orbitrig.service.settings import DEFAULT_RIG_ID
from rigunits import DAY

#: why the dashboard does not suspend on Ctrl-Z (orbitrig.cli.signals.refuse_suspension)
RELAYS = "while it relays the operators' stop and abort (suspended, it would hold them back)"


def _fail(message: str, code: int = 2) -> NoReturn:
    from orbitrig.cli.failure import fail

    fail(message, code)


def _http_address(text: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        _fail(f"--http {text!r}: expected HOST:PORT, e.g. 127.0.0.1:8080")
    return host.strip("[]"), int(port)


def _loopback(host: str) -> bool:
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return host == "localhost"


def _https_context(cert: Path | None, key: Path | None, host: str):
    """The TLS context of the page (None: plain HTTP, allowed on loopback only:
    passwords cross this connection at sign-in)."""
    import ssl

    if (cert is None) != (key is None):
        _fail("--https-cert and --https-key go together")
    if cert is None:
        if not _loopback(host):
            _fail(
                f"--http {host}: plain HTTP only on loopback (passwords are sent at sign-in); "
                "give --https-cert and --https-key, or serve on 127.0.0.1 behind a TLS reverse proxy"
            )
        return None
    ctx = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
    try:
        ctx.load_cert_chain(cert, key)
    except (OSError, ssl.SSLError) as err:
        _fail(f"--https-cert/--https-key: cannot load {cert} / {key}: {err}")
    return ctx


def _limits(
    sessions_per_user: int, signin_delay: float, lockout_after: int, lockout: float, request_timeout: float
) -> dict:
    """The dashboard's limits as DashboardSettings fields (exit 2 on a value out of range)."""
    import math

    from orbitrig.dashboard.throttle import ThrottlePolicy

    if not 1 <= sessions_per_user <= d.MAX_SESSIONS:
        _fail(f"--sessions-per-user must be 1..{d.MAX_SESSIONS}")
    if lockout_after < 1:
        _fail("--lockout-after must be >= 1")
    for name, value in (
        ("--signin-delay", signin_delay),
        ("--lockout", lockout),
        ("--request-timeout", request_timeout),
    ):
        if not (math.isfinite(value) and 0 < value <= DAY):
            _fail(f"{name} must be > 0 s and at most a day")
    return {
        "sessions_per_user": sessions_per_user,
        "request_timeout": request_timeout,
        "throttle": ThrottlePolicy(delay=signin_delay, lock_after=lockout_after, lockout=lockout),
    }


def _settings(
    broker: str,
    rig_id: str,
    prefix: str | None,
    tls_ca: Path | None,
    idle_timeout: float,
    reply_timeout: float,
    limits: dict,
    tick: float,
):
    import math

    from orbitrig.analysis.typeset import entry_html, force_channels, message_html
    from orbitrig.dashboard.lifted import PageTypesetting
    from orbitrig.cli.serve_options import tls_ca_problem
    from orbitrig.dashboard.session import DashboardSettings
    from orbitrig.service.protocol import topics, validate_rig_id
    from orbitrig.service.rig_service import BrokerSettings, ServiceError

    try:
        validate_rig_id(rig_id)
        tree = topics(rig_id, prefix)
    except ValueError as err:
        _fail(str(err))
    problem = tls_ca_problem(tls_ca)
    if problem is not None:
        _fail(problem)
    for name, value in (("--idle-timeout", idle_timeout), ("--reply-timeout", reply_timeout)):
        if not 0 < value < math.inf:  # NaN too: a session would never end, a reply never be waited for
            _fail(f"{name} {value:g}: a finite number of seconds > 0")
    if not 0 < tick <= 60:
        _fail("--tick must be > 0 and at most 60 s")
    try:
        where = BrokerSettings.from_url(broker, tls_ca=tls_ca)
    except ServiceError as err:
        _fail(str(err))
    return DashboardSettings(
        host=where.host,
        port=where.port,
        topics=tree,
        tls=where.tls,
        tls_ca=tls_ca,
        idle_timeout=idle_timeout,
        reply_timeout=reply_timeout,
        tick=tick,
        names=force_channels(),  # the plots' legends name the forces as the report does
        # the results table names the coefficients so too, the event list lifts the columns a message names
        typeset=PageTypesetting(entry_html=entry_html, message_html=message_html),
        **limits,
    )


async def _serve_until_signal(settings, host: str, port: int, ssl_context) -> None:
    """Serve the page until Ctrl-C or SIGTERM (those not ignored since the start), saying which
    ended it ('SIGTERM: the dashboard stops', orbitrig.cli.signals.signal_cause); Ctrl-Z refused."""
    import asyncio
    import logging
    import signal

    from orbitrig.dashboard.server import serve

    shutdown = asyncio.Event()
    loop = asyncio.get_running_loop()
    log = logging.getLogger("orbitrig.cli.dashboard")

    def on_signal(sig: signal.Signals) -> None:
        if not shutdown.is_set():  # said once
            log.info("%s: the dashboard stops", signal_cause(sig))
        shutdown.set()

    for sig in watched((signal.SIGINT, signal.SIGTERM)):
        loop.add_signal_handler(sig, on_signal, sig)
    refuse_suspension(loop, "dashboard", log.warning, RELAYS)
    await serve(settings, host, port, shutdown, ssl_context=ssl_context)


_TICK = typer.Option(
    d.TICK_S,
    "--tick",
    help="s without a message to a page after which the server sends one; the page calls its view stale "
    "after 7/3 of it (7 s) and reconnects a feed silent for 4 of it (12 s)",
)


def register(app: typer.Typer) -> None:
    @app.command("dashboard")
    def dashboard(
        broker: BrokerOpt,  # the options that meet the service's: as serve's (one option, one help)
        rig_id: RigIdOpt = DEFAULT_RIG_ID,
        prefix: PrefixOpt = None,
        http: str = typer.Option("127.0.0.1:8080", "--http", help="HOST:PORT the page is served on"),
        https_cert: Optional[Path] = typer.Option(None, "--https-cert", help="serve HTTPS with this certificate"),
        https_key: Optional[Path] = typer.Option(None, "--https-key", help="its private key"),
        tls_ca: TlsCaOpt = None,
        idle_timeout: float = typer.Option(
            d.IDLE_TIMEOUT_S, "--idle-timeout", help="s without activity that end a session"
        ),
        reply_timeout: float = typer.Option(
            d.REPLY_TIMEOUT_S,
            "--reply-timeout",
            help="s to wait for the service's reply; without it a command's outcome is unknown (the page says so)",
        ),
        sessions_per_user: int = typer.Option(
            d.SESSIONS_PER_USER,
            "--sessions-per-user",
            help="sessions one broker user may hold; a new sign-in ends the oldest",
        ),
        signin_delay: float = typer.Option(
            d.SIGNIN_DELAY_S,
            "--signin-delay",
            help="s before the next sign-in after a refused one; doubles with every refusal",
        ),
        lockout_after: int = typer.Option(
            d.LOCK_AFTER,
            "--lockout-after",
            help=f"refused sign-ins that lock a user name out (a client address: {ADDRESS_FACTOR}x)",
        ),
        lockout: float = typer.Option(
            d.LOCKOUT_S, "--lockout", help="s a lockout lasts (the right password waits too)"
        ),
        request_timeout: float = typer.Option(
            d.REQUEST_TIMEOUT_S,
            "--request-timeout",
            help="s a request's head and body must arrive within (slow clients cut)",
        ),
        tick: float = _TICK,
        verbose: bool = typer.Option(False, "--verbose", "-v", help="log at debug level"),
    ) -> None:
        """Serve the live view of a rig: sign in with your broker user name and password."""
        import asyncio

        from orbitrig.cli.service_log import setup_service_log

        setup_service_log(verbose=verbose)  # a terminal that stops reading (Ctrl-S) holds back no abort
        log_ignored("dashboard")  # a background job of a script: Ctrl-C does not reach it
        limits = _limits(sessions_per_user, signin_delay, lockout_after, lockout, request_timeout)
        settings = _settings(broker, rig_id, prefix, tls_ca, idle_timeout, reply_timeout, limits, tick)
        host, port = _http_address(http)
        ssl_context = _https_context(https_cert, https_key, host)

        try:
            asyncio.run(_serve_until_signal(settings, host, port, ssl_context))
        except OSError as err:
            _fail(f"--http {http}: {err.strerror or err}", 1)

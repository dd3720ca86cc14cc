"""`orbitrig serve`: the rig service under MQTT control (docs/protocols/mqtt.md)."""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import Optional

import typer

from orbitrig.cli.service_log import DEFAULT_BACKUPS, DEFAULT_MAX_MB, setup_service_log

PASSWORD_ENV = "ORBITRIG_MQTT_PASSWORD"
USERNAME_ENV = "ORBITRIG_MQTT_USERNAME"


def _fail(message: str, code: int = 2) -> None:
    """A usage or configuration error: one plain line on standard error, exit `code`."""
    typer.echo(f"orbitrig serve: {message}", err=True)
    raise typer.Exit(code)


def read_password(password_file: Path | None) -> str | None:
    """The broker password from ``password_file`` (first line) or from the
    environment variable ORBITRIG_MQTT_PASSWORD; None when neither is given.
    A file other users may read or write is refused (as ssh refuses such a key)."""
    if password_file is not None:
        try:
            mode = password_file.stat().st_mode
            if mode & (stat.S_IRWXG | stat.S_IRWXO):
                _fail(f"--password-file: {password_file} is accessible by other users "
                      f"(mode {stat.S_IMODE(mode):04o}): chmod 600 {password_file}")
            text = password_file.read_bytes().decode("utf-8")
        except OSError as err:
            _fail(f"--password-file: cannot read {password_file}: {err.strerror or err}")
        except UnicodeDecodeError as err:
            _fail(f"--password-file: {password_file} is not UTF-8 text ({err.reason} at byte {err.start})")
        password = text.splitlines()[0] if text.strip() else ""
        if not password:
            _fail(f"--password-file: {password_file} is empty")
        return password
    return os.environ.get(PASSWORD_ENV) or None


def register(app: typer.Typer) -> None:
    @app.command("serve")
    def serve(
        broker: str = typer.Option(..., "--broker", help="mqtt://host:port or mqtts://host:port"),
        sim: bool = typer.Option(False, "--sim", help="run against the built-in simulator"),
        config: Optional[Path] = typer.Option(None, "--config", help="rig configuration (TOML)"),
        rig_id: str = typer.Option("rig1", "--rig-id", help="topic prefix orbitrig/<rig-id>"),
        prefix: Optional[str] = typer.Option(
            None, "--prefix", help="topic prefix instead of orbitrig/<rig-id> (levels without wildcards)"),
        username: Optional[str] = typer.Option(None, "--username", envvar=USERNAME_ENV,
                                               help="broker user name"),
        password_file: Optional[Path] = typer.Option(
            None, "--password-file",
            help=f"file holding the broker password (else ${PASSWORD_ENV}); never on the command line"),
        tls_ca: Optional[Path] = typer.Option(None, "--tls-ca", help="CA file: TLS to the broker"),
        out: Path = typer.Option(Path("runs"), "--out", help="runs are written to OUT/<date>-<matrix>/"),
        matrices: Optional[Path] = typer.Option(
            None, "--matrices", help="matrix folder (default: 'matrices' beside the rig config)"),
        supervision_policy: str = typer.Option(
            "keep", "--supervision-policy",
            help="when the broker is gone longer than --supervision-timeout: keep | pause | stop"),
        supervision_timeout: float = typer.Option(60.0, "--supervision-timeout", help="s"),
        client_id: Optional[str] = typer.Option(
            None, "--client-id",
            help="MQTT client id (default mosq-orbitrig-serve-<prefix>; see config/mosquitto/README.md)"),
        confirm: str = typer.Option(
            "remote", "--confirm",
            help="manual settings: remote (wait for a 'confirm' command) | auto (--sim only)"),
        speedup: Optional[float] = typer.Option(None, "--speedup",
                                                help="simulator time speed-up (--sim; default: as orbitrig sweep)"),
        verbose: bool = typer.Option(False, "--verbose", "-v", help="log at debug level (every event)"),
        catalog: Optional[str] = typer.Option(
            None, "--catalog", envvar="ORBITRIG_CATALOG",
            help="campaign catalog URL: each completed point is added (docs/catalog.md)"),
        log_file: Optional[Path] = typer.Option(None, "--log-file", help="also log to this file, rotated by size"),
        log_max_mb: float = typer.Option(DEFAULT_MAX_MB, "--log-max-mb", help="MB per log file before it rotates"),
        log_backups: int = typer.Option(DEFAULT_BACKUPS, "--log-backups", help="rotated log files kept (LOG.1 ...)"),
    ) -> None:
        """Run the rig service: start, watch and stop runs over MQTT."""
        _start(broker=broker, sim=sim, config=config, rig_id=rig_id, prefix=prefix, username=username,
               password_file=password_file, tls_ca=tls_ca, out=out, matrices=matrices,
               supervision_policy=supervision_policy, supervision_timeout=supervision_timeout,
               client_id=client_id, confirm=confirm, speedup=speedup, verbose=verbose, catalog=catalog,
               log=(log_file, log_max_mb, log_backups))


def _broker_password(rig_id: str, prefix: str | None, tls_ca: Path | None, username: str | None,
                     password_file: Path | None) -> str | None:
    """Check the topic and broker options; the password (exit 2 on any problem)."""
    from orbitrig.service.protocol import topics, validate_rig_id

    try:
        validate_rig_id(rig_id)
    except ValueError as err:
        _fail(f"--rig-id: {err}")
    try:
        topics(rig_id, prefix)
    except ValueError as err:
        _fail(f"--prefix: {err}")
    if tls_ca is not None and not tls_ca.is_file():
        _fail(f"--tls-ca: no such file: {tls_ca}")
    password = read_password(password_file)
    if username is None and password is not None:
        _fail("a password needs a user name (--username or ORBITRIG_MQTT_USERNAME)")
    if username is not None and password is None:
        _fail(f"no password: give --password-file or set {PASSWORD_ENV}")
    return password


def _start(*, broker: str, sim: bool, config: Path | None, rig_id: str, prefix: str | None,
           username: str | None, password_file: Path | None, tls_ca: Path | None, out: Path,
           matrices: Path | None, supervision_policy: str, supervision_timeout: float,
           client_id: str | None, confirm: str, speedup: float | None, verbose: bool,
           catalog: str | None = None,
           log: tuple[Path | None, float, int] = (None, DEFAULT_MAX_MB, DEFAULT_BACKUPS)) -> None:
    import asyncio

    from orbitrig import config as cfg
    from orbitrig.errors import ConfigError
    from orbitrig.run.states import ConfirmMode
    from orbitrig.service.rig_service import BrokerSettings, ServiceError, ServiceSettings

    log_file, max_mb, backups = log
    if not (max_mb > 0 and backups >= 0):
        _fail(f"--log-max-mb {max_mb:g} / --log-backups {backups}: a size > 0 and a count >= 0")
    try:
        setup_service_log(verbose=verbose, log_file=log_file, max_mb=max_mb, backups=backups)
    except OSError as err:
        _fail(f"--log-file: cannot open {log_file}: {err.strerror or err}")
    password = _broker_password(rig_id, prefix, tls_ca, username, password_file)
    try:
        rig = cfg.load_rig(config)
        broker_settings = BrokerSettings.from_url(broker, username=username, password=password,
                                                  tls_ca=tls_ca)
        folder = matrices or Path(rig.file).resolve().parent / "matrices"
        settings = ServiceSettings(rig_id=rig_id, matrices_dir=folder, prefix=prefix,
                                   supervision_policy=supervision_policy,
                                   supervision_timeout=supervision_timeout, client_id=client_id,
                                   catalog_url=catalog)
    except (ConfigError, ServiceError) as err:
        _fail(str(err))
    if speedup is not None and not 0 < speedup <= 1e4:
        _fail(f"--speedup {speedup:g}: a finite factor > 0 and at most 10000")
    if confirm not in (ConfirmMode.REMOTE, ConfirmMode.AUTO):
        _fail(f"--confirm: one of remote, auto, not {confirm!r}")
    if confirm == ConfirmMode.AUTO and not sim:
        _fail("--confirm auto only with --sim (a real rig needs an operator)")
    if not folder.is_dir():
        _fail(f"matrix folder: no such folder: {folder} (--matrices)")
    try:
        asyncio.run(_serve(rig, settings, broker_settings, out=out, sim=sim, speedup=speedup,
                           confirm=confirm))
    except* ServiceError as group:
        _fail("; ".join(str(e) for e in group.exceptions), 1)


def build_service(rig, settings, broker_settings, *, out: Path, sim_rig=None, confirm: str = "remote"):
    """The RigService of `orbitrig serve`: each run gets a fresh RunEngine (the engine of
    `orbitrig sweep`; on the simulator `sim_rig` when given) writing to OUT/<date>-<matrix>/."""

    from orbitrig import config as cfg
    from orbitrig.run.engine import RunEngine
    from orbitrig.run.plan import make_plan
    from orbitrig.service.rig_service import RigService
    from rigunits import utc_stamp

    access = None
    if sim_rig is not None:
        from orbitrig.cli.simulated_rig import simulated_access

        access = simulated_access(sim_rig)

    def load_matrix(path: Path):
        # every problem of this matrix on this rig, before anything moves; the plan is run as it is
        return make_plan(cfg.load_matrix(path), rig)

    def new_engine(name: str, matrix):
        stamp = utc_stamp()
        run_dir, n = out / f"{stamp}-{name}", 1
        while run_dir.exists():
            n += 1
            run_dir = out / f"{stamp}-{name}-{n}"
        return RunEngine(rig, out_dir=run_dir, access=access, confirm_mode=confirm)

    return RigService(settings, broker_settings, engine_factory=new_engine, load_matrix=load_matrix)


async def _serve(rig, settings, broker_settings, *, out: Path, sim: bool, speedup: float | None,
                 confirm: str) -> None:
    import asyncio
    import contextlib
    import signal

    shutdown = asyncio.Event()
    loop = asyncio.get_running_loop()
    from orbitrig.run.heap import tune_heap
    from orbitrig.run.modbus_log import keep_pymodbus_off_the_terminal

    keep_pymodbus_off_the_terminal()
    tune_heap()  # bounded memory over months (orbitrig.run.heap)
    services = []

    def on_signal() -> None:  # the first: the run stops at once with a ramp; another: it aborts
        if shutdown.is_set() and services:
            services[0].abort_run("a second signal while shutting down")
        shutdown.set()

    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        loop.add_signal_handler(sig, on_signal)

    async with contextlib.AsyncExitStack() as stack:
        sim_rig = None
        if sim:
            from orbitrig.cli.simulated_rig import DEFAULT_SPEEDUP, simulated_rig

            sim_rig, _ = await stack.enter_async_context(simulated_rig(speedup or DEFAULT_SPEEDUP))
        service = build_service(rig, settings, broker_settings, out=out, sim_rig=sim_rig, confirm=confirm)
        services.append(service)
        await service.serve(shutdown)

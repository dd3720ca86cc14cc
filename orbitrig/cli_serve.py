"""`orbitrig serve`: the rig service under MQTT control (spec/mqtt.md)."""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import Optional

import typer

PASSWORD_ENV = "ORBITRIG_MQTT_PASSWORD"
USERNAME_ENV = "ORBITRIG_MQTT_USERNAME"


def read_password(password_file: Path | None) -> str | None:
    """The broker password from ``password_file`` (first line) or from the
    environment variable ORBITRIG_MQTT_PASSWORD; None when neither is given."""
    if password_file is not None:
        try:
            text = password_file.read_text(encoding="utf-8")
            mode = password_file.stat().st_mode
        except OSError as err:
            raise typer.BadParameter(f"cannot read {password_file}: {err.strerror or err}",
                                     param_hint="--password-file") from None
        if mode & (stat.S_IRGRP | stat.S_IROTH | stat.S_IWOTH):
            typer.echo(f"warning: {password_file} is readable by other users (chmod 600 it)", err=True)
        password = text.splitlines()[0] if text.strip() else ""
        if not password:
            raise typer.BadParameter(f"{password_file} is empty", param_hint="--password-file")
        return password
    return os.environ.get(PASSWORD_ENV) or None


def register(app: typer.Typer) -> None:
    @app.command("serve")
    def serve(
        broker: str = typer.Option(..., "--broker", help="mqtt://host:port or mqtts://host:port"),
        sim: bool = typer.Option(False, "--sim", help="run against the built-in simulator"),
        config: Optional[Path] = typer.Option(None, "--config", help="rig configuration (TOML)"),
        rig_id: str = typer.Option("rig1", "--rig-id", help="topic prefix orbitrig/<rig-id>"),
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
        confirm: str = typer.Option(
            "remote", "--confirm",
            help="manual settings: remote (wait for a 'confirm' command) | auto (--sim only)"),
        speedup: Optional[float] = typer.Option(None, "--speedup",
                                                help="simulator time speed-up (--sim; default: as orbitrig sweep)"),
        verbose: bool = typer.Option(False, "--verbose", "-v"),
    ) -> None:
        """Run the rig service: start, watch and stop runs over MQTT."""
        import asyncio
        import logging

        from orbitrig import config as cfg
        from orbitrig.errors import ConfigError
        from orbitrig.mqtt_protocol import validate_rig_id
        from orbitrig.service import BrokerSettings, RigService, ServiceError, ServiceSettings

        logging.basicConfig(level=logging.DEBUG if verbose else logging.INFO,
                            format="%(asctime)s %(levelname)s %(name)s: %(message)s")
        logging.getLogger("mqtt").setLevel(logging.WARNING)
        try:
            validate_rig_id(rig_id)
        except ValueError as err:
            raise typer.BadParameter(str(err), param_hint="--rig-id") from None
        if tls_ca is not None and not tls_ca.is_file():
            raise typer.BadParameter(f"no such file: {tls_ca}", param_hint="--tls-ca")
        password = read_password(password_file)
        if username is None and password is not None:
            raise typer.BadParameter("a password needs a user name", param_hint="--username")
        if username is not None and password is None:
            raise typer.BadParameter(f"no password: give --password-file or set {PASSWORD_ENV}",
                                     param_hint="--password-file")
        try:
            rig = cfg.load_rig(config)
            broker_settings = BrokerSettings.from_url(broker, username=username, password=password,
                                                      tls_ca=tls_ca)
            folder = matrices or Path(rig.file).resolve().parent / "matrices"
            settings = ServiceSettings(rig_id=rig_id, matrices_dir=folder,
                                       supervision_policy=supervision_policy,  # type: ignore[arg-type]
                                       supervision_timeout=supervision_timeout)
        except (ConfigError, ServiceError) as err:
            typer.echo(f"error: {err}", err=True)
            raise typer.Exit(2) from None
        if confirm not in ("remote", "auto"):
            raise typer.BadParameter("one of remote, auto", param_hint="--confirm")
        if confirm == "auto" and not sim:
            raise typer.BadParameter("auto confirmation only with --sim (a real rig needs an operator)",
                                     param_hint="--confirm")
        if not folder.is_dir():
            raise typer.BadParameter(f"no such folder: {folder}", param_hint="--matrices")
        try:
            asyncio.run(_serve(rig, settings, broker_settings, out=out, sim=sim, speedup=speedup,
                               confirm=confirm))
        except* ServiceError as group:
            for err in group.exceptions:
                typer.echo(f"error: {err}", err=True)
            raise typer.Exit(1) from None


def build_service(rig, settings, broker_settings, *, out: Path, sim_rig=None, confirm: str = "remote"):
    """The RigService of `orbitrig serve`: each run gets a fresh RunEngine
    (the executor of `orbitrig sweep`) writing to OUT/<date>-<matrix>/."""
    import datetime as dt

    from orbitrig import config as cfg
    from orbitrig.executor import RunEngine
    from orbitrig.plan import expand
    from orbitrig.service import RigService

    def load_matrix(path: Path):
        matrix = cfg.load_matrix(path)
        expand(matrix, rig)  # every problem of this matrix on this rig, before anything moves
        return matrix

    def new_engine(name: str, matrix):
        stamp = dt.datetime.now().strftime("%Y%m%d-%H%M%S")
        run_dir, n = out / f"{stamp}-{name}", 1
        while run_dir.exists():
            n += 1
            run_dir = out / f"{stamp}-{name}-{n}"
        return RunEngine(rig, out_dir=run_dir, sim=sim_rig, confirm_mode=confirm)

    return RigService(settings, broker_settings, engine_factory=new_engine, load_matrix=load_matrix)


async def _serve(rig, settings, broker_settings, *, out: Path, sim: bool, speedup: float | None,
                 confirm: str) -> None:
    import asyncio
    import contextlib
    import signal

    shutdown = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, shutdown.set)

    async with contextlib.AsyncExitStack() as stack:
        sim_rig = None
        if sim:
            from orbitrig.cli_sweep import DEFAULT_SIM_SPEEDUP
            from sim.rig import SimRig

            sim_rig = await stack.enter_async_context(
                SimRig(speedup=speedup or DEFAULT_SIM_SPEEDUP, adc_pty=False))
        service = build_service(rig, settings, broker_settings, out=out, sim_rig=sim_rig, confirm=confirm)
        await service.serve(shutdown)

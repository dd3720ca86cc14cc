"""The options of `orbitrig serve` and the broker settings made of them: the service's
account and the account of its abort connection (docs/protocols/mqtt.md), passwords
from a file or the environment, never from the command line."""

from __future__ import annotations

import dataclasses
import os
import stat
from pathlib import Path
from typing import Annotated, NoReturn, Optional

import typer

from orbitrig.cli.config_help import RIG_CONFIG_HELP
from orbitrig.cli.sweep_options import DrawFigures as DrawFigures  # as sweep's: one option, one help
from orbitrig.cli.sweep_options import SimConfig
from orbitrig.service.settings import SUPERVISION_POLICIES

PASSWORD_ENV = "ORBITRIG_MQTT_PASSWORD"
USERNAME_ENV = "ORBITRIG_MQTT_USERNAME"
ABORT_PASSWORD_ENV = "ORBITRIG_MQTT_ABORT_PASSWORD"

_CLIENT_ID_HELP = "MQTT client id (default mosq-orbitrig-serve-<prefix>; see config/mosquitto/README.md)"
_ABORT_USER_HELP = (
    "account of the abort connection, which reads <prefix>/abort alone so that no flood of commands "
    "is ahead of an abort (default: the --username with '-abort')"
)
_ABORT_PASSWORD_HELP = f"file holding the abort account's password (else ${ABORT_PASSWORD_ENV}, else the service's)"

BrokerOpt = Annotated[str, typer.Option("--broker", help="mqtt://host:port or mqtts://host:port")]
SimOpt = Annotated[bool, typer.Option("--sim", help="run against the built-in simulator")]
SimConfigOpt = SimConfig  # as sweep's (one option, one help): the scenario of every run the service starts
ConfigOpt = Annotated[Optional[Path], typer.Option("--config", help=RIG_CONFIG_HELP)]
RigIdOpt = Annotated[str, typer.Option("--rig-id", help="topic prefix orbitrig/<rig-id>")]
PrefixOpt = Annotated[
    Optional[str], typer.Option("--prefix", help="topic prefix instead of orbitrig/<rig-id> (levels without wildcards)")
]
UsernameOpt = Annotated[Optional[str], typer.Option("--username", envvar=USERNAME_ENV, help="broker user name")]
PasswordFileOpt = Annotated[
    Optional[Path],
    typer.Option(
        "--password-file", help=f"file holding the broker password (else ${PASSWORD_ENV}); never on the command line"
    ),
]
AbortUserOpt = Annotated[Optional[str], typer.Option("--abort-username", help=_ABORT_USER_HELP)]
AbortPasswordFileOpt = Annotated[Optional[Path], typer.Option("--abort-password-file", help=_ABORT_PASSWORD_HELP)]
AbortConnectionOpt = Annotated[
    bool,
    typer.Option(
        "--abort-connection/--no-abort-connection",
        help="a second broker connection for <prefix>/abort (without it, aborts share the main connection)",
    ),
]
TlsCaOpt = Annotated[Optional[Path], typer.Option("--tls-ca", help="CA file: TLS to the broker")]
OutOpt = Annotated[Path, typer.Option("--out", help="runs are written to OUT/<date>-<matrix>/")]
MatricesOpt = Annotated[
    Optional[Path], typer.Option("--matrices", help="matrix folder (default: 'matrices' beside the rig config)")
]
PolicyOpt = Annotated[
    str,
    typer.Option(
        "--supervision-policy",
        help=f"when the broker is gone longer than --supervision-timeout: {' | '.join(SUPERVISION_POLICIES)}",
    ),
]
TimeoutOpt = Annotated[float, typer.Option("--supervision-timeout", help="s")]
ClientIdOpt = Annotated[Optional[str], typer.Option("--client-id", help=_CLIENT_ID_HELP)]
ConfirmOpt = Annotated[
    str, typer.Option("--confirm", help="manual settings: remote (wait for a 'confirm' command) | auto (--sim only)")
]
SpeedupOpt = Annotated[
    Optional[float], typer.Option("--speedup", help="simulator time speed-up (--sim; default: as orbitrig sweep)")
]
VerboseOpt = Annotated[bool, typer.Option("--verbose", "-v", help="log at debug level (every event)")]
CatalogOpt = Annotated[
    Optional[str],
    typer.Option(
        "--catalog",
        envvar="ORBITRIG_CATALOG",
        help="campaign catalog URL: each completed point is added (docs/catalog.md)",
    ),
]
LogFileOpt = Annotated[Optional[Path], typer.Option("--log-file", help="also log to this file, rotated by size")]
LogMbOpt = Annotated[float, typer.Option("--log-max-mb", help="MB per log file before it rotates")]
LogBackupsOpt = Annotated[int, typer.Option("--log-backups", help="rotated log files kept (LOG.1 ...)")]


@dataclasses.dataclass(frozen=True)
class ServeOptions:
    """`orbitrig serve`'s command line, as given (its defaults: the command's, orbitrig.cli.serve)."""

    broker: str
    sim: bool
    sim_config: Path | None
    config: Path | None
    rig_id: str
    prefix: str | None
    username: str | None
    password_file: Path | None
    abort_username: str | None
    abort_password_file: Path | None
    abort_connection: bool
    tls_ca: Path | None
    out: Path
    matrices: Path | None
    supervision_policy: str
    supervision_timeout: float
    client_id: str | None
    confirm: str
    speedup: float | None
    verbose: bool
    catalog: str | None
    draw_figures: bool
    log_file: Path | None
    log_max_mb: float
    log_backups: int


def fail(message: str, code: int = 2) -> NoReturn:
    """A usage or configuration error: one plain line on standard error, exit `code`."""
    from orbitrig.cli.failure import fail as failed

    failed(message, code, command="serve")


def read_password(
    password_file: Path | None, *, option: str = "--password-file", env: str = PASSWORD_ENV
) -> str | None:
    """The broker password from ``password_file`` (first line) or from the
    environment variable ``env``; None when neither is given.
    A file other users may read or write is refused (as ssh refuses such a key)."""
    if password_file is None:
        return os.environ.get(env) or None
    try:
        mode = password_file.stat().st_mode
        if stat.S_ISDIR(mode):  # its mode would be blamed (a folder is 0755)
            fail(f"{option}: {password_file} is a folder: give the file holding the password")
        if mode & (stat.S_IRWXG | stat.S_IRWXO):
            fail(
                f"{option}: {password_file} is accessible by other users "
                f"(mode {stat.S_IMODE(mode):04o}): chmod 600 {password_file}"
            )
        text = password_file.read_bytes().decode("utf-8")
    except OSError as err:
        fail(f"{option}: cannot read {password_file}: {err.strerror or err}")
    except UnicodeDecodeError as err:
        fail(f"{option}: {password_file} is not UTF-8 text ({err.reason} at byte {err.start})")
    password = text.splitlines()[0] if text.strip() else ""
    if not password:
        fail(f"{option}: {password_file} is empty")
    return password


def tls_ca_problem(tls_ca: Path | None) -> str | None:
    """What is wrong with a --tls-ca path (serve's and the dashboard's): no such file, or a folder;
    None when it is a file or not given."""
    if tls_ca is None or tls_ca.is_file():
        return None
    return f"--tls-ca: {'a folder, not a file' if tls_ca.is_dir() else 'no such file'}: {tls_ca}"


def broker_password(opts: ServeOptions) -> str | None:
    """Check the topic and broker options; the password (exit 2 on any problem)."""
    from orbitrig.service.protocol import topics, validate_rig_id

    try:
        validate_rig_id(opts.rig_id)
    except ValueError as err:
        fail(f"--rig-id: {err}")
    try:
        topics(opts.rig_id, opts.prefix)
    except ValueError as err:
        fail(f"--prefix: {err}")
    problem = tls_ca_problem(opts.tls_ca)
    if problem is not None:
        fail(problem)
    password = read_password(opts.password_file)
    if opts.username is None and password is not None:
        fail(f"a password needs a user name (--username or {USERNAME_ENV})")
    if opts.username is not None and password is None:
        fail(f"no password: give --password-file or set {PASSWORD_ENV}")
    return password


def abort_account(opts: ServeOptions, password: str | None):  # -> AbortAccount | None
    """The abort connection's account: ``--abort-username`` (default: the service's
    user name with ``-abort``; none on a broker without accounts), its password from
    ``--abort-password-file`` or $ORBITRIG_MQTT_ABORT_PASSWORD, else the service's."""
    from orbitrig.service.settings import ABORT_ACCOUNT_SUFFIX, AbortAccount

    if not opts.abort_connection:
        if opts.abort_username is not None or opts.abort_password_file is not None:
            fail("--no-abort-connection: no --abort-username or --abort-password-file with it")
        return None
    username = opts.abort_username
    if username is None and opts.username is not None:
        username = opts.username + ABORT_ACCOUNT_SUFFIX
    own = read_password(opts.abort_password_file, option="--abort-password-file", env=ABORT_PASSWORD_ENV)
    if username is None and own is not None:
        fail("an abort password needs an account (--abort-username, or --username)")
    if username is not None and (own or password) is None:
        fail(f"no password for the abort account {username!r}: give --abort-password-file or set {ABORT_PASSWORD_ENV}")
    return AbortAccount(username, own or password)

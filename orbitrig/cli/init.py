"""`orbitrig init DIR`: write an editable lab configuration from the shipped defaults.

Exit status 0 on success, 2 when DIR already holds a configuration (without --force) or
cannot be written.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer


def register(app: typer.Typer) -> None:
    @app.command("init")
    def init_cmd(
        directory: Annotated[
            Path, typer.Argument(metavar="DIR", help="The lab configuration folder (made if missing).")
        ],
        broker_dir: Annotated[
            Optional[Path],
            typer.Option(
                "--broker-dir",
                help="Folder the broker reads its password file, ACL and TLS files from, written into "
                "mosquitto.conf (default DIR/mosquitto).",
            ),
        ] = None,
        force: Annotated[bool, typer.Option("--force", help="Overwrite an existing configuration in DIR.")] = False,
        rig_id: Annotated[
            Optional[str],
            typer.Option(
                "--rig-id",
                help="This rig's identifier, written into rig.toml: recorded in every run and calibration "
                "record, which are checked against it (default: the shipped example's).",
            ),
        ] = None,
    ) -> None:
        """Write rig.toml, matrices/, designs/, calibration/ and mosquitto/ into DIR.

        Later commands use DIR when run in it, with ORBITRIG_HOME=DIR, or with --config DIR/rig.toml.
        """
        from orbitrig.cli.failure import fail
        from orbitrig.cli.terminal import printing
        from orbitrig.config import HOME_ENV, SHIPPED_RIG_ID, write_lab
        from orbitrig.errors import ConfigError

        try:
            files = write_lab(directory, broker_dir, force, rig_id)
        except ConfigError as err:
            fail(str(err), 2)
        with printing():  # `| head`: the reader has what it wanted, the exit status stays
            for path in files:
                typer.echo(str(path))
            typer.echo(
                f"lab configuration in {directory}: edit rig.toml (its [transports], channels, [bearing] and "
                "[drives] are the paper's rig's until you do; `orbitrig calibrate` steps then measure its "
                f"calibration); commands use it when run in this folder, with {HOME_ENV}={directory.resolve()}, "
                f"or with --config {directory / 'rig.toml'}"
            )
        if rig_id is None:
            typer.echo(
                f"note: rig_id in rig.toml is the shipped example's ({SHIPPED_RIG_ID}): set this rig's own "
                "(or give --rig-id); runs record it and calibration records of another rig are refused by it",
                err=True,
            )

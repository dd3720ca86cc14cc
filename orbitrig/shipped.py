"""Where the configuration shipped with orbitrig is: ``orbitrig/data`` in an installed wheel,
``config/`` of the source tree when run from it (or installed editable).

Nothing but pathlib: the CLI's every ``--help`` reads the shipped matrices' names from here
without loading orbitrig.config (which loads numpy); orbitrig.config.home takes it from here."""

from __future__ import annotations

from pathlib import Path

#: the rig configuration file of a configuration folder
RIG_FILE = "rig.toml"
#: the orbitrig package's folder
PACKAGE = Path(__file__).resolve().parent


def shipped_config(package: Path = PACKAGE) -> Path:
    """The default configuration folder of the orbitrig `package` folder: its ``data`` when it
    holds a rig.toml (a wheel), else ``config/`` beside the package (the source tree)."""
    data = package / "data"
    return data if (data / RIG_FILE).is_file() else package.parent / "config"

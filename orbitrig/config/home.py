"""Where the configuration is: the lab's folder, or the defaults shipped with orbitrig.

A lab configuration is a folder (``orbitrig init DIR`` writes one) holding ``rig.toml``,
``matrices/``, ``designs/``, ``calibration/`` and ``mosquitto/``. A command finds it in
this order, the first that applies wins:

1. ``--config FILE``: the folder of FILE;
2. the environment variable ``ORBITRIG_HOME`` (a lab folder);
3. the current directory, when it holds a ``rig.toml``;
4. the defaults shipped with the package (``config/`` of the source tree, copied into the
   wheel as ``orbitrig/data``).

A matrix or design given by NAME is looked up in the lab's ``matrices/`` (``designs/``),
then in the shipped ones.
"""

from __future__ import annotations

import os
from pathlib import Path

from orbitrig.shipped import RIG_FILE, shipped_config

HOME_ENV = "ORBITRIG_HOME"
MATRICES = "matrices"
DESIGNS = "designs"


def config_home(rig_path: Path | str | None = None) -> Path:
    """The lab configuration folder by the order of the module docstring."""
    if rig_path is not None:
        return Path(rig_path).parent
    env = os.environ.get(HOME_ENV)
    if env:
        return Path(env)
    if (Path.cwd() / RIG_FILE).is_file():
        return Path.cwd()
    return shipped_config()


def writable_home(rig_path: Path | str | None = None) -> Path:
    """The lab folder a command writes into (calibration records, rig.toml's active record,
    designs): ``config_home``, or a ConfigError when that is only the shipped defaults (no
    --config, $ORBITRIG_HOME or rig.toml in the current directory), which are never written
    to: in an installed wheel they are the package's own files, shared by every later
    `orbitrig init`."""
    from orbitrig.errors import ConfigError

    home = config_home(rig_path)
    if rig_path is None and home == shipped_config():
        raise ConfigError(
            str(home / RIG_FILE),
            [
                "belongs to the defaults shipped with orbitrig, which it never writes to: make a lab folder with "
                f"`orbitrig init DIR`, then set {HOME_ENV}=DIR, run in DIR, or give --config DIR/{RIG_FILE}"
            ],
        )
    return home


def search_folders(kind: str, rig_path: Path | str | None = None) -> list[Path]:
    """The folders a NAME of ``kind`` (matrices, designs) is looked up in, in order."""
    folders = [config_home(rig_path) / kind, shipped_config() / kind]
    return [f for i, f in enumerate(folders) if f not in folders[:i]]


def named_file(kind: str, name: str, rig_path: Path | str | None = None) -> Path:
    """NAME.toml in the first of ``search_folders`` holding it (else in the first folder)."""
    folders = search_folders(kind, rig_path)
    for folder in folders:
        if (folder / f"{name}.toml").is_file():
            return folder / f"{name}.toml"
    return folders[0] / f"{name}.toml"


def known_names(kind: str, rig_path: Path | str | None = None) -> list[str]:
    """Every NAME of ``kind`` the search folders hold."""
    return sorted({p.stem for f in search_folders(kind, rig_path) if f.is_dir() for p in f.glob("*.toml")})

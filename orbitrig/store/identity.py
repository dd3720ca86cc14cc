"""A run's identity: one id for the run, wherever it is read (MQTT, logs, catalog, exports).

A new run's id is taken in the folder that holds its directory (`claim_created`): one empty file
per id in its TAKEN folder, made new (O_EXCL), so that two runs of one rig started in the same
millisecond there (two processes) get two ids, the later one dated at the next free millisecond.
A run directory named by orbitrig (`orbitrig serve`'s) is taken the same way (`claim_dir`).
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import errno
import logging
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from orbitrig.store.errors import storage_error
from rigunits import utc_iso, utc_stamp

log = logging.getLogger(__name__)
#: the folder, beside the run directories, holding one empty file per run id taken there
TAKEN = ".run-ids"
_UNSAFE = re.compile(r"[^A-Za-z0-9._-]")
#: a folder of run directories that refuses new entries (the run directory itself may take them)
_UNWRITABLE = {errno.EACCES, errno.EPERM, errno.EROFS}


def run_identity(rig_id: str, created: str) -> str:
    """``<rig id>@<creation time>`` (ISO 8601 UTC, run.json's ``created``; rig id ``rig`` when
    none was recorded): the same after the directory is moved or copied and after a resume."""
    return f"{rig_id or 'rig'}@{created}"


def claim_created(runs: Path, rig_id: str, when: _dt.datetime | None = None) -> str:
    """The creation time (timestamp text, run.json's ``created``) of a new run of ``rig_id`` whose
    directory is in the folder ``runs``: ``when`` (None: now) to the millisecond, or the first
    millisecond after it whose id no run there has taken. The id is taken by creating
    ``runs/TAKEN/<rig id>@<utc_stamp>`` new (O_EXCL): whoever made it first has it, also another
    process at that instant. A folder ``runs`` that refuses it (no write permission, read-only,
    the run directory given inside it all the same): ``when`` untaken, a warning saying so.
    StorageError (StorageFullError on a full disk) naming the file when it cannot be made."""
    t = (when or _dt.datetime.now(_dt.timezone.utc)).astimezone(_dt.timezone.utc)
    t = t.replace(microsecond=t.microsecond // 1000 * 1000)
    folder = Path(runs) / TAKEN
    rig = _UNSAFE.sub("_", rig_id or "rig")
    path = folder
    try:
        folder.mkdir(exist_ok=True)
        while True:
            path = folder / f"{rig}@{utc_stamp(t)}"
            try:
                os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644))
            except FileExistsError:  # another run's
                t += _dt.timedelta(milliseconds=1)
                continue
            return utc_iso(t)
    except OSError as err:
        if err.errno not in _UNWRITABLE:
            raise storage_error(path, "take the run id", err) from err
        log.warning(
            "run id %s@%s not taken in %s (%s): not checked against other runs there",
            rig,
            utc_iso(t),
            folder,
            err.strerror,
        )
        return utc_iso(t)


def claim_dir(folder: Path, name: str) -> Path:
    """A new run directory ``folder/name``, or ``name-2``, ``name-3``, ... when that one exists:
    made new (mkdir, no exist_ok), so that whoever made it first has it, also another process at
    that instant. A folder that refuses it (permissions, a full disk): the name, not made (the
    run's creation says why)."""
    path, n = Path(folder) / name, 1
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        while True:
            try:
                path.mkdir()
            except FileExistsError:  # another run's (or a file's)
                n += 1
                path = Path(folder) / f"{name}-{n}"
                continue
            return path
    except OSError:
        return path


def header_identity(header: Mapping[str, Any]) -> str:
    """:func:`run_identity` of a run.json header (its provenance's rig_id and ``created``)."""
    prov = header.get("provenance")
    rig_id = str(prov.get("rig_id", "")) if isinstance(prov, Mapping) else ""
    return run_identity(rig_id, str(header.get("created", "")))


def header_software(header: Mapping[str, Any]) -> str:
    """The software that wrote a run, from its run.json header: ``software_version`` (orbitrig's
    version, then its libraries') with orbitrig's entry replaced by the provenance's, which names
    the code (``orbitrig 0.1.0 (source <digest>, git <describe>)``, orbitrig.run.provenance), so
    that run.json (RunStore.create writes this), run.h5 and every export say the same. A run
    without provenance, or whose header names the code already: as stored."""
    versions = str(header.get("software_version", ""))
    prov = header.get("provenance")
    code = str(prov.get("software_version", "")) if isinstance(prov, Mapping) else ""
    if not code or versions == code or versions.startswith(f"{code}, "):
        return versions
    first, sep, libraries = versions.partition(", ")
    if first.startswith("orbitrig "):
        return f"{code}{sep}{libraries}"
    return f"{code}, {versions}" if versions else code


def software_versions() -> str:
    """orbitrig's version, then its libraries' (run.json's ``software_version`` as a run starts)."""
    import importlib.metadata as md

    from orbitrig import __version__

    parts = [f"orbitrig {__version__}"]
    for pkg in ("numpy", "scipy", "h5py", "pymodbus", "python-can", "pydantic"):
        with contextlib.suppress(md.PackageNotFoundError):
            parts.append(f"{pkg} {md.version(pkg)}")
    return ", ".join(parts)

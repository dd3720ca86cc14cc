"""A run's identity: one id for the run, wherever it is read (MQTT, logs, catalog, exports)."""

from __future__ import annotations

import contextlib
from collections.abc import Mapping
from typing import Any


def run_identity(rig_id: str, created: str) -> str:
    """``<rig id>@<creation time>`` (ISO 8601 UTC, run.json's ``created``; rig id ``rig`` when
    none was recorded): the same after the directory is moved or copied and after a resume."""
    return f"{rig_id or 'rig'}@{created}"


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

"""Who made a run, with what, on which rig: the provenance every run records.

`Provenance.of_run` gathers it when a run starts: the operator (``--operator`` of `orbitrig
sweep`, or the MQTT / dashboard user who sent ``start``), the software version with its source
revision (`software_version`: the version number alone names no code), the rig id and
the sensors' serial numbers (rig.toml), the active calibration record (name and SHA-256 of its
text, and whether that text is as its step wrote it: `record_seal`; whether its measurements were
within rig.toml's calibration_valid_days at the start: `calibration_validity`), the SHA-256 of
rig.toml's and the matrix file's texts as read (`rig_sha256`, `matrix_sha256`: run.json stores the
matrix with the design it used appended, whose hash is not the file's), the host and the start time. Times are ISO 8601 UTC (rigunits.now_iso).
It goes into run.json (``provenance``) and run.h5's root attributes; the end time is the last
status line of the journal. Every command that changes the run (start, confirm, pause,
resume, stop, abort) is logged with who sent it and when (`command_line`, `RunStore.command`).
"""

from __future__ import annotations

from typing import Any
import functools
import hashlib
import importlib.util
import socket
import subprocess
from dataclasses import asdict, dataclass, field
from pathlib import Path

from orbitrig import __version__
from orbitrig.config import RigConfig, SealState, digest, seal_state, validity
from orbitrig.run.states import RunCommand
from rigunits import now_iso

#: who sent a command when nobody said (an MQTT client that gave no "by")
UNNAMED = "unnamed"
#: the distribution's packages (pyproject.toml's include patterns, which an installed wheel has not: the
#: same list, tests/test_architecture.py holds them equal): the code whose sources the revision digests
PACKAGES = ("orbitrig", "reduction", "daq", "drives", "sim", "rigerrors", "rigthreads", "rigunits")
GIT_TIMEOUT_S = 5.0


@dataclass(frozen=True)
class Provenance:
    operator: str
    software_version: str
    rig_id: str
    sensor_serials: dict[str, str] = field(default_factory=dict)
    calibration_record: str = ""
    calibration_record_sha256: str = ""
    host: str = ""
    started: str = ""
    calibration_record_seal: str = ""  # record_seal of its text ("" no record)
    calibration_validity: str = ""  # its parts' ages against calibration_valid_days at the start ("" no record)
    rig_sha256: str = ""  # SHA-256 (hex) of rig.toml's text as read ("" none)
    matrix_sha256: str = ""  # SHA-256 (hex) of the matrix file's text as read, before [design_used] ("" none)

    @classmethod
    def of_run(cls, rig: RigConfig, operator: str, matrix_text: str = "") -> "Provenance":
        """The provenance of a run starting now on ``rig``, started by ``operator``, measuring the
        matrix whose file's text as read is ``matrix_text``."""
        serials = {c.name: c.serial for c in rig.ordered_channels}
        return cls(
            operator=operator or UNNAMED,
            software_version=software_version(),
            rig_id=rig.identity,
            sensor_serials=serials,
            calibration_record=rig.calibration_record or "",
            calibration_record_sha256=digest(rig.record_text) if rig.record_text else "",
            host=socket.gethostname(),
            started=now_iso(),
            calibration_record_seal=record_seal(rig.record_text) if rig.record_text else "",
            calibration_validity=validity(rig),
            rig_sha256=digest(rig.text) if rig.text else "",
            matrix_sha256=digest(matrix_text) if matrix_text else "",
        )

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def summary(self) -> str:
        """One line for run.log."""
        seal = f", {self.calibration_record_seal}" if self.calibration_record_seal else ""
        cal = (
            f"{self.calibration_record} (sha256 {self.calibration_record_sha256[:12]}{seal})"
            if self.calibration_record
            else "none"
        )
        return (
            f"provenance: operator {self.operator}, {self.software_version}, rig {self.rig_id}, "
            f"host {self.host}, calibration record {cal}"
        )


def record_seal(text: str) -> str:
    """Whether a calibration record's ``text`` is as its step wrote it: "as written" (its SHA-256
    line matches its text), "not verifiable" (it holds none: written before records did, or typed
    in); a run never starts with one edited after (orbitrig.config.check_seal refuses it)."""
    state = seal_state(text)[0]
    return "as written" if state is SealState.VERIFIED else str(state)


def command_line(command: RunCommand, by: str | None, detail: str = "") -> str:
    """The run.log text of a command: 'command pause by alice' (+ detail)."""
    return f"command {command} by {by or UNNAMED}" + (f" ({detail})" if detail else "")


def software_version() -> str:
    """'orbitrig VERSION (source DIGEST[, git DESCRIBE])': `source_digest` and `git_describe`."""
    git = git_describe()
    return f"orbitrig {__version__} (source {source_digest()}" + (f", git {git})" if git else ")")


@functools.cache
def source_digest() -> str:
    """First 12 hex digits of the SHA-256 of the distribution's Python sources (PACKAGES: each
    ``.py`` file's path inside its package and its bytes, in path order): the same for the same
    code, in a git checkout or an installed wheel. Computed once per process."""
    h = hashlib.sha256()
    for name in PACKAGES:
        spec = importlib.util.find_spec(name)
        for folder in (spec.submodule_search_locations or []) if spec else []:
            root = Path(folder)
            for path in sorted(root.rglob("*.py")):
                h.update(f"{name}/{path.relative_to(root).as_posix()}\0".encode())
                h.update(path.read_bytes())
    return h.hexdigest()[:12]


@functools.cache
def git_describe() -> str:
    """``git describe --always --dirty`` of the checkout the package runs from ('' when it runs
    from no checkout, git is missing or does not answer within GIT_TIMEOUT_S)."""
    root = Path(__file__).resolve().parents[2]
    if not (root / ".git").exists():
        return ""
    try:
        out = subprocess.run(
            ["git", "-C", str(root), "describe", "--always", "--dirty"],
            capture_output=True,
            text=True,
            timeout=GIT_TIMEOUT_S,
        )
    except (OSError, subprocess.SubprocessError):
        return ""
    return out.stdout.strip() if out.returncode == 0 else ""

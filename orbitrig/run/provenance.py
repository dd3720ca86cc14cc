"""Who made a run, with what, on which rig: the provenance every run records.

`Provenance.of_run` gathers it when a run starts: the operator (``--operator`` of `orbitrig
sweep`, or the MQTT / dashboard user who sent ``start``), the software version, the rig id and
the sensors' serial numbers (rig.toml), the active calibration record (name and SHA-256 of its
text), the host and the start time. Times are ISO 8601 UTC (rigunits.now_iso).
It goes into run.json (``provenance``) and run.h5's root attributes; the end time is the last
status line of the journal. Every command that changes the run (start, confirm, pause,
resume, stop, abort) is logged with who sent it and when (`command_line`, `RunStore.command`).
"""

from __future__ import annotations

from typing import Any
import socket
from dataclasses import asdict, dataclass, field
from enum import StrEnum

from orbitrig import __version__
from orbitrig.config import RigConfig, digest
from rigunits import now_iso

#: who sent a command when nobody said (an MQTT client that gave no "by")
UNNAMED = "unnamed"


class RunCommand(StrEnum):
    """The commands that change a run."""

    START = "start"
    CONFIRM = "confirm"
    PAUSE = "pause"
    RESUME = "resume"
    STOP = "stop"
    ABORT = "abort"


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

    @classmethod
    def of_run(cls, rig: RigConfig, operator: str) -> "Provenance":
        """The provenance of a run starting now on ``rig``, started by ``operator``."""
        serials = {c.name: c.serial for c in rig.ordered_channels}
        return cls(
            operator=operator or UNNAMED,
            software_version=f"orbitrig {__version__}",
            rig_id=rig.identity,
            sensor_serials=serials,
            calibration_record=rig.calibration_record or "",
            calibration_record_sha256=digest(rig.record_text) if rig.record_text else "",
            host=socket.gethostname(),
            started=now_iso(),
        )

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def summary(self) -> str:
        """One line for run.log."""
        cal = (
            f"{self.calibration_record} (sha256 {self.calibration_record_sha256[:12]})"
            if self.calibration_record
            else "none"
        )
        return (
            f"provenance: operator {self.operator}, {self.software_version}, rig {self.rig_id}, "
            f"host {self.host}, calibration record {cal}"
        )


def command_line(command: RunCommand, by: str | None, detail: str = "") -> str:
    """The run.log text of a command: 'command pause by alice' (+ detail)."""
    return f"command {command} by {by or UNNAMED}" + (f" ({detail})" if detail else "")

"""The run's append-only event log (``journal.jsonl``): one JSON object per line.

Kinds (key ``k``): ``status`` (status, message, at), ``point`` (point, action: begin |
complete | set_aside, detail), ``block`` (point, tag, bytes), ``event`` (t, state,
message), ``can`` (row), ``drives`` (row), ``command`` (command, by, at, detail: a command
that changed the run and who sent it), ``continued`` (at, detail: the journal was deleted while
the run went on, or missing when it was resumed, and this one continues it; orbitrig.store.journal_file). ``t`` is seconds since the run started;
``at`` an ISO-8601 UTC time. A torn last line (a kill mid-append) is ignored; the run's
status is the last ``status`` line that made it to disk.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from orbitrig.store.durable import read_lines
from orbitrig.store.errors import RunDirError
from orbitrig.store.status import RunStatus
from rigunits import ONE, now_iso

CAN_FIELDS = (
    "t_recess",
    "t_groove",
    "t_supply",
    "flow",
    "p_supply",
    "p_recess1",
    "p_recess2",
    "p_recess3",
    "p_recess4",
    "beta",
    "sensor_fault",
    "pump_off",
    "node_lost",
)
#: unit of each field of /logs/can, t first (pint parses each; a flag is a number, 0 or 1)
CAN_UNITS = ("s", "K", "K", "K", "m^3/s", "Pa", "Pa", "Pa", "Pa", "Pa", ONE, ONE, ONE, ONE)
DRIVE_FIELDS = (
    "spin_ref",
    "spin_act",
    "orbit_ref",
    "orbit_act",
    "spin_status",
    "orbit_status",
    "spin_fault",
    "orbit_fault",
    "spin_torque",
    "orbit_torque",
)
#: unit of each field of /logs/drives, t first (status words and fault codes are numbers; torques
#: a fraction of the nominal torque)
DRIVE_UNITS = ("s", "rad/s", "rad/s", "rad/s", "rad/s", ONE, ONE, ONE, ONE, ONE, ONE)
#: what a dimensionless log field is, for the log's description
FIELD_MEANING = {
    "beta": "recess-to-supply pressure ratio",
    "sensor_fault": "flag",
    "pump_off": "flag",
    "node_lost": "flag",
    "spin_status": "status word",
    "orbit_status": "status word",
    "spin_fault": "fault code",
    "orbit_fault": "fault code",
    "spin_torque": "fraction of nominal",
    "orbit_torque": "fraction of nominal",
}
#: a state change of the run: (t s since the start, state, message)
EventRow = tuple[float, str, str]
CAN_DTYPE = np.dtype([("t", "f8")] + [(f, "f8") for f in CAN_FIELDS])
DRIVE_DTYPE = np.dtype([("t", "f8")] + [(f, "f8") for f in DRIVE_FIELDS])


def line(kind: str, **fields: object) -> str:
    return json.dumps({"k": kind, **fields}, separators=(",", ":"))


def status_line(status: RunStatus, message: str) -> str:
    return line("status", status=str(status), message=message, at=now_iso())


def log_lines(
    events: Sequence[Sequence[float | str]],
    can: Sequence[Sequence[float | str]],
    drives: Sequence[Sequence[float | str]],
) -> list[str]:
    """Journal lines of the rows gathered by a LogBuffer (events: t, state, message; CAN and
    drive rows: t and numbers)."""
    out = [line("event", t=float(t), state=str(s), message=str(m)) for t, s, m in events]
    out += [line("can", row=[_num(v) for v in r]) for r in can]
    out += [line("drives", row=[_num(v) for v in r]) for r in drives]
    return out


def _num(v: float | str) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


@dataclass
class Journal:
    """What the journal says, as far as it made it to disk."""

    status: RunStatus = RunStatus.RUNNING
    status_message: str = ""
    status_at: str = ""  # ISO 8601 UTC time of the last status line (the run's end once final)
    commands: list[tuple[str, str, str, str]] = field(default_factory=list)  # (at, command, by, detail)
    events: list[EventRow] = field(default_factory=list)  # (t, state, message)
    can: list[tuple[float, ...]] = field(default_factory=list)  # rows of CAN_DTYPE
    drives: list[tuple[float, ...]] = field(default_factory=list)  # rows of DRIVE_DTYPE
    points: list[dict[str, Any]] = field(default_factory=list)  # the point and block records, in order
    torn: int = 0  # lines ignored (torn tail or unreadable)
    continued: list[str] = field(default_factory=list)  # the journal continues one lost: what was lost, when


def missing(path: Path) -> str:
    """The warning that the journal `path` is missing ("" when it is there): the run's recorded status
    and its logs are lost, and a reader finds it 'running' with empty logs."""
    if path.exists():  # whatever it is (a reader of it says what it cannot read)
        return ""
    return (
        f"{path} is missing: the run's recorded status, commands, events and CAN and drive logs are lost "
        "(it reads as running, with empty logs)"
    )


def read_journal(path: Path) -> Journal:
    """What the journal at ``path`` says; lines that do not parse or lack a field count as torn.
    RunDirError naming the file and line for a line whose number is beyond a float (1e400 written
    out as an integer): a file damaged, not a write cut short. StorageError when it cannot be read."""
    records, torn = read_lines(path)
    j = Journal(torn=torn)
    for number, r in records:
        try:
            k = r.get("k")
            if k == "status":
                j.status, j.status_message = RunStatus.read(r["status"]), str(r.get("message", ""))
                j.status_at = str(r.get("at", ""))
            elif k == "command":
                j.commands.append((str(r["at"]), str(r["command"]), str(r["by"]), str(r.get("detail", ""))))
            elif k == "event":
                j.events.append((float(r["t"]), str(r["state"]), str(r["message"])))
            elif k in ("can", "drives"):
                n = 1 + len(CAN_FIELDS if k == "can" else DRIVE_FIELDS)  # t and the fields
                row = [math.nan if v is None else float(v) for v in r["row"]][:n]
                (j.can if k == "can" else j.drives).append(tuple(row + [math.nan] * (n - len(row))))
            elif k in ("point", "block"):
                j.points.append(r)
            elif k == "continued":
                j.continued.append(str(r["detail"]))
        except (KeyError, TypeError, ValueError):
            j.torn += 1
        except OverflowError as err:
            raise RunDirError(path, f"line {number}: {err} (the file is damaged)") from None
    return j

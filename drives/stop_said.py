"""A stop in the messages' words: its kind from the word sent (`stop_kind`), the drives that took it
(`took_it`), and what those did when another missed it (`missed_stop`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from drives.errors import DriveError

if TYPE_CHECKING:
    from drives.drive import Drive
    from drives.read_first import ReadFirst


def stop_kind(emergency: bool, read: ReadFirst | None = None) -> str:
    """'emergency stop (OFF3)' or 'ramp stop (OFF1)': a stop's words in a message; `emergency`: the
    word sent (`StopSender.emergency`), never the word asked; `read`: what was read first over a
    bare link ('emergency stop (OFF3, as spin (id 1) read turning in its emergency ramp)',
    'ramp stop (OFF1, orbit (id 2) not read)')."""
    said = read.said() if read is not None else ""
    word = "OFF3" if emergency else "OFF1"
    return ("emergency stop" if emergency else "ramp stop") + (f" ({word}, {said})" if said else f" ({word})")


def took_it(drives: Sequence[Drive], errors: Sequence[DriveError]) -> list[str]:
    """'spin (id 1)', ... of the `drives` whose stop word went out: those no error of `send_stop`
    names."""
    missed = {err.drive for err in errors}
    return [f"{d.name} (id {d.device_id})" for d in drives if d.device_id not in missed]


def missed_stop(
    missed: DriveError, drives: Sequence[Drive], took: frozenset[int], waited: DriveError | None
) -> DriveError:
    """`missed` (a drive's stop delivery error: `RigDrives.stop` raises it), its message ended with
    what the drives of device ids `took` did after taking that stop: at standstill (`waited` None),
    or the error of the wait for it (a trip, not at zero speed in time)."""
    names = " and ".join(f"{d.name} drive (id {d.device_id})" for d in drives if d.device_id in took)
    did = "at standstill" if waited is None else f"not confirmed at standstill: {waited}"
    missed.args = (f"{missed.args[0]}; {names}, which took the stop, {did}",)
    return missed

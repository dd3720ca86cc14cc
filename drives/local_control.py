"""A drive in local control: the operator at its keypad has it, and it refuses the network's
control words.

The contract says only that CW bit REMOTE must be 1 for a drive to accept commands from the
network and that SW bit REMOTE means network control accepted; not how a drive answers a control
word while its keypad has it. Ours (docs/protocols/drive-modbus.md, "Local control"): it refuses
it with a Modbus exception and changes nothing (the simulator answers 03). A control word refused
with an exception by a drive that then reads SW REMOTE = 0 is said as local control, whatever the
code: `DriveInLocalControl`, naming the drive and the word.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from drives import registers as R
from drives.errors import DriveError, DriveExceptionResponse

if TYPE_CHECKING:
    from drives.drive import Drive

#: the control words orbitrig writes, as a message names them
WORD_NAMES: dict[int, str] = {
    R.CW_READY: "ready word (0x0476)",
    R.CW_RUN: "run word (0x047F)",
    R.CW_RAMP_STOP: "ramp stop (OFF1, 0x047E)",
    R.CW_EMERGENCY_STOP: "emergency stop (OFF3, 0x047B)",
    R.CW_RESET: "fault reset word (0x04F6)",
}

#: what a message says of a drive in local control
LOCAL = "in local control (status word REMOTE = 0): the operator at its keypad has it"


class DriveInLocalControl(DriveExceptionResponse):
    """A drive refused a control word (an exception answer) and reads SW REMOTE = 0: in local
    control, the operator at its keypad has it. `word`: the control word refused."""

    def __init__(self, refused: DriveExceptionResponse, word: int):
        what = WORD_NAMES.get(word, f"control word {word:#06x}")
        super().__init__(
            f"did not take the {what}: {LOCAL}; the word refused",
            exception_code=refused.exception_code,
            drive=refused.drive,
            register=R.CW,
            drive_name=refused.drive_name,
        )
        self.word = word


async def said_local(d: Drive, err: DriveError, word: int, *, stop: bool = False) -> DriveError:
    """`err` of control word `word` to `d`, as DriveInLocalControl when it is an exception answer
    and `d` then reads SW REMOTE = 0 (one read, no retries); else `err` (also when the read fails,
    whatever it raised: a stop's errors are never lost to it). `stop`: a stop's read, urgent (a
    start's waits for a stop under way, never goes between its words)."""
    if not isinstance(err, DriveExceptionResponse) or isinstance(err, DriveInLocalControl) or err.register != R.CW:
        return err
    try:
        (sw,) = await d.link.read(d.device_id, R.SW, 1, retries=0, stop=stop)
    except Exception:  # noqa: BLE001 - whatever the read raised, the word's own error is said
        return err
    if sw & R.SWBit.REMOTE:
        return err
    local = DriveInLocalControl(err, word)
    local.__cause__ = err
    return local


async def said_local_all(
    drives: Sequence[Drive], errors: list[DriveError], word: int, superseded: Callable[[], bool]
) -> list[DriveError]:
    """`errors` of a stop's control word `word` to `drives`, each said as local control where it is
    (`said_local`); read once its words have all gone out, none once `superseded()`: a stop asked
    since goes out without waiting for a read (it reads, and says the word it sent: this stop's
    refused word may have been another than its `word` now, OFF1 before the takeover)."""
    by_id = {d.device_id: d for d in drives}
    return [
        await said_local(by_id[e.drive], e, word, stop=True) if e.drive in by_id and not superseded() else e
        for e in errors
    ]

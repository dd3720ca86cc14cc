"""Has a calibration record been edited since its step wrote it (docs/calibration.md): a step
writes into the record the SHA-256 of its own text (the line ``sha256 = "..."`` left out, which
holds it); ``seal_state`` recomputes it, ``check_seal`` refuses an active record whose text no
longer matches (ConfigError naming the file and the line) and warns (UnverifiableRecordWarning) of
a measured one written before records held it. It catches a hand edit, not a forgery: whoever
edits the file on purpose can write the new digest too.
"""

from __future__ import annotations

import hashlib
import re
import warnings
from enum import StrEnum
from pathlib import Path

from orbitrig.config.messages import key_line
from orbitrig.config.records import CalibrationRecord
from orbitrig.config.record_setup import MEASURED_STEPS
from orbitrig.errors import ConfigError

KEY = "sha256"
#: the top-level line that holds the record's digest (the first ``[`` table ends the top level)
SEAL_LINE = re.compile(rf'^{KEY}[ \t]*=[ \t]*"([0-9a-f]{{64}})"[^\n]*(?:\n|$)', re.MULTILINE)
_TABLE = re.compile(r"^[ \t]*\[", re.MULTILINE)
PLACEHOLDER = "0" * 64
NOTE = "SHA-256 of this record's text without this line: an edit is refused"


class SealState(StrEnum):
    """What a record's digest says of its text."""

    VERIFIED = "verified"  # the text is as its step wrote it
    EDITED = "edited after it was written"  # the digest differs from the text's
    UNSEALED = "not verifiable"  # no digest: written before records held one, or typed in


class UnverifiableRecordWarning(UserWarning):
    """An active measured record from before records held their own SHA-256."""


def _seal_match(text: str) -> re.Match[str] | None:
    """The digest's line, when it is a top-level key (above the first table)."""
    m = SEAL_LINE.search(text)
    table = _TABLE.search(text)
    return m if m is not None and (table is None or m.start() < table.start()) else None


def digest(text: str) -> str:
    """SHA-256 (hex) of a text as a run records it: a record's whole file (its ``sha256`` line
    included), a design's (orbitrig.config.designs)."""
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def text_digest(text: str) -> str:
    """SHA-256 (hex) of a record's ``text`` without its digest's line: the one it holds."""
    m = _seal_match(text)
    return digest(text if m is None else text[: m.start()] + text[m.end() :])


def without_seal(text: str) -> str:
    """``text`` with its digest's line left blank (the record's keys, on their lines)."""
    m = _seal_match(text)
    return text if m is None else text[: m.start()] + "\n" * m.group(0).endswith("\n") + text[m.end() :]


def seal(text: str) -> str:
    """``text`` (rendered with ``sha256 = PLACEHOLDER``) with its digest in place of the placeholder."""
    m = _seal_match(text)
    if m is None or m.group(1) != PLACEHOLDER:
        raise ValueError("a record is sealed from its text rendered with the placeholder digest")
    return text[: m.start(1)] + text_digest(text) + text[m.end(1) :]


def seal_state(text: str) -> tuple[SealState, str, str]:
    """(state, the digest the record holds ("" none), its text's digest) of a record's ``text``."""
    m = _seal_match(text)
    now = text_digest(text)
    if m is None:
        return SealState.UNSEALED, "", now
    return (SealState.VERIFIED if m.group(1) == now else SealState.EDITED), m.group(1), now


def check_seal(record: CalibrationRecord, record_text: str, path: Path) -> None:
    """A ConfigError naming ``path`` and its digest's line when the active record's text is not
    the text its step wrote; an UnverifiableRecordWarning for a measured record without a digest
    (an ``initial`` record without one is typed in, not written by a step: not warned of)."""
    state, held, now = seal_state(record_text)
    if state is SealState.VERIFIED:
        return
    if state is SealState.UNSEALED:
        if record.step in MEASURED_STEPS:
            step_at = key_line(record_text, ("step",)) or 1
            message = (
                f"this {record.step} record is not verifiable: it predates the SHA-256 records hold of their "
                "own text, so an edit since its step wrote it cannot be detected (calibrating again writes one)"
            )
            warnings.warn_explicit(message, UnverifiableRecordWarning, str(path), step_at)
        return
    at = key_line(record_text, (KEY,))
    typed = (
        "; an initial record is typed in: to type in your own values, save them as a record of a new "
        f"name without its '{KEY}' line and name that in rig.toml's calibration_record"
        if record.step not in MEASURED_STEPS
        else ""
    )
    raise ConfigError(
        str(path),
        [
            f"{f'line {at}: ' if at else ''}key '{KEY}': this {record.step} record was edited after it was "
            f"written: its text's SHA-256 is {now[:12]}..., the record says {held[:12]}... (the step's "
            "text). Its corrections are no longer the ones measured: put the file back as written (a run "
            "made with it holds its text: run.json calibration_record_text), make another record active "
            "(its name as rig.toml's calibration_record; `orbitrig calibrate list` lists them), "
            f"or calibrate again{typed}"
        ],
    )


def seal_mark(text: str) -> str:
    """What `calibrate list` appends to a record's line: "" for one as written, else its state."""
    state = seal_state(text)[0]
    return "" if state is SealState.VERIFIED else f"  {state.upper() if state is SealState.EDITED else state}"


def seal_note(text: str) -> str:
    """`calibrate show`'s line on a record's own digest: as written, edited (both digests), not verifiable."""
    state, held, now = seal_state(text)
    if state is SealState.EDITED:
        return f"# EDITED after it was written: its sha256 line says {held}, its text's is {now}"
    return "# as written (its sha256 line matches its text)" if held else "# not verifiable (no sha256 line)"

"""How old the active calibration record's measurements are (docs/calibration.md): a record is
complete, so its gain matrices, runout, lags and probe gains may come from older steps; each part's
date is that of the last record of its step among the records it started from (``previous``, in
the records' folder). ``age_lines`` says them (the dry run); ``age_warning`` names those older than
rig.toml's ``calibration_valid_days`` (the plan's warnings: the dry run, the sweep's start, run.log);
``validity`` says both in one line for a run's provenance (``calibration_validity``).
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass
from typing import TYPE_CHECKING

from orbitrig.config.messages import key_line
from orbitrig.config.records import CalibrationRecord, RecordStep
from orbitrig.errors import ConfigError
from rigunits import DAY

if TYPE_CHECKING:
    from orbitrig.config.rig import RigConfig

#: the longest chain of ``previous`` records followed (a loop or a long history ends there)
MAX_CHAIN = 1000


@dataclass(frozen=True)
class PartAge:
    """One measured part of the active record: its step, the record that measured it, when, how many
    days before ``now``; ``traced`` False: the record of its step is not reached (the chain breaks at
    ``missing``, a record not in the folder), ``record`` and ``date`` are the oldest record reached,
    so the part was measured before that date: at least that old."""

    step: RecordStep
    record: str
    date: str
    days: float
    traced: bool
    missing: str = ""  # untraced: the record the chain breaks at ("": the chain ends, no record of the step in it)
    why: str = ""  # why it breaks there: not in the folder, does not read, a loop, the longest chain


def measured_steps(record: CalibrationRecord) -> list[RecordStep]:
    """The steps whose measurements ``record`` holds, in the steps' order."""
    held = {
        RecordStep.LOADS: bool(record.loads),
        RecordStep.RUNOUT: record.runout is not None,
        RecordStep.DELAY: bool(record.delay),
        RecordStep.PROBES: bool(record.probes),
    }
    return [step for step, has in held.items() if has]


def _chain(rig: RigConfig) -> tuple[list[tuple[str, CalibrationRecord]], str, str]:
    """(the active record and the records it started from, newest first, as far as the folder has
    them; the name the chain breaks at, "" when it ends at a record started from none; why it
    breaks there)."""
    from orbitrig.config.active_record import record_folder
    from orbitrig.config.record_files import read_record

    folder = record_folder(rig.file)
    chain = [(rig.calibration_record or "", rig.record)]
    name = rig.record.previous
    while name:
        if name in {n for n, _ in chain}:
            return chain, name, "reached before (the records' previous make a loop)"
        if len(chain) >= MAX_CHAIN:
            return chain, name, f"not followed past {MAX_CHAIN} records"
        try:
            record, _ = read_record(folder, name)
        except ConfigError as err:
            gone = not (folder / f"{name}.toml").is_file()
            return chain, name, "not in the records' folder" if gone else f"which does not read ({err})"
        chain.append((name, record))
        name = record.previous
    return chain, "", ""


def part_ages(rig: RigConfig, now: _dt.datetime | None = None) -> list[PartAge]:
    """The age of each measured part of ``rig``'s active record ([] without one, or an initial one)."""
    if rig.record is None:
        return []
    now = now or _dt.datetime.now(_dt.UTC)
    chain, missing, why = _chain(rig)
    out = []
    for step in measured_steps(rig.record):
        hit = next(((n, r) for n, r in chain if r.step is step), None)
        name, record = hit if hit is not None else chain[-1]
        days = (now - _dt.datetime.fromisoformat(record.date)).total_seconds() / DAY
        broken = ("", "") if hit is not None else (missing, why)
        out.append(PartAge(step, name, record.date, days, hit is not None, *broken))
    return out


def _age(part: PartAge) -> str:
    """'loads 12 days old (2026-11-26, record NAME)'; an untraced part says what is known: measured
    before the oldest record reached, its own record not found."""
    if part.traced:
        return f"{part.step} {part.days:.0f} days old ({part.date[:10]}, record {part.record})"
    where = (
        f"the records it started from break at {part.missing}, {part.why}"
        if part.missing
        else f"the records it started from end there, none of them a {part.step} record"
    )
    return (
        f"{part.step} measured before {part.date[:10]}, at least {part.days:.0f} days old (its record not "
        f"found: the oldest record reached is {part.record}; {where})"
    )


def age_lines(rig: RigConfig, now: _dt.datetime | None = None) -> list[str]:
    """The dry run's line on the active record's age: each measured part's, or what it is."""
    if rig.record is None:
        return ["calibration: no calibration record (rig.toml names none)"]
    parts = part_ages(rig, now)
    limit = rig.calibration_valid_days
    valid = f"; valid {limit:g} days (calibration_valid_days)" if limit is not None else ""
    if not parts:
        return [f"calibration: record {rig.calibration_record} ({rig.record.step}): nothing measured yet{valid}"]
    return [f"calibration: record {rig.calibration_record}: " + ", ".join(_age(p) for p in parts) + valid]


def age_warning(rig: RigConfig, now: _dt.datetime | None = None) -> str | None:
    """'line N: key 'calibration_valid_days': ...' naming each measured part of the active record
    older than rig.toml's calibration_valid_days, and each whose own record is not found and so
    cannot be shown within it (at least N days old, N within), and the steps to run again; None when
    there are none, or no limit is set. A warning, not a refusal: the run goes on with the record."""
    limit = rig.calibration_valid_days
    if limit is None:
        return None
    parts = part_ages(rig, now)
    old = [p for p in parts if p.days > limit]
    unknown = [p for p in parts if not p.traced and p.days <= limit]
    if not old and not unknown:
        return None
    at = key_line(rig.text, ("calibration_valid_days",))
    said = [f"{', '.join(_age(p) for p in old)}: older than calibration_valid_days = {limit:g}"] if old else []
    if unknown:
        said.append(f"{', '.join(_age(p) for p in unknown)}: not shown to be within calibration_valid_days = {limit:g}")
    redo = " ".join(f"`orbitrig calibrate {s}`" for s in RecordStep if s in {p.step for p in old + unknown})
    return (
        f"{f'line {at}: ' if at else ''}key 'calibration_valid_days': the active calibration record "
        f"{rig.calibration_record} holds {'; and '.join(said)}; the run goes on, corrected by that calibration; "
        f"calibrate again ({redo})"
    )


def validity(rig: RigConfig, now: _dt.datetime | None = None) -> str:
    """The active record's validity as a run's provenance keeps it (``calibration_validity``): "expired:
    ..." when a measured part is older than rig.toml's calibration_valid_days or cannot be shown within
    it (age_warning), "valid: ..." within it, "no limit: ..." without it, then each part's age
    ("loads 12 days old (2026-11-26, record NAME)"; an initial record: "nothing measured yet"); "" without
    a record."""
    if rig.record is None:
        return ""
    ages = ", ".join(_age(p) for p in part_ages(rig, now)) or f"nothing measured yet ({rig.record.step} record)"
    limit = rig.calibration_valid_days
    if limit is None:
        return f"no limit: calibration_valid_days not set; {ages}"
    state = "expired: past" if age_warning(rig, now) else "valid: within"
    return f"{state} calibration_valid_days = {limit:g} at the run's start; {ages}"

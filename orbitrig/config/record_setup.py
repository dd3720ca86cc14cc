"""Is a calibration record the rig's, measured with its channel setup (docs/calibration.md): a
measured record names the rig's id and every channel's serial and gain it was measured with;
``check_setup`` refuses it (ConfigError naming each changed channel) on another setup, and warns
(UncheckedRecordWarning, at the record's file and line) of an older one without a setup, and
(UncorrectedProbeLagWarning) of one whose probes' lags were recorded before the sweep took them out.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, cast

from orbitrig.config.messages import key_line
from orbitrig.config.records import CalibrationRecord, ChannelName, RecordStep
from orbitrig.errors import ConfigError
from rigunits import MICROSECOND

if TYPE_CHECKING:
    from orbitrig.config.rig import RigConfig

PROBE_CHANNELS = ("x_a", "y_a", "x_b", "y_b")

#: the steps that measure on a rig: their record's ``rig`` must name the rig that uses it
MEASURED_STEPS = frozenset({RecordStep.LOADS, RecordStep.RUNOUT, RecordStep.DELAY, RecordStep.PROBES})


def made_elsewhere(record: CalibrationRecord, name: str, rig_id: str) -> bool:
    """Whether ``record`` was measured on another rig than the one called ``name`` with id
    ``rig_id``: a record with its channel setup (written since records carry it) names the rig's
    id, ``rig_id or name``; an older one the rig's name or id. Not checked: a record that names
    no rig (``rig`` is optional), and an initial record (typed in from data sheets, not measured;
    the shipped one names the shipped example rig; `orbitrig init` writes a lab's from it, dated then)."""
    if record.step not in MEASURED_STEPS or not record.rig:
        return False
    return record.rig != (rig_id or name) if record.channels else record.rig not in {name, rig_id}


def identity(rig: RigConfig) -> dict:
    """The ``rig`` and ``channels`` of a record measured now on ``rig``: its rig_id (its name
    without one) and every channel's serial and gain."""
    channels = {c.name: {"serial": c.serial, "gain": c.gain} for c in rig.channels}
    return {"rig": rig.identity, "channels": channels}


def calibrated(record: CalibrationRecord) -> dict[str, list[str]]:
    """The channels whose calibration ``record`` holds, each with the steps that measured it (a
    force channel's delay is its lag behind the probes: those count too)."""
    parts: dict[str, list[str]] = {
        "loads": [f"{axis}_{lms}" for lms in record.loads for axis in ("fx", "fy")],
        "runout": list(PROBE_CHANNELS) if record.runout else [],
        "delay": list(dict.fromkeys([*record.delay, *PROBE_CHANNELS])) if record.delay else [],
        "probes": list(record.probes),
    }
    out: dict[str, list[str]] = {}
    for step, names in parts.items():
        for name in names:
            out.setdefault(name, []).append(step)
    return out


class UncheckedRecordWarning(UserWarning):
    """An active measured record from before records carried the rig's id and channel setup."""


class UncorrectedProbeLagWarning(UserWarning):
    """An active record holding probe lags ([delay.<probe>]) written before the sweep took them out."""


def check_probe_lags(record: CalibrationRecord, record_text: str, path: Path) -> None:
    """A one-line UncorrectedProbeLagWarning, at the record's first ``[delay.<probe>]``, when ``record``
    holds probe lags without ``probe_lags_corrected``: written when the sweep left them in the
    probes' readings and counted them in their [uncertainty]; the sweep keeps that rule for it
    (turning them too would count each lag twice), so its measured lags are not taken out."""
    held = [p for p in PROBE_CHANNELS if p in record.delay]
    if record.probe_lags_corrected or not held:
        return
    lags = ", ".join(
        f"{p} {record.delay[p].phase_deg:+.3f} deg {record.delay[p].delay_us:+.1f} {MICROSECOND}" for p in held
    )
    message = (
        f"this {record.step} record's probe lags ({lags}) were recorded before the sweep took them out "
        "(no probe_lags_corrected): they stay in the probes' readings and count in full in their [uncertainty], "
        "as the record says; `orbitrig calibrate delay` again to have them taken out"
    )
    at = key_line(record_text, ("delay", held[0])) or key_line(record_text, ("step",)) or 1
    warnings.warn_explicit(message, UncorrectedProbeLagWarning, str(path), at)


def check_setup(rig: RigConfig, record: CalibrationRecord, record_text: str, path: Path) -> None:
    """Whether the active ``record`` (file ``path``) was measured with ``rig``'s channel setup: a
    ConfigError naming each channel it calibrates whose serial or gain changed, with both values;
    for a measured record without a setup (an older one) a one-line UncheckedRecordWarning. Its
    probe lags as written before the sweep took them out: check_probe_lags' warning."""
    check_probe_lags(record, record_text, path)
    if record.step not in MEASURED_STEPS:
        return
    if not record.channels:
        at = key_line(record_text, ("rig",)) or key_line(record_text, ("step",)) or 1
        message = (
            f"this {record.step} record predates the rig's id and channel setup in records: the rig, sensors "
            f"and gains it was measured with cannot be checked against {rig.file} (calibrating again records them)"
        )
        warnings.warn_explicit(message, UncheckedRecordWarning, str(path), at)
        return
    changes, steps = _setup_changes(rig, record, record_text)
    if changes:
        redo = " ".join(f"`orbitrig calibrate {s}`" for s in RecordStep if s in steps)
        changes[-1] += (
            f". Its corrections belong to the sensors as they were: set the channel back in {rig.file}, make "
            f"active a record measured with this setup, or remove calibration_record and calibrate again ({redo})"
        )
        raise ConfigError(str(path), changes)


def _setup_changes(rig: RigConfig, record: CalibrationRecord, record_text: str) -> tuple[list[str], set[str]]:
    """(one problem per changed channel, the steps that measured them)."""
    present = {c.name: (i, c) for i, c in enumerate(rig.channels)}
    problems, steps = [], set()
    for name, by in calibrated(record).items():
        was = record.channels.get(cast(ChannelName, name))  # calibrated() yields channel names
        if was is None or name not in present:
            continue
        i, now = present[name]
        fields = [f for f in ("serial", "gain") if not _same(getattr(was, f), getattr(now, f))]
        if not fields:
            continue
        at, now_at = (
            key_line(record_text, ("channels", name, fields[0])),
            key_line(rig.text, ("channels", i, fields[0])),
        )
        problems.append(
            f"{f'line {at}: ' if at else ''}key 'channels.{name}': this {record.step} record calibrates {name} "
            f"({', '.join(by)}) as measured with {_values(was, fields)}; {rig.file}"
            f"{f' (line {now_at})' if now_at else ''} sets {_values(now, fields)}"
        )
        steps.update(by)
    return problems, steps


def _same(was: str | float, now: str | float) -> bool:
    if isinstance(was, str) or isinstance(now, str):
        return was == now
    return math.isclose(was, now, rel_tol=1e-9, abs_tol=0.0)


def _values(channel, fields: list[str]) -> str:
    """'serial 'X' and gain 0.1' of ``channel``'s ``fields``."""
    return " and ".join(
        f"{f} {getattr(channel, f)!r}" if f == "serial" else f"{f} {getattr(channel, f):.10g}" for f in fields
    )

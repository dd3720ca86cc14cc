"""Calibration records: one TOML file per calibration, versioned by date (docs/calibration.md).

A record lives in the folder ``calibration/`` beside the rig configuration, named
``<UTC date and time>-<step>.toml`` (``2026-11-26T214458Z-loads``), so that the names sort by
date. Each record is complete: a calibration step starts from the active record and replaces
what it measured, so the active record alone says how the rig is calibrated. The rig
configuration names the active one (``calibration_record = "NAME"``); its ``[uncertainty]``
feeds the type-B budget, its ``[loads.<system>]`` gain matrices correct the forces, its
``[runout]`` phasors are taken from the probes' blocks, its ``[delay]`` phases and delays
bring the force channels in step with the probes. A measured record carries the rig's id and the
channel setup (serial, gain) it was measured with; ``check_setup`` refuses it on another setup.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import math
import os
import re
import stat
import tomllib
import warnings
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal, cast

import numpy as np
from pydantic import Field, field_validator

from orbitrig.config.calibration import CalibrationUncertainty, Percent
from orbitrig.config.fields import BY_VALUE, _Model
from orbitrig.config.messages import _line_of
from orbitrig.config.toml_out import render
from orbitrig.errors import ConfigError
from orbitrig.load_systems import LoadSystem

if TYPE_CHECKING:
    from orbitrig.config.rig import RigConfig

FOLDER = "calibration"
NAME = re.compile(r"^\d{4}-\d\d-\d\dT\d{6}Z-[a-z]+$")
RECORD_KEY = re.compile(r"""^([ \t]*calibration_record[ \t]*=[ \t]*)("[^"\n]*"|'[^'\n]*')""", re.MULTILINE)
TABLE_HEADER = re.compile(r"^[ \t]*\[")
TOP_KEY = re.compile(r"^[ \t]*([A-Za-z0-9_-]+)[ \t]*=")
PROBE_CHANNELS = ("x_a", "y_a", "x_b", "y_b")
ChannelName = Literal["fx_piezo", "fy_piezo", "fx_strain", "fy_strain", "x_a", "y_a", "x_b", "y_b"]

Matrix2 = Annotated[list[Annotated[list[float], Field(min_length=2, max_length=2)]], Field(min_length=2, max_length=2)]
Pair = Annotated[list[float], Field(min_length=2, max_length=2)]


class RecordStep(StrEnum):
    """What a record's calibration step measured."""

    INITIAL = "initial"  # typed in from the sensors' data sheets and certificates
    LOADS = "loads"
    RUNOUT = "runout"
    DELAY = "delay"
    PROBES = "probes"


class Reference(_Model):
    """The reference standard of a step: its id and its certificate's relative standard uncertainty."""

    id: str = Field(min_length=1)
    uncertainty_pct: Percent


class LoadGains(_Model):
    """A load measuring system's gain matrix: f_journal = gain @ f_read + offset (N; f_read through
    the channel gains of rig.toml), each entry's standard uncertainty, the fit's residual."""

    gain: Matrix2
    gain_u: Matrix2
    offset_n: Pair = [0.0, 0.0]
    residual_n: Annotated[float, Field(ge=0)] = 0.0
    loads: Annotated[int, Field(ge=0)] = 0

    @property
    def matrix(self) -> np.ndarray:
        return np.array(self.gain, dtype=float)


class ProbeRunout(_Model):
    """Runout of one probe track at 1x and 2x spin (um, [re, im], phase to the slow roll's trigger)."""

    h1_um: Pair
    h2_um: Pair


class Runout(_Model):
    """Slow-roll runout phasors of the four probes."""

    spin_rpm: Annotated[float, Field(gt=0)]
    revolutions: Annotated[int, Field(ge=1)]
    x_a: ProbeRunout
    y_a: ProbeRunout
    x_b: ProbeRunout
    y_b: ProbeRunout

    def phasors(self, probe: str) -> np.ndarray:
        """(2,) complex runout (m) of ``probe`` at 1x and 2x spin."""
        p = getattr(self, probe)
        return np.array([complex(*p.h1_um), complex(*p.h2_um)]) * 1e-6


class ProbeGain(_Model):
    """A displacement probe's calibration: x_journal = gain x_read (x_read through the channel gain
    of rig.toml), the gain's standard uncertainty and the probe's linearity (percent of the span)."""

    gain: Annotated[float, Field(gt=0)]
    gain_u: Annotated[float, Field(ge=0)] = 0.0
    linearity_pct: Annotated[float, Field(ge=0)] = 0.0
    span_um: Annotated[float, Field(ge=0)] = 0.0
    steps: Annotated[int, Field(ge=0)] = 0


class ChannelDelay(_Model):
    """A force channel's lag behind the probes: phase_deg + 360 f delay_us 1e-6 degrees at f Hz,
    with the fit's standard uncertainties."""

    phase_deg: Annotated[float, Field(ge=-180, le=180)]
    delay_us: Annotated[float, Field(ge=-100_000, le=100_000)]
    phase_u_deg: Annotated[float, Field(ge=0)] = 0.0
    delay_u_us: Annotated[float, Field(ge=0)] = 0.0


class ChannelSetup(_Model):
    """A channel as rig.toml set it up when the record was measured."""

    serial: str = ""
    gain: float


class CalibrationRecord(_Model):
    """One calibration record (docs/calibration.md)."""

    date: str  # ISO 8601, UTC
    operator: str = Field(min_length=1)
    rig: str = ""  # the rig's identity: rig.toml's rig_id (its name without one); older records: its name
    step: Annotated[RecordStep, BY_VALUE]
    previous: str = ""  # the record this one started from
    software: str = ""
    channels: dict[ChannelName, ChannelSetup] = {}  # the setup measured with; {}: an older record
    reference: Reference | None = None
    loads: dict[Annotated[LoadSystem, BY_VALUE], LoadGains] = {}
    runout: Runout | None = None
    delay: dict[Literal["fx_piezo", "fy_piezo", "fx_strain", "fy_strain"], ChannelDelay] = {}
    probes: dict[Literal["x_a", "y_a", "x_b", "y_b"], ProbeGain] = {}
    uncertainty: CalibrationUncertainty = CalibrationUncertainty()

    @field_validator("date")
    @classmethod
    def _utc(cls, v: str) -> str:
        try:
            t = _dt.datetime.fromisoformat(v)
        except ValueError:
            raise ValueError("an ISO 8601 date and time, e.g. 2026-11-26T21:44:58+00:00") from None
        if t.utcoffset() != _dt.timedelta(0):
            raise ValueError("must be UTC (+00:00 or Z)")
        return v

    def force_gain(self, lms: LoadSystem) -> np.ndarray:
        """The gain matrix of load measuring system ``lms`` (identity when not calibrated)."""
        g = self.loads.get(lms)
        return np.eye(2) if g is None else g.matrix


#: the steps that measure on a rig: their record's ``rig`` must name the rig that uses it
MEASURED_STEPS = frozenset({RecordStep.LOADS, RecordStep.RUNOUT, RecordStep.DELAY, RecordStep.PROBES})


def made_elsewhere(record: CalibrationRecord, name: str, rig_id: str) -> bool:
    """Whether ``record`` was measured on another rig than the one called ``name`` with id
    ``rig_id``: a record with its channel setup (written since records carry it) names the rig's
    id, ``rig_id or name``; an older one the rig's name or id. Not checked: a record that names
    no rig (``rig`` is optional), and an initial record (typed in from data sheets, not measured;
    the shipped one, which `orbitrig init` copies into every lab, names the shipped example rig)."""
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
        "delay": [*record.delay, *PROBE_CHANNELS] if record.delay else [],
        "probes": list(record.probes),
    }
    out: dict[str, list[str]] = {}
    for step, names in parts.items():
        for name in names:
            out.setdefault(name, []).append(step)
    return out


class UncheckedRecordWarning(UserWarning):
    """An active measured record from before records carried the rig's id and channel setup."""


def check_setup(rig: RigConfig, record: CalibrationRecord, record_text: str, path: Path) -> None:
    """Whether the active ``record`` (file ``path``) was measured with ``rig``'s channel setup: a
    ConfigError naming each channel it calibrates whose serial or gain changed, with both values;
    for a measured record without a setup (an older one) a one-line UncheckedRecordWarning."""
    if record.step not in MEASURED_STEPS:
        return
    if not record.channels:
        at = _line_of(record_text, ("rig",)) or _line_of(record_text, ("step",)) or 1
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
            _line_of(record_text, ("channels", name, fields[0])),
            _line_of(rig.text, ("channels", i, fields[0])),
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


def folder_of(rig_file: str | Path) -> Path:
    """The calibration records' folder of the rig configuration ``rig_file``."""
    return Path(rig_file).resolve().parent / FOLDER


def record_name(date: str, step: str) -> str:
    """The file stem of a record made at ``date`` (ISO 8601 UTC) by ``step``."""
    t = _dt.datetime.fromisoformat(date).astimezone(_dt.timezone.utc)
    return f"{t:%Y-%m-%dT%H%M%S}Z-{step}"


def digest(text: str) -> str:
    """SHA-256 (hex) of a record's text, as the run records it."""
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def record_from_text(text: str, file: str) -> CalibrationRecord:
    from orbitrig.config import _build, _parse

    return _build(CalibrationRecord, _parse(text, file), file, text)


def read_record(folder: Path, name: str) -> tuple[CalibrationRecord, str]:
    """(record, its text) of record ``name`` in ``folder``; ConfigError naming the file."""
    from orbitrig.config import read_text

    path = Path(folder) / f"{name}.toml"
    if not path.is_file():
        known = ", ".join(list_names(folder)) or "none"
        raise ConfigError(str(path), [f"no calibration record {name!r} (records in {folder}: {known})"])
    text, file = read_text(path)
    return record_from_text(text, file), text


def list_names(folder: Path) -> list[str]:
    """The record names in ``folder``, oldest first."""
    return sorted(p.stem for p in Path(folder).glob("*.toml")) if Path(folder).is_dir() else []


def write_record(folder: Path, record: CalibrationRecord, header: str = "") -> tuple[str, str]:
    """Write ``record`` under its dated name (never over an existing one); (name, text)."""
    name = record_name(record.date, record.step)
    path = Path(folder) / f"{name}.toml"
    if path.exists():
        raise ConfigError(str(path), ["a record of that name exists already (one step per second)"])
    text = render(record.model_dump(mode="json", exclude_none=True), header)
    record_from_text(text, str(path))  # what is written reads back
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    except OSError as err:
        raise ConfigError(str(path), [f"cannot write the record: {err.strerror or err}"]) from err
    return name, text


def activate(rig_file: str | Path, name: str) -> None:
    """Make ``name`` the active record of the rig configuration ``rig_file`` (its
    ``calibration_record`` line; added among the top-level keys when missing). Nothing else changes:
    the file is replaced as one durable step (orbitrig.store.durable, its mode kept; a symbolic link
    followed), so a full disk or a kill leaves it as it was. A file that cannot be written (no write
    permission bit, immutable, a full disk) raises ConfigError naming it, the file unchanged."""
    path = Path(rig_file).resolve()
    try:
        text = path.read_bytes().decode("utf-8")
    except OSError as err:
        raise ConfigError(str(rig_file), [f"cannot read it: {err.strerror or err}"]) from err
    if RECORD_KEY.search(text):
        text = RECORD_KEY.sub(lambda m: f'{m.group(1)}"{name}"', text, count=1)
    else:
        placed = _with_record_key(text, name)
        if placed is None:
            raise ConfigError(str(path), [f'cannot add calibration_record = "{name}": add it among the top-level keys'])
        text = placed
    _replace(path, text.encode("utf-8"), str(rig_file))


def _replace(path: Path, data: bytes, shown: str) -> None:
    """``data`` as the new content of the existing file ``path`` (temp name, fsync, rename), its
    permission bits kept; refused (ConfigError naming ``shown``) when it has no write bit or the
    write fails, the file unchanged."""
    from orbitrig.store.durable import atomic_file
    from orbitrig.store.errors import StorageError, StorageFullError

    mode = stat.S_IMODE(path.stat().st_mode)
    if not mode & 0o222 or not os.access(path, os.W_OK):
        why = f"it is read-only (mode {mode:o})" if not mode & 0o222 else "write access refused (immutable?)"
        raise ConfigError(shown, [f"cannot write it: {why}; left unchanged"])
    try:
        with atomic_file(path) as f:
            os.fchmod(f.fileno(), mode)
            f.write(data)
    except StorageError as err:
        why = err.problem if isinstance(err, StorageFullError) else err.reason
        raise ConfigError(shown, [f"{why}; left unchanged"]) from None


def _with_record_key(text: str, name: str) -> str | None:
    """``text`` with ``calibration_record = "name"`` among its top-level keys: after ``name = ...``,
    else after the last top-level key, else above the first table (and its comments), else on
    top; the first place where the text reads back as before plus that key (None: no such place)."""
    lines = text.splitlines(keepends=True)
    nl = "\r\n" if "\r\n" in text else "\n"
    first = next((i for i, ln in enumerate(lines) if TABLE_HEADER.match(ln)), len(lines))
    keys = [i for i in range(first) if TOP_KEY.match(lines[i])]
    named = [i for i in keys if lines[i].split("=")[0].strip() == "name"]
    above = first
    while above > 0 and lines[above - 1].lstrip().startswith("#"):
        above -= 1
    want = _toml(text)
    if want is not None:
        want["calibration_record"] = name
    for at, gap in [(i + 1, "") for i in named[:1] + keys[-1:]] + [(above, nl), (0, "")]:
        head = "".join(lines[:at])
        head += nl if head and not head.endswith("\n") else ""
        out = f'{head}calibration_record = "{name}"{nl}{gap if at < len(lines) else ""}' + "".join(lines[at:])
        if want is None or _toml(out) == want:
            return out
    return None


def _toml(text: str) -> dict | None:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        return None

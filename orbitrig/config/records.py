"""Calibration records: one TOML file per calibration, versioned by date (docs/calibration.md).

A record lives in the folder ``calibration/`` beside the rig configuration, named
``<UTC date and time>-<step>.toml`` (``2026-11-26T214458Z-loads``), so that the names sort by
date. Each record is complete: a calibration step starts from the active record and replaces
what it measured, so the active record alone says how the rig is calibrated. The rig
configuration names the active one (``calibration_record = "NAME"``); its ``[uncertainty]``
feeds the type-B budget, its ``[loads.<system>]`` gain matrices correct the forces, its
``[runout]`` phasors are taken from the probes' blocks, its ``[delay]`` phases and delays
bring the force channels in step with the probes.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import re
from enum import StrEnum
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, field_validator

from orbitrig.config.calibration import CalibrationUncertainty, Percent
from orbitrig.config.fields import BY_VALUE, _Model
from orbitrig.config.toml_out import render
from orbitrig.errors import ConfigError
from orbitrig.load_systems import LoadSystem

FOLDER = "calibration"
NAME = re.compile(r"^\d{4}-\d\d-\d\dT\d{6}Z-[a-z]+$")
RECORD_KEY = re.compile(r'^(calibration_record\s*=\s*)"[^"]*"', re.MULTILINE)

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


class CalibrationRecord(_Model):
    date: str  # ISO 8601, UTC
    operator: str = Field(min_length=1)
    rig: str = ""
    step: Annotated[RecordStep, BY_VALUE]
    previous: str = ""  # the record this one started from
    software: str = ""
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
    """Whether ``record`` was measured on another rig than the one called ``name`` (rig.toml's
    ``name``, which `orbitrig calibrate` writes into ``rig``) with id ``rig_id``. Not checked: a
    record that names no rig (``rig`` is optional), and an initial record (typed in from data
    sheets, not measured; the shipped one, which `orbitrig init` copies into every lab, names
    the shipped example rig)."""
    return record.step in MEASURED_STEPS and bool(record.rig) and record.rig not in {name, rig_id}


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
    from orbitrig.config import _read

    path = Path(folder) / f"{name}.toml"
    if not path.is_file():
        known = ", ".join(list_names(folder)) or "none"
        raise ConfigError(str(path), [f"no calibration record {name!r} (records in {folder}: {known})"])
    text, file = _read(path)
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
    ``calibration_record`` line; added after ``name = ...`` when missing). Nothing else changes."""
    path = Path(rig_file)
    text = path.read_text(encoding="utf-8")
    line = f'calibration_record = "{name}"'
    if RECORD_KEY.search(text):
        text = RECORD_KEY.sub(lambda m: f'{m.group(1)}"{name}"', text, count=1)
    else:
        m = re.search(r"^name\s*=.*$", text, re.MULTILINE)
        at = m.end() if m else 0
        text = text[:at] + ("\n" if m else "") + line + ("" if m else "\n") + text[at:]
    path.write_text(text, encoding="utf-8")

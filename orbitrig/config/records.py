"""Calibration records: one TOML file per calibration, versioned by date (docs/calibration.md).

A record lives in the folder ``calibration/`` beside the rig configuration, named
``<UTC date and time>-<step>.toml`` (``2026-11-26T214458Z-loads``), so that the names sort by
date. Each record is complete: a calibration step starts from the active record and replaces
what it measured, so the active record alone says how the rig is calibrated. The rig
configuration names the active one (``calibration_record = "NAME"``); its ``[uncertainty]``
feeds the type-B budget, its ``[loads.<system>]`` gain matrices correct the forces, its
``[runout]`` phasors are taken from the probes' blocks, its ``[delay]`` phases and delays
bring the force channels in step with the probes (and, ``probe_lags_corrected``, each probe
in step with the four probes' mean). A measured record carries the rig's id and the
channel setup (serial, gain) it was measured with; ``check_setup`` (record_setup) refuses it on
another setup. Here: the record's model; the folder, names, reading, writing and making a record
active are record_files'.
"""

from __future__ import annotations

import datetime as _dt
from enum import StrEnum
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, field_validator

from orbitrig.config.calibration import CalibrationUncertainty, Percent
from orbitrig.config.fields import BY_VALUE, ChannelName, ConfigModel
from orbitrig.load_systems import LoadSystem
from rigunits import UM

Matrix2 = Annotated[list[Annotated[list[float], Field(min_length=2, max_length=2)]], Field(min_length=2, max_length=2)]
Pair = Annotated[list[float], Field(min_length=2, max_length=2)]
#: standard uncertainties of a 2 x 2 matrix's entries: none negative
Matrix2U = Annotated[
    list[Annotated[list[Annotated[float, Field(ge=0)]], Field(min_length=2, max_length=2)]],
    Field(min_length=2, max_length=2),
]
#: degrees of freedom of a fit's residuals (a record written before them: None)
Dof = Annotated[int, Field(ge=1)] | None
#: coverage factors of a 2 x 2 matrix's expanded uncertainties: each at least 1
Matrix2K = Annotated[
    list[Annotated[list[Annotated[float, Field(ge=1)]], Field(min_length=2, max_length=2)]],
    Field(min_length=2, max_length=2),
]
#: the largest condition number of a gain matrix a record holds (a cross-axis term of a few percent: about 1.1)
MAX_GAIN_CONDITION = 1e3


class RecordStep(StrEnum):
    """What a record's calibration step measured."""

    INITIAL = "initial"  # typed in from the sensors' data sheets and certificates
    LOADS = "loads"
    RUNOUT = "runout"
    DELAY = "delay"
    PROBES = "probes"


class Reference(ConfigModel):
    """The reference standard of a step: its id and its certificate's relative standard uncertainty."""

    id: str = Field(min_length=1)
    uncertainty_pct: Percent


class LoadGains(ConfigModel):
    """A load measuring system's gain matrix: f_journal = gain @ f_read + offset (N; f_read through
    the channel gains of rig.toml), each entry's standard uncertainty, the fit's residual; the fit's
    degrees of freedom, each entry's coverage factor and expanded uncertainty gain_U = gain_k gain_u
    (reduction.calibration.expanded; None: a record written before them)."""

    gain: Matrix2
    gain_u: Matrix2U
    offset_n: Pair = [0.0, 0.0]
    residual_n: Annotated[float, Field(ge=0)] = 0.0
    loads: Annotated[int, Field(ge=0)] = 0
    dof: Dof = None
    gain_k: Matrix2K | None = None
    gain_U: Matrix2U | None = None

    @field_validator("gain")
    @classmethod
    def _invertible(cls, v: list[list[float]]) -> list[list[float]]:
        """A gain matrix maps the two read forces onto the journal's: a singular one (a row of
        zeros, two equal rows) would fold them onto one line and every coefficient with them."""
        cond = float(np.linalg.cond(np.array(v, dtype=float)))
        if not cond <= MAX_GAIN_CONDITION:
            raise ValueError(
                f"a gain matrix must be invertible (condition number {cond:.3g}, "
                f"at most {MAX_GAIN_CONDITION:g}): the read forces would be folded onto one line"
            )
        return v

    @property
    def matrix(self) -> np.ndarray:
        return np.array(self.gain, dtype=float)

    @property
    def fit_dof(self) -> int | None:
        """The fit's degrees of freedom: ``dof``; a record written before it: 2 (loads - 3) (None without)."""
        return self.dof if self.dof is not None else (2 * (self.loads - 3) if self.loads > 3 else None)


class ProbeRunout(ConfigModel):
    """Runout of one probe track at 1x and 2x spin (um, [re, im], phase to the slow roll's trigger),
    each with its standard uncertainty from the scatter of the slow roll's revolutions (um; None: a
    record written before the step measured it, or one revolution)."""

    h1_um: Pair
    h2_um: Pair
    h1_u_um: Annotated[float, Field(ge=0)] | None = None
    h2_u_um: Annotated[float, Field(ge=0)] | None = None


class Runout(ConfigModel):
    """Slow-roll runout phasors of the four probes; ``slip_pct``, ``slip_u_pct``: the slip of the
    slow roll's spin against its orbit spindle fitted from the runout, and its standard uncertainty
    (percent; the revolutions were turned back by it before the average: docs/calibration.md; None:
    a record written before it, or fewer than three revolutions)."""

    spin_rpm: Annotated[float, Field(gt=0)]
    revolutions: Annotated[int, Field(ge=1)]
    slip_pct: float | None = None
    slip_u_pct: Annotated[float, Field(ge=0)] | None = None
    x_a: ProbeRunout
    y_a: ProbeRunout
    x_b: ProbeRunout
    y_b: ProbeRunout

    def phasors(self, probe: str) -> np.ndarray:
        """(2,) complex runout (m) of ``probe`` at 1x and 2x spin."""
        p = getattr(self, probe)
        return np.array([complex(*p.h1_um), complex(*p.h2_um)]) * UM

    def uncertainties(self, probes: tuple[str, ...]) -> np.ndarray | None:
        """(len(probes), 2) standard uncertainties (m) of their runout at 1x and 2x spin; None when
        any is absent (a record written before them, a slow roll of one revolution)."""
        u = [(getattr(self, p).h1_u_um, getattr(self, p).h2_u_um) for p in probes]
        if any(v is None for pair in u for v in pair):
            return None
        return np.array(u, dtype=float) * UM


class ProbeGain(ConfigModel):
    """A displacement probe's calibration: x_journal = gain x_read (x_read through the channel gain
    of rig.toml), the gain's standard uncertainty and the probe's linearity (percent of the span);
    the line's degrees of freedom, the coverage factor and gain_U = gain_k gain_u (None: a record
    written before them)."""

    gain: Annotated[float, Field(gt=0)]
    gain_u: Annotated[float, Field(ge=0)] = 0.0
    linearity_pct: Annotated[float, Field(ge=0)] = 0.0
    span_um: Annotated[float, Field(ge=0)] = 0.0
    steps: Annotated[int, Field(ge=0)] = 0
    dof: Dof = None
    gain_k: Annotated[float, Field(ge=1)] | None = None
    gain_U: Annotated[float, Field(ge=0)] | None = None

    @property
    def fit_dof(self) -> int | None:
        """The line's degrees of freedom: ``dof``; a record written before it: steps - 2 (None without)."""
        return self.dof if self.dof is not None else (self.steps - 2 if self.steps > 2 else None)


class ChannelDelay(ConfigModel):
    """A channel's lag behind the four probes' mean: phase_deg + 360 f delay_us 1e-6 degrees at
    f Hz, with the fit's standard uncertainties (a probe's: its difference from the others); the
    line's degrees of freedom, the coverage factor k and the expanded uncertainties k u (None: a
    record written before them)."""

    phase_deg: Annotated[float, Field(ge=-180, le=180)]
    delay_us: Annotated[float, Field(ge=-100_000, le=100_000)]
    phase_u_deg: Annotated[float, Field(ge=0)] = 0.0
    delay_u_us: Annotated[float, Field(ge=0)] = 0.0
    dof: Dof = None
    k: Annotated[float, Field(ge=1)] | None = None
    phase_U_deg: Annotated[float, Field(ge=0)] | None = None
    delay_U_us: Annotated[float, Field(ge=0)] | None = None

    @property
    def fit_dof(self) -> int | None:
        """The line's degrees of freedom: ``dof`` (a record written before it: None, its speeds not kept)."""
        return self.dof


class ChannelSetup(ConfigModel):
    """A channel as rig.toml set it up when the record was measured."""

    serial: str = ""
    gain: float


class CalibrationRecord(ConfigModel):
    """One calibration record (docs/calibration.md)."""

    date: str  # ISO 8601, UTC
    operator: str = Field(min_length=1)
    rig: str = ""  # the rig's identity: rig.toml's rig_id (its name without one); older records: its name
    step: Annotated[RecordStep, BY_VALUE]
    previous: str = ""  # the record this one started from
    software: str = ""
    simulator: str = ""  # the scenario a step run with --sim measured on; "": measured on the rig
    simulator_sha256: str = ""  # SHA-256 of that scenario's TOML text; "": on the rig, or an older record
    channels: dict[ChannelName, ChannelSetup] = {}  # the setup measured with; {}: an older record
    reference: Reference | None = None
    loads: dict[Annotated[LoadSystem, BY_VALUE], LoadGains] = {}
    runout: Runout | None = None
    delay: dict[ChannelName, ChannelDelay] = {}  # every channel; an older record: the force channels only
    #: true (a delay step from this version on): the sweep turns each probe by its [delay] lag and its
    #: [uncertainty] holds the fit's alone; false: its lag is left in the readings, counted in its [uncertainty]
    probe_lags_corrected: bool = False
    probes: dict[Literal["x_a", "y_a", "x_b", "y_b"], ProbeGain] = {}
    uncertainty: CalibrationUncertainty = CalibrationUncertainty()

    @field_validator("date")
    @classmethod
    def _utc(cls, v: str) -> str:
        try:
            t = _dt.datetime.fromisoformat(v)
        except ValueError:
            raise ValueError("an ISO 8601 date and time, e.g. 2026-11-26T21:44:58.000Z") from None
        if t.utcoffset() != _dt.timedelta(0):
            raise ValueError("must be UTC (+00:00 or Z)")
        return v

    def force_gain(self, lms: LoadSystem) -> np.ndarray:
        """The gain matrix of load measuring system ``lms`` (identity when not calibrated)."""
        g = self.loads.get(lms)
        return np.eye(2) if g is None else g.matrix

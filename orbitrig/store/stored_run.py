"""A stored run as plain data (docs/storage.md), what orbitrig.store.reader reads a run directory
into: :class:`Run` (status, configuration text, provenance, points), one :class:`Point` per
operating point with its :class:`Settings`, orbit tables per load measuring system, the
:class:`Frequency` blocks and the sweep's :class:`StoredIdentification` entries.

Units are SI as stored (rad/s, Pa, m, N); conversion to rpm, MPa, degrees is left to the report.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path, PureWindowsPath
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from orbitrig.load_systems import LoadSystem
from orbitrig.store.identity import run_identity
from orbitrig.store.status import RunStatus
from reduction.methods import Method

if TYPE_CHECKING:
    from reduction.table import OrbitTable


@dataclass(frozen=True)
class Settings:
    """Operating point settings (SI, as stored in the point's attributes); a figure's title gives
    them typeset (orbitrig.analysis.typeset.operating_point_math), the page in a table."""

    spin: float  # rad/s
    spin_rpm: float
    recess_pressure: float  # Pa
    pressure_ratio: float  # -
    static_eccentricity: float  # -
    dynamic_eccentricity: float  # -
    orbit_radius: float  # m, commanded
    label: str


@dataclass(frozen=True)
class Frequency:
    """One orbit frequency of a point (group ``frequencies/FF_dir``)."""

    name: str  # "FF_dir"
    orbit: float  # rad/s, signed (< 0 backward)
    orbit_hz: float  # > 0
    direction: int  # +1 forward, -1 backward
    complete: bool
    coherence: npt.NDArray[np.float64] | None  # (2, 4): rows piezo|strain, cols xfx, yfx, xfy, yfy
    n_records: int = 0  # revolutions averaged
    measured_orbit_speed: float = float("nan")  # rad/s, > 0: from the trigger times (the table row's orbit)
    #: rad/s, spin and signed orbit as written to the drives (each REF rounded to its count); nan: a
    #: run written before they were stored (the planned speeds stand for them)
    written: tuple[float, float] = (float("nan"), float("nan"))
    #: the averaged block, SI per channel (N or m): mean (C, S), slots (C, S), dc (C,),
    #: phasors (C,) complex, uncertainty (C,) when measured
    waveform: dict[str, npt.NDArray[Any]] = field(default_factory=dict, repr=False)


@dataclass(frozen=True)
class StoredIdentification:
    """One ``identification/<lms>__<model>__<freq_dep>`` entry of the sweep."""

    lms: LoadSystem
    model: str
    freq_dep: str  # the original spec, e.g. "power:auto"
    result: dict[str, Any] | None  # the `identify --json` object
    error: str | None  # the refusal message when the model was refused
    method: str = Method.OLS.value  # the word stored (ols when the file names none)

    @property
    def ok(self) -> bool:
        return self.result is not None


@dataclass
class Point:
    """One operating point (group ``/points/PPPP``)."""

    index: int
    name: str  # "PPPP"
    complete: bool
    settings: Settings
    frequencies: list[Frequency] = field(default_factory=list)
    tables: dict[LoadSystem, OrbitTable] = field(default_factory=dict)  # lms -> orbit table
    identifications: list[StoredIdentification] = field(default_factory=list)
    truth: dict[str, Any] | None = None
    lms_comparison: dict[str, Any] | None = None
    runout_turns: dict[str, Any] | None = None  # per block, the spin turns the runout is placed with
    problem: str = ""  # why the point is not complete ("" when complete; orbitrig.store.index)
    software: str = ""  # the software that measured it ("": a run of an earlier version)

    def identification(
        self, lms: LoadSystem, model: str, freq_dep: str, method: str | None = None
    ) -> StoredIdentification | None:
        """The stored identification (refused or not) of ``lms``, ``model``, ``freq_dep`` and,
        when given, ``method`` (else the first stored of any method); None when there is none."""
        for ident in self.identifications:
            if (ident.lms, ident.model, ident.freq_dep) == (lms, model, freq_dep) and method in (None, ident.method):
                return ident
        return None


@dataclass
class Run:
    """A run directory as read from disk (`torn`: journal lines ignored, `unreadable`: pieces skipped,
    `warnings`: what a reader should know of it, e.g. its journal.jsonl missing)."""

    directory: Path
    status: RunStatus
    status_message: str
    sim: bool
    software_version: str
    created: str
    matrix_name: str
    rig_config: str
    matrix_config: str
    points: list[Point]
    channels: list[str] = field(default_factory=list)
    channel_units: list[str] = field(default_factory=list)
    torn: int = 0
    unreadable: list[str] = field(default_factory=list)
    unbegun: list[int] = field(default_factory=list)  # point folders without a settings record (cut at its start)
    warnings: list[str] = field(default_factory=list)  # said by every command reading the run (select_points)
    sim_scenario_name: str = (
        ""  # --sim runs: the simulator scenario (its file's path where the run was made, or the default)
    )
    sim_scenario_config: str = ""  # its TOML text ("" in runs of earlier versions: their default rig)
    provenance: dict[str, str] = field(default_factory=dict)  # PROVENANCE_KEYS ("" unknown), times ISO 8601 UTC
    calibration_record_text: str = ""  # the active calibration record's TOML text ("" none stored)

    @property
    def software_versions(self) -> list[str]:
        """The software that measured the points, each once, in point order: two or more when the
        run was resumed with other software (``software_version`` names the one it started with)."""
        return list(dict.fromkeys(p.software for p in self.points if p.software))

    @property
    def complete_points(self) -> list[Point]:
        return [p for p in self.points if p.complete]

    @property
    def sim_scenario_sha256(self) -> str:
        """SHA-256 (hex) of the stored simulator scenario's text ("" when the run stored none)."""
        return hashlib.sha256(self.sim_scenario_config.encode()).hexdigest() if self.sim_scenario_config else ""

    @property
    def run_id(self) -> str:
        """The run's id (orbitrig.store.identity): as its sweep, the service and the catalog name it."""
        return run_identity(self.provenance.get("rig_id", ""), self.created)


def scenario_label(name: str) -> str:
    """The short name of a stored simulator scenario `name` (its file's path on the machine that
    made the run): the file's stem, ``paper`` for the shipped sim.toml (the default scenario), an
    older run's default by its name's first word."""
    stem = PureWindowsPath(name).stem if name.endswith(".toml") else name.split(" (")[0]  # / or \\ separated
    return "paper" if stem == "sim" else stem


#: who made the run, where and when (docs/storage.md); `ended` is "" while the run is running
#: the run's provenance as read (text; ``sensor_serials`` a JSON object channel -> serial number)
_WHO_WHERE = ("operator", "rig_id", "host", "calibration_record", "calibration_record_sha256", "sensor_serials")
#: whether the record's text was as its step wrote it ("as written", "not verifiable"; "" no record, or a
#: run written before provenance said)
SEAL = "calibration_record_seal"
#: whether the record's measurements were within rig.toml's calibration_valid_days at the run's start
#: ("expired: ...", "valid: ...", "no limit: ..."; "" no record, or a run written before provenance said)
VALIDITY = "calibration_validity"
#: SHA-256 (hex) of rig.toml's and of the matrix file's texts as read, before the matrix's [design_used] is
#: appended ("" a run written before provenance said)
CONFIG_SHA256 = ("rig_sha256", "matrix_sha256")
PROVENANCE_KEYS: tuple[str, ...] = (
    *_WHO_WHERE,
    SEAL,
    VALIDITY,
    *CONFIG_SHA256,
    "started",
    "ended",
)  # "ended" last: a run in progress has none

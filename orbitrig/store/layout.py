"""The run directory's layout: every file name, and the units and labels of what is stored.

Both the writer (orbitrig.store.writer) and the readers (orbitrig.store.reader, export)
find files through :class:`RunLayout`; docs/storage.md describes the same layout::

    DIR/run.json                    the run's header, written once (format, configs, channels)
    DIR/journal.jsonl               append-only event log (status, points, events, CAN, drives)
    DIR/points/PPPP/point.json      an operating point's settings
    DIR/points/PPPP/FF_dir.h5       one orbit frequency (block), one durable file each
    DIR/points/PPPP/results.h5      the point's orbit tables and identifications
    DIR/points/PPPP/complete.json   the commit record: size and SHA-256 of every file above
    DIR/aside/...                   what `--resume` set aside (incomplete or damaged)
    DIR/run.h5                      the single file for MATLAB / h5py users (consolidated)
    DIR/coefficients.csv, DIR/run.log

A point is complete when ``complete.json`` exists and every file it names has the
recorded size and digest; nothing else counts.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from reduction.columns import GAMMA2_COLUMNS
from reduction.columns import U_COLUMNS as _U_COLUMNS
from rigunits import DAMPING, ONE, TEXT

FORMAT = "orbitrig-run/2"
#: formats of run.h5 this version reads (1: written in place by earlier versions)
READABLE_FORMATS = ("orbitrig-run/1", FORMAT)

HEADER, JOURNAL, RUN_FILE = "run.json", "journal.jsonl", "run.h5"
CSV_FILE, LOG_FILE = "coefficients.csv", "run.log"
POINTS, ASIDE = "points", "aside"
POINT_FILE, RESULTS_FILE, COMMIT_FILE = "point.json", "results.h5", "complete.json"
BLOCK_SUFFIX = ".h5"
_POINT_DIR = re.compile(r"\d{4}")
_BLOCK_FILE = re.compile(r"\d{2}_(fwd|bwd)\.h5")

#: coherence columns: (displacement, force) pairs, and the columns of an orbit table's `u`
#: (standard uncertainty of each phasor), as the orbit table orders them
COHERENCE_PAIRS, U_COLUMNS = GAMMA2_COLUMNS, _U_COLUMNS
U_UNITS = ("m", "m", "N", "N")
#: unit of each real derived quantity at the orbit frequencies (H: N/m per part, complex)
DERIVED_UNITS = {"c_eff_xx": DAMPING, "c_eff_yy": DAMPING, "wfr": ONE}
#: what each coefficient matrix is, in words (run.h5's descriptions, the figures' axes)
MATRIX_NAMES = {"K": "stiffness", "C": "damping", "D": "apparent inertia (added mass)"}
#: the meaning of ``interval_95_basis`` wherever it is stored or exported
INTERVAL_BASIS_MEANING = "what U of interval_95 rests on: combined (statistical and calibration) or statistical only"

#: unit of each column of a point's row (orbitrig.store.frames.points_frame), as pint parses it and as
#: run.h5 gives the point's attribute of the same name (rigunits: ONE for a number or flag, TEXT for text)
SETTINGS_UNITS = {
    "label": TEXT,
    "complete": ONE,  # a flag: dimensionless, as run.h5's complete__units and the catalog have it
    "spin": "rad/s",
    "spin_rpm": "rpm",
    "recess_pressure": "Pa",
    "pressure_ratio": ONE,
    "static_eccentricity": ONE,
    "dynamic_eccentricity": ONE,
    "orbit_radius": "m",
    "n_frequencies": ONE,
}
#: the columns of a point's row that are not its settings (orbitrig.store.stored_run.Settings)
POINT_STATE = ("complete", "n_frequencies")
#: the unit of the recess pressure where a person reads it (coefficients.csv's recess_pressure_mpa;
#: rigunits.MPA Pa each)
PRESSURE_DISPLAY_UNIT = "MPa"

#: units of the attributes of each kind of group (HDF5 attributes cannot carry attributes)
POINT_ATTR_UNITS = (
    "spin: rad/s; spin_rpm: rpm; recess_pressure: Pa; pressure_ratio: 1; "
    "static_eccentricity: 1; dynamic_eccentricity: 1; orbit_radius: m"
)
BLOCK_ATTR_UNITS = (
    "orbit: rad/s (signed, < 0 backward); orbit_hz: Hz; measured_orbit_speed: rad/s; "
    "spin_written, orbit_written: rad/s; n_records: 1"
)
TABLE_ATTR_UNITS = "spin: rad/s"
IDENT_ATTR_UNITS = "condition_number: 1; residual_rms: N; dof: 1; chi2: 1; p_value: 1"


def unit_product(a: str, b: str) -> str:
    """The unit of a product of a quantity in ``a`` and one in ``b``, in the form pint parses:
    ('N/m', 'N s/m') -> '(N/m) * (N s/m)' (a covariance entry of Kxx and Cxx)."""
    return f"({a}) * ({b})"


def point_name(index: int) -> str:
    """The name of operating point `index` in the run's folders, log lines and progress: 3 -> '0003'."""
    return f"{index:04d}"


def point_cell(index: int, full: bool) -> str:
    """Operating point `index` in a table cell: named as on the terminal ('0003', point_name) in
    text, by its index ('3') in CSV and JSON (`full`), as every CSV file of a run carries it
    (coefficients.csv, reduce_*.csv, the exports)."""
    return str(index) if full else point_name(index)


@dataclass(frozen=True)
class RunLayout:
    """Paths of one run directory."""

    dir: Path

    def __post_init__(self) -> None:
        object.__setattr__(self, "dir", Path(self.dir))

    @property
    def header(self) -> Path:
        return self.dir / HEADER

    @property
    def journal(self) -> Path:
        return self.dir / JOURNAL

    @property
    def run_file(self) -> Path:
        return self.dir / RUN_FILE

    @property
    def csv(self) -> Path:
        return self.dir / CSV_FILE

    @property
    def log(self) -> Path:
        return self.dir / LOG_FILE

    @property
    def points(self) -> Path:
        return self.dir / POINTS

    @property
    def aside(self) -> Path:
        return self.dir / ASIDE

    def has_pieces(self) -> bool:
        """True when DIR holds a run in durable pieces (written by this version)."""
        return self.header.is_file()

    def point_dir(self, index: int) -> Path:
        return self.points / point_name(index)

    def point_file(self, index: int) -> Path:
        return self.point_dir(index) / POINT_FILE

    def block_file(self, index: int, tag: str) -> Path:
        return self.point_dir(index) / f"{tag}{BLOCK_SUFFIX}"

    def results_file(self, index: int) -> Path:
        return self.point_dir(index) / RESULTS_FILE

    def commit_file(self, index: int) -> Path:
        return self.point_dir(index) / COMMIT_FILE

    def point_indexes(self) -> list[int]:
        """Indexes of the point directories present (complete or not), ascending."""
        if not self.points.is_dir():
            return []
        return sorted(int(p.name) for p in self.points.iterdir() if p.is_dir() and _POINT_DIR.fullmatch(p.name))

    def block_tags(self, index: int) -> list[str]:
        """Tags ('03_bwd') of the block files present in a point directory, sorted."""
        d = self.point_dir(index)
        if not d.is_dir():
            return []
        return sorted(p.name[: -len(BLOCK_SUFFIX)] for p in d.iterdir() if _BLOCK_FILE.fullmatch(p.name))

    def aside_dir(self, index: int, reason: str) -> Path:
        """A free name under DIR/aside for point `index` set aside for `reason`."""
        n = 1
        while (self.aside / f"{point_name(index)}.{reason}.{n}").exists():
            n += 1
        return self.aside / f"{point_name(index)}.{reason}.{n}"


def freq_dep_from_key(key: str) -> str:
    """Undo storage's key mangling: 'power_auto' -> 'power:auto', 'power_1_2_3' -> 'power:1,2,3'."""
    head, sep, rest = key.partition("_")
    return head if not sep else f"{head}:{rest.replace('_', ',')}"


def freq_dep_key(freq_dep: str) -> str:
    """Storage's key form of a frequency-dependence spec (':' and ',' -> '_')."""
    return freq_dep.replace(":", "_").replace(",", "_")

"""`orbitrig export RUN`: a run's orbit tables and results in formats other tools read.

Every format carries the same content (orbitrig.store.export_content): provenance, each
complete point's settings and orbit tables (with the whirl direction), every fit's
coefficients with std and U, covariance with its names, budget, derived quantities,
adequacy, the simulator's truth, and (mat, tdms, h5) the averaged waveforms:

- ``csv``: orbitrig.store.export_csv; ``csv_manifest.txt`` lists the files written, and the
  earlier csv export's files not written again are removed (orbitrig.store.export_manifest);
- ``mat``: ``run.mat`` (MATLAB, GNU Octave), orbitrig.store.export_mat;
- ``tdms``: ``run.tdms`` (NI LabVIEW), orbitrig.store.export_tdms;
- ``h5``: ``run.h5``, the whole run in one file that GNU Octave reads too, orbitrig.store.export_h5.

Every file is written to a temporary name and renamed into place; every failure
is a StorageError naming the file (on a full disk the one being written, with the
advice to export again). Every point asked for and not exported is named
(orbitrig.store.selection). When no point asked for can be exported (e.g. a mistyped
``--point``), nothing is written or removed: an earlier export stays as it was (as
`orbitrig report` leaves its page).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path

from orbitrig.store.errors import StorageFullError, storage_error
from orbitrig.store.layout import RunLayout
from orbitrig.store.reader import read_run
from orbitrig.store.stored_run import Run
from orbitrig.store.selection import Selection, select_points


class ExportFormat(StrEnum):
    """The formats of `orbitrig export` (their ``--format`` words). ``ross`` is the fits over rotor
    speed for ROSS, written by orbitrig.analysis.ross_export; the others by :func:`export_run`."""

    CSV = "csv"
    MAT = "mat"
    TDMS = "tdms"
    H5 = "h5"
    ROSS = "ross"


#: the formats :func:`export_run` writes (a run's tables and results)
FORMATS = (ExportFormat.CSV, ExportFormat.MAT, ExportFormat.TDMS, ExportFormat.H5)
EXPORT_DIR = "export"
#: the advice of an export that found the disk full (not a sweep's "resume the run")
EXPORT_FULL_ADVICE = "free space, then export again"


@dataclass
class Exported:
    """The files written and the points selected (with the skipped ones named)."""

    files: list[Path]
    selection: Selection


def export_run(
    directory: str | Path, fmt: ExportFormat | str, out: str | Path | None = None, points: Iterable[int] | None = None
) -> Exported:
    """Write the export of the run in `directory` as `fmt` into `out` (default DIR/export):
    the complete points among `points` (None: all; h5 always holds the whole run). No files
    (nothing written, `out` untouched) when no such point has an orbit table.
    Raises RunDirError (not a run) or StorageError."""
    if fmt not in FORMATS:
        raise ValueError(f"unknown format {str(fmt)!r}: one of {', '.join(FORMATS)}")
    fmt = ExportFormat(fmt)
    layout = RunLayout(Path(directory))
    out = Path(out) if out is not None else layout.dir / EXPORT_DIR
    run = read_run(layout.dir)  # a RunDirError for what is not a run
    selection = select_points(run, None if fmt is ExportFormat.H5 else points)
    selection.skip_tableless()
    if fmt is not ExportFormat.H5 and not selection.points:  # an earlier export stays as it was
        return Exported([], selection)
    try:
        return Exported(_write(fmt, run, layout, selection, out), selection)
    except StorageFullError as err:
        raise err.advising(EXPORT_FULL_ADVICE) from err


def _write(fmt: ExportFormat, run: Run, layout: RunLayout, selection: Selection, out: Path) -> list[Path]:
    """The files of format `fmt` written into `out` (made first when missing)."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise storage_error(out, "create the export directory", err) from err
    if fmt is ExportFormat.H5:
        from orbitrig.store.export_h5 import export_h5

        return [export_h5(layout, out)]
    from orbitrig.store.export_csv import export_csv
    from orbitrig.store.export_manifest import replace_earlier
    from orbitrig.store.export_mat import export_mat
    from orbitrig.store.export_tdms import export_tdms

    write = {ExportFormat.CSV: export_csv, ExportFormat.MAT: export_mat, ExportFormat.TDMS: export_tdms}[fmt]
    files = write(run, selection.points, out)
    if fmt is ExportFormat.CSV:  # per-point files: the earlier csv export's not written again go
        selection.notes += replace_earlier(out, files)
    return files

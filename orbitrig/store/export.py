"""`orbitrig export RUN`: a run's orbit tables and results in formats other tools read.

Every format carries the same content (orbitrig.store.export_content): provenance, each
complete point's settings and orbit tables (with the whirl direction), every fit's
coefficients with std and U, covariance with its names, budget, derived quantities,
adequacy, the simulator's truth, and (mat, tdms, h5) the averaged waveforms:

- ``csv``: orbitrig.store.export_csv;
- ``mat``: ``run.mat`` (MATLAB, GNU Octave), orbitrig.store.export_mat;
- ``tdms``: ``run.tdms`` (NI LabVIEW), orbitrig.store.export_tdms;
- ``h5``: ``run.h5``, the consolidated single file (docs/storage.md).

Every file is written to a temporary name and renamed into place; every failure
is a StorageError naming the file.
"""

from __future__ import annotations

from pathlib import Path

from orbitrig.store.durable import write_atomic
from orbitrig.store.errors import storage_error
from orbitrig.store.layout import RunLayout
from orbitrig.store.reader import read_run

FORMATS = ("csv", "mat", "tdms", "h5")
EXPORT_DIR = "export"


def export_run(directory: str | Path, fmt: str, out: str | Path | None = None) -> list[Path]:
    """Write the export of the run in `directory` as `fmt` into `out` (default DIR/export).
    Returns the files written. Raises RunDirError (not a run) or StorageError."""
    if fmt not in FORMATS:
        raise ValueError(f"unknown format {fmt!r}: one of {', '.join(FORMATS)}")
    layout = RunLayout(Path(directory))
    out = Path(out) if out is not None else layout.dir / EXPORT_DIR
    if fmt == "h5":
        run = read_run(layout.dir)  # a RunDirError for what is not a run
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise storage_error(out, "create the export directory", err) from err
        return [_export_h5(layout, out)]
    run = read_run(layout.dir)
    points = [p for p in run.complete_points if p.tables]
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise storage_error(out, "create the export directory", err) from err
    from orbitrig.store.export_csv import export_csv
    from orbitrig.store.export_mat import export_mat
    from orbitrig.store.export_tdms import export_tdms

    return {"csv": export_csv, "mat": export_mat, "tdms": export_tdms}[fmt](run, points, out)


def _export_h5(layout: RunLayout, out: Path) -> Path:
    from orbitrig.store.consolidate import run_image

    path = out / layout.run_file.name
    if layout.has_pieces():
        data = run_image(layout)
    else:  # a directory holding only run.h5: copy it
        try:
            data = layout.run_file.read_bytes()
        except OSError as err:
            raise storage_error(layout.run_file, "read", err) from err
    if path.resolve() != layout.run_file.resolve() or layout.has_pieces():
        write_atomic(path, data)
    return path

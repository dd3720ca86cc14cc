"""Figures reused across reports: a point whose inputs did not change is not drawn again.

After a point's figures are written, ``DIR/plots/.figures/PPPP.json`` records their names and
a key: SHA-256 of the point as read from the store (settings, orbit tables, stored fits, truth),
the report options (figure kinds, frequencies, style) and the source of the code that draws
them (orbitrig.analysis, reduction, the plain data of orbitrig.store.stored_run, the units of
rigunits) with the matplotlib version. A later report with the same key, whose files are all present in every
format, reuses them. The record is removed before a
point is drawn, so a report cut short never leaves a record of half-drawn figures. A report
written elsewhere (``orbitrig report --out``) takes the figures of the run's own ``DIR/plots``
(drawn by the sweep or an earlier report) whose key matches its request as copies, recorded in
its own folder; it never writes into the run.
"""

from __future__ import annotations

import functools
import hashlib
import json
import pickle
from pathlib import Path

from orbitrig.store.durable import remove, write_atomic
from orbitrig.store.errors import storage_error

CACHE_DIR = ".figures"


@functools.cache
def _code_digest() -> str:
    """SHA-256 of the drawing and reduction code (a new version draws every figure again), with
    the stored run's plain data the figures draw and the units their texts are written in (rigunits)."""
    import matplotlib

    import orbitrig.analysis
    import reduction
    import rigunits
    from orbitrig.store import stored_run

    h = hashlib.sha256(matplotlib.__version__.encode())
    for package in (orbitrig.analysis, reduction):
        for source in sorted(Path(package.__path__[0]).glob("*.py")):  # the folder of its __init__.py
            h.update(source.name.encode() + source.read_bytes())
    h.update(Path(stored_run.__file__).read_bytes())
    h.update(Path(rigunits.__file__).read_bytes())
    return h.hexdigest()


def point_key(point, options) -> str:
    """The key of one point's figures (stored Point, ReportOptions)."""
    h = hashlib.sha256(_code_digest().encode())
    h.update(repr((sorted(options.figures), options.all_frequencies, options.style)).encode())
    h.update(pickle.dumps(point, protocol=5))
    return h.hexdigest()


def _record(out: Path, name: str) -> Path:
    return out / CACHE_DIR / f"{name}.json"


def reuse(pr, out: Path, key: str, formats) -> bool:
    """Fill `pr.plots` and `pr.unreadable` from the record of point `pr.point` when its key is
    `key` and every figure is there in every format; False (nothing changed) otherwise."""
    try:
        record = json.loads(_record(out, pr.point.name).read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):  # damaged (nested too deeply: RecursionError): drawn again
        return False
    if not isinstance(record, dict) or record.get("key") != key:
        return False
    pngs = [out / name for name in record.get("plots", [])]
    if not all(png.with_suffix(f".{fmt}").is_file() for png in pngs for fmt in formats):
        return False
    pr.plots, pr.unreadable = pngs, list(record.get("unreadable", []))
    return True


def forget(out: Path, name: str) -> None:
    """Remove the record of point `name` (its figures are about to be drawn again)."""
    remove(_record(out, name))


def remember(pr, out: Path, key: str) -> None:
    """Record the figures just drawn for point `pr.point` under `key`."""
    path = _record(out, pr.point.name)
    try:
        path.parent.mkdir(exist_ok=True)
    except OSError as err:
        raise storage_error(path.parent, "create the folder", err) from err
    record = {"key": key, "plots": [p.name for p in pr.plots], "unreadable": pr.unreadable}
    write_atomic(path, json.dumps(record, indent=1).encode())


def adopt(pr, source: Path, out: Path, key: str, formats) -> bool:
    """Reuse the figures of point `pr.point` recorded in `source` (a run's own DIR/plots, only
    read) under `key`, every one present in every format of `formats`: copied into `out` and
    recorded there, `pr.plots` naming the copies; False (`pr` as it was) otherwise."""
    if not reuse(pr, source, key, formats):
        return False
    try:
        files = {
            png.with_suffix(f".{fmt}"): png.with_suffix(f".{fmt}").read_bytes() for png in pr.plots for fmt in formats
        }
    except OSError:  # removed or unreadable since the check: drawn again
        pr.plots, pr.unreadable = [], []
        return False
    for path, data in files.items():
        write_atomic(out / path.name, data)
    pr.plots = [out / png.name for png in pr.plots]
    remember(pr, out, key)
    return True

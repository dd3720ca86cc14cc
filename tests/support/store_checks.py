"""Checks shared by the storage tests: a run directory reads back whole."""

from __future__ import annotations

import contextlib
import csv
import errno
import json
import time
from pathlib import Path

import h5py

from orbitrig.store.index import scan
from orbitrig.store.layout import RunLayout
from orbitrig.store.reader import read_run


def small_matrix(name: str, revolutions: int, spin_rpm: tuple[float, ...] = (1000.0, 2000.0)) -> str:
    """A test matrix of the storage tests: one kc8 model, 3 orbit ratios x both directions
    per point, one point per spin speed."""
    return f"""
name = "{name}"
revolutions = {revolutions}
[operating]
spin_rpm = {list(spin_rpm)}
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.4]
static_eccentricity = [0.0]
dynamic_eccentricity = [0.096]
[orbit]
ratios = [0.3, 0.6, 0.9]
[[models]]
model = "kc8"
"""


def read_all(path: Path) -> int:
    """Open an HDF5 file and read every dataset in full; return how many."""
    n = []

    def visit(_name, obj):
        if isinstance(obj, h5py.Dataset):
            obj[()]
            n.append(1)

    with h5py.File(path, "r") as f:
        f.visititems(visit)
    return len(n)


def check_whole(run_dir: Path, points: list[int], blocks_per_point: int) -> None:
    """Every point complete exactly once with all its blocks; every file reads back whole."""
    layout = RunLayout(run_dir)
    states = scan(layout)
    assert [(s.index, s.complete) for s in states] == [(i, True) for i in points], states
    run = read_run(run_dir)
    assert [p.index for p in run.points] == points and all(p.complete for p in run.points)
    for p in run.points:
        assert len(p.frequencies) == blocks_per_point and len({f.name for f in p.frequencies}) == blocks_per_point
        assert set(p.tables) == {"piezo", "strain"}
    for h5 in layout.points.rglob("*.h5"):
        assert read_all(h5) > 0, h5
    for js in layout.points.rglob("*.json"):
        json.loads(js.read_text())
    assert not list(layout.points.rglob("*.tmp")), "a temporary file left inside a committed point"
    rows = list(csv.DictReader(open(layout.csv, encoding="utf-8")))
    keys = [(r["point"], r["lms"], r["model"], r["freq_dep"], r["method"]) for r in rows]
    assert len(keys) == len(set(keys)), "a point stored twice in coefficients.csv"
    assert sorted({int(r["point"]) for r in rows}) == points
    assert read_all(layout.run_file) > 0
    with h5py.File(layout.run_file, "r") as f:
        assert sorted(int(n) for n in f["points"]) == points
        assert all(bool(g.attrs["complete"]) for g in f["points"].values())


def fill(mnt: Path) -> Path:
    """Write zeros into mnt/filler until the file system is full (again, when the run frees
    space meanwhile: it drops its growing run.h5.tmp at the first failed write)."""
    path = mnt / "filler"
    probe = mnt / "probe"
    with open(path, "wb", buffering=0) as fh:
        for _ in range(50):
            for size in (65536, 512):
                with contextlib.suppress(OSError):
                    while True:
                        fh.write(b"\0" * size)
            try:
                probe.write_bytes(b"\0" * 8192)
            except OSError as err:
                assert err.errno == errno.ENOSPC
                break
            probe.unlink()
            time.sleep(0.05)
        else:
            raise AssertionError(f"{mnt} never stayed full")
    probe.unlink(missing_ok=True)
    return path

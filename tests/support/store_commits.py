"""A run of synthetic points committed one by one through the sweep's own storage
(orbitrig.store.writer.RunStore), and a count of the bytes the store hashes to check its
points against their commit records: what tests/store/test_store_commit_hashing.py and
bench/bench_store_commit.py measure the per-point commit path with.

Every point has the same blocks (random counts of the given size) and the same results (one
identification, made once), so what a commit costs can be compared from the first point to
the last."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from orbitrig import config as cfg
from orbitrig.run.identification import identify_operating_point
from orbitrig.run.plan import operating_points
from orbitrig.store import index
from orbitrig.store.records import BlockRecord
from orbitrig.store.writer import RunStore

MATRIX = """
name = "commits"
revolutions = {revolutions}
[operating]
spin_rpm = {spins}
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.25]
static_eccentricity = [0.0]
dynamic_eccentricity = [0.096]
[orbit]
ratios = {ratios}
directions = ["forward", "backward"]
[[models]]
model = "kcd11"
"""
SAMPLES = 45  # per channel and revolution: 360 slots over 8 channels


@dataclass
class Hashed:
    """Bytes and files the store's integrity checks hashed (orbitrig.store.index.digest)."""

    bytes: int = 0
    files: int = 0
    paths: list[Path] = field(default_factory=list)

    def take(self) -> int:
        """The bytes hashed since the last take."""
        n, self.bytes = self.bytes, 0
        return n


@contextlib.contextmanager
def counting_hashes() -> Iterator[Hashed]:
    """Count every file the store hashes to check a point against its commit record, while inside."""
    seen = Hashed()
    real = index.digest

    def counted(path: Path) -> tuple[int, str]:
        size, sha = real(path)
        seen.bytes, seen.files = seen.bytes + size, seen.files + 1
        seen.paths.append(Path(path))
        return size, sha

    index.digest = counted
    try:
        yield seen
    finally:
        index.digest = real


def block_record(block, revolutions: int, rng: np.random.Generator) -> BlockRecord:
    """A block of `revolutions` revolutions of random counts and phasors, stored as the engine stores one."""
    ph = rng.standard_normal(8) + 1j * rng.standard_normal(8)
    return BlockRecord(
        block=block,
        measured_orbit_speed=abs(block.orbit),
        raw_counts=rng.integers(-3000, 3000, (revolutions, 8, SAMPLES), dtype=np.int16),
        slots=np.arange(8 * SAMPLES, dtype=np.int16).reshape(SAMPLES, 8).T,
        gains=np.full(8, 1e-3),
        offsets=np.zeros(8),
        mean=rng.standard_normal((8, SAMPLES)),
        record_phasors=ph * (1 + 0.01 * rng.standard_normal((revolutions, 8))),
        phasors=ph,
        dc=np.zeros(8),
        rms_residual=np.zeros(8),
        coherence=np.full((2, 4), 0.99),
        uncertainty=np.abs(ph) * 1e-3,
        n_records=revolutions,
        stop_reason="count",
        stats={"frames_good": revolutions},
    )


def commit_points(
    out: Path,
    n_points: int,
    *,
    blocks: int = 8,
    revolutions: int = 4,
    on_commit: Callable[[int, float, float], None] | None = None,
) -> RunStore:
    """A new run in `out` of `n_points` points of `blocks` blocks (orbit frequencies x 2 directions)
    of `revolutions` revolutions each, each point committed; `on_commit(index, wall, cpu)` is told
    the seconds of each point's commit path (results, commit record, coefficients.csv, its copy
    into run.h5.tmp): wall, and the CPU time of the thread committing (what other processes on
    the machine do not change). Returns the store, its run not ended."""
    import time

    rig = cfg.load_rig()
    ratios = [round(0.1 + 0.05 * k, 3) for k in range(blocks // 2)]
    spins = [1000.0 + 10.0 * k for k in range(n_points)]
    text = MATRIX.format(revolutions=revolutions, spins=spins, ratios=ratios)
    matrix = cfg.matrix_from_text(text, "commits.toml")
    store = RunStore.create(out, rig_text=rig.text, matrix_text=matrix.text, matrix_name=matrix.name, sim=False)
    rng = np.random.default_rng(1)
    results = None
    for p in operating_points(matrix, rig):
        store.begin_point(p)
        recs = [block_record(b, revolutions, rng) for b in p.blocks]
        for rec in recs:
            store.write_block(p.index, rec)
        if results is None:  # the same results for every point: the commit path is what is measured
            results = identify_operating_point(p.spin, recs, rig.channel_index, matrix.models)
        t, cpu = time.perf_counter(), time.thread_time()
        store.write_results(p.index, results)
        store.complete_point(p.index)
        if on_commit is not None:
            on_commit(p.index, time.perf_counter() - t, time.thread_time() - cpu)
    return store


def point_bytes(out: Path, point: int) -> int:
    """Bytes of the files of point `point` of the run in `out` (its commit record left out)."""
    d = out / "points" / f"{point:04d}"
    return sum(f.stat().st_size for f in d.iterdir() if f.is_file() and f.name != "complete.json")

"""Storage cost of the durable run directory (orbitrig.store).

Writes a synthetic run of paper-sized blocks (50 revolutions x 8 channels x 45 samples)
with the sweep's own RunStore and prints

- per block: building the HDF5 file in memory + write + fsync + rename + fsync of the
  directory + the journal append (median, 95th percentile, max),
- per point: results file, commit record, coefficients.csv and the copy of the point into
  the run.h5 built in memory,
- what is left for the end of the run (status, logs, writing run.h5), and the file sizes,
- the byte estimate of orbitrig.store.estimate against what was written.

    python3 -m bench.bench_store [--points 6] [--blocks 20] [--revolutions 50] [--dir DIR]

--dir puts the run on another file system (the default temporary directory is often tmpfs,
where fsync costs nothing; the rig writes to a disk).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from orbitrig import config as cfg
from orbitrig.run.identification import identify_operating_point
from orbitrig.run.plan import make_plan, operating_points
from orbitrig.store.estimate import plan_bytes
from orbitrig.store.writer import RunStore
from orbitrig.store.status import RunStatus
from tests.support.store_commits import block_record

MATRIX = """
name = "bench-store"
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
[[models]]
model = "kc8"
"""


def _ms(xs: list[float]) -> str:
    xs = sorted(xs)
    p95 = xs[min(len(xs) - 1, int(0.95 * len(xs)))]
    return f"median {1e3 * statistics.median(xs):7.2f} ms, p95 {1e3 * p95:7.2f} ms, max {1e3 * xs[-1]:7.2f} ms"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--points", type=int, default=6)
    ap.add_argument("--blocks", type=int, default=20, help="orbit frequencies x directions per point (even)")
    ap.add_argument("--revolutions", type=int, default=50)
    ap.add_argument("--dir", type=Path, default=None)
    args = ap.parse_args()
    rig = cfg.load_rig()
    ratios = [round(0.1 + 0.05 * k, 3) for k in range(args.blocks // 2)]
    spins = [1000.0 + 10.0 * k for k in range(args.points)]
    matrix = cfg.matrix_from_text(MATRIX.format(revolutions=args.revolutions, spins=spins, ratios=ratios), "bench.toml")
    out = Path(tempfile.mkdtemp(prefix="bench-store-", dir=args.dir)) / "run"
    rng = np.random.default_rng(1)
    store = RunStore.create(out, rig_text=rig.text, matrix_text=matrix.text, matrix_name=matrix.name, sim=False)
    per_block, per_point, per_identify = [], [], []
    for p in operating_points(matrix, rig):
        store.begin_point(p)
        recs = []
        for b in p.blocks:
            recs.append(block_record(b, args.revolutions, rng))
            t = time.perf_counter()
            store.write_block(p.index, recs[-1])
            per_block.append(time.perf_counter() - t)
        t = time.perf_counter()
        results = identify_operating_point(p.spin, recs, rig.channel_index, matrix.models)
        per_identify.append(time.perf_counter() - t)
        t = time.perf_counter()
        store.write_results(p.index, results)
        store.complete_point(p.index)
        per_point.append(time.perf_counter() - t)
    pieces = sum(f.stat().st_size for f in out.rglob("*") if f.is_file())
    t = time.perf_counter()
    store.set_status(RunStatus.COMPLETED, "bench")  # consolidates run.h5
    consolidate = time.perf_counter() - t
    size = (out / "run.h5").stat().st_size
    block_size = (out / "points/0000" / f"{operating_points(matrix, rig)[0].blocks[0].tag}.h5").stat().st_size
    print(f"run in {out}: {args.points} points x {args.blocks} blocks of {args.revolutions} revolutions")
    print(f"block write + fsync + rename (+ journal): {_ms(per_block)}   ({block_size / 1e3:.1f} kB each)")
    print(f"point results + commit + CSV + run.h5 copy: {_ms(per_point)}")
    print(f"  (identification of the point, for scale: {_ms(per_identify)})")
    print(
        f"run.h5 at the end (status, logs, write): {consolidate:.3f} s for {size / 1e6:.2f} MB "
        f"({consolidate / max(1, args.points):.3f} s per point); pieces {pieces / 1e6:.2f} MB"
    )
    est = plan_bytes(rig, list(make_plan(matrix, rig).steps))
    print(f"estimate (plan_bytes) {est / 1e6:.2f} MB for {(pieces + size) / 1e6:.2f} MB written")


if __name__ == "__main__":
    main()

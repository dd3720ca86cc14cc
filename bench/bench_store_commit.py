"""The per-point commit path of the durable run directory over a run (orbitrig.store.writer):
does committing point N cost what committing point 1 did?

Writes a synthetic run as long as the paper's matrix (108 points) of paper-sized blocks (--blocks
per point, --revolutions x 8 channels x 45 samples each) with the sweep's own RunStore and times,
per point, its commit path: the results file, the commit record, coefficients.csv and the copy of
the point into run.h5.tmp. Prints the median wall and CPU time of the first and of the last
--window points and the bytes the store hashed to check points against their commit records in
those commits (tests.support.store_commits), then the run's end (each point verified once before
run.h5 is consolidated).

    python3 -m bench.bench_store_commit [--points 108] [--blocks 20] [--revolutions 50] [--dir DIR]

Exit 1 when the last points' median commit takes more CPU than 1.5 x the first points' + 30 ms
(CPU time of the committing thread: other processes on a shared machine do not change it; the
margin holds what grows with the run by design, coefficients.csv rewritten whole), or when a
commit hashes more than its own point's files (a commit that checks the points before it again
grows with N: O(n^2) over a run).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

from orbitrig.store.status import RunStatus
from tests.support.store_commits import commit_points, counting_hashes, point_bytes

RATIO, SLACK_S = 1.5, 0.030  # the last points' median commit may take 1.5 x the first's CPU + 30 ms


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--points", type=int, default=108)
    ap.add_argument("--blocks", type=int, default=20, help="orbit frequencies x directions per point (even)")
    ap.add_argument("--revolutions", type=int, default=50)
    ap.add_argument("--window", type=int, default=5, help="points averaged at each end")
    ap.add_argument("--dir", type=Path, default=None, help="put the run on this file system (default: temp)")
    args = ap.parse_args()
    out = Path(tempfile.mkdtemp(prefix="bench-store-commit-", dir=args.dir)) / "run"
    wall: list[float] = []
    cpu: list[float] = []
    hashed_per_commit: list[int] = []
    with counting_hashes() as hashed:

        def committed(index: int, s: float, c: float) -> None:
            wall.append(s)
            cpu.append(c)
            hashed_per_commit.append(hashed.take())

        store = commit_points(out, args.points, blocks=args.blocks, revolutions=args.revolutions, on_commit=committed)
        t = time.perf_counter()
        store.set_status(RunStatus.COMPLETED, "bench")  # verifies every point, consolidates run.h5
        end_s, end_hashed = time.perf_counter() - t, hashed.take()
    w = min(args.window, args.points // 2)
    first, last = statistics.median(cpu[:w]), statistics.median(cpu[-w:])
    first_wall, last_wall = statistics.median(wall[:w]), statistics.median(wall[-w:])
    own = [point_bytes(out, i) for i in range(args.points)]
    worst = max(range(args.points), key=lambda i: hashed_per_commit[i] - own[i])
    total = sum(own)
    print(f"run in {out}: {args.points} points x {args.blocks} blocks of {args.revolutions} revolutions")
    print(f"pieces {total / 1e6:.1f} MB ({own[0] / 1e6:.2f} MB per point)")
    print(
        f"commit path, median of points 1-{w}: {1e3 * first:.1f} ms CPU ({1e3 * first_wall:.1f} ms wall); "
        f"of the last {w}: {1e3 * last:.1f} ms CPU ({1e3 * last_wall:.1f} ms wall)"
    )
    print(
        f"hashed per commit: point 1 {hashed_per_commit[0] / 1e6:.2f} MB, point {args.points} "
        f"{hashed_per_commit[-1] / 1e6:.2f} MB (its own files {own[-1] / 1e6:.2f} MB)"
    )
    print(f"run's end (every point verified, run.h5 written): {end_s:.2f} s, {end_hashed / 1e6:.1f} MB hashed")
    misses = []
    if last > RATIO * first + SLACK_S:
        misses.append(f"commit CPU grows with N: {1e3 * last:.1f} ms > {RATIO} x {1e3 * first:.1f} ms + 30 ms")
    if hashed_per_commit[worst] > own[worst]:
        misses.append(
            f"commit of point {worst + 1} hashed {hashed_per_commit[worst]} bytes, its own files {own[worst]}"
        )
    for miss in misses:
        print(f"MISS: {miss}")
    sys.exit(1 if misses else 0)


if __name__ == "__main__":
    main()

"""Cost of `orbitrig report` on the paper's test matrix: 108 operating points of ~17 figures
each must be reported in under 2 minutes with 2 worker processes, cold (no figure drawn before).

Synthesises a run of N points (tests/support/report_synthetic.py: the sweep's own storage,
the paper's 10 ratios x 2 directions and 4 models, the same 17 figures per point; writing 108
points takes several minutes, so `--run DIR` keeps it for the next bench) and times `orbitrig
report DIR --workers 2` end to end in a subprocess: cold with the defaults (PNG 300 dpi,
report.pdf from the PNGs), again on the unchanged run (every figure reused), after a sweep (the
figures of every point but the last drawn during the sweep, as `orbitrig sweep` leaves them:
orbitrig.analysis.report_ahead draws each completed point and is stopped with the sweep) and
cold with `--formats png,pdf,svg` (vector files of every figure; `--vector` only). With fewer
than 108 points the time is extrapolated linearly to 108 (the points are independent; the
summary figure and report.pdf are a small part). On a shared machine the wall time says
little: the CPU seconds of the report and its workers, divided by the workers, say what idle
cores would take. Prints one line per measurement and exits 1 when the cold 108-point default
report (the smaller projection) takes 2 minutes or more.

Run: python3 -m bench.bench_report [--points 108] [--workers 2] [--run DIR] [--vector]
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tests.support.report_synthetic import write_synthetic_run

ROOT = Path(__file__).resolve().parents[1]
PAPER_POINTS = 108
TARGET_S = 120.0


def _children_cpu() -> float:
    """CPU seconds of the finished children (the report and, through it, its workers)."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def measure(run: Path, args: list[str], workers: int, label: str, points: int) -> float:
    """`orbitrig report RUN ARGS --workers N`; print wall and CPU seconds, figures and the
    108-point projection (wall; CPU / workers, what idle cores would take); return the smaller."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    t0, cpu0 = time.perf_counter(), _children_cpu()
    done = subprocess.run(
        [sys.executable, "-m", "orbitrig", "report", str(run), "--workers", str(workers), *args],
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    dt, cpu = time.perf_counter() - t0, _children_cpu() - cpu0
    if done.returncode != 0:
        sys.exit(f"{label}: orbitrig report exited {done.returncode}: {done.stderr.strip()[-2000:]}")
    figures = len(list((run / "plots").glob("*.png")))
    wall, idle = dt * PAPER_POINTS / points, cpu / workers * PAPER_POINTS / points
    print(
        f"{label:28s} {points:3d} points, {figures:4d} figures: {dt:6.1f} s wall, {cpu:6.1f} s CPU "
        f"({cpu / figures:.2f} CPU s per figure); {PAPER_POINTS} points: {wall:5.0f} s wall, "
        f"{idle:5.0f} s on {workers} idle cores (load average {os.getloadavg()[0]:.1f})",
        flush=True,
    )
    return min(wall, idle)


def synthetic(directory: Path, points: int) -> Path:
    """The synthetic run in `directory` (written when absent or of another size), plots removed."""
    run = directory / f"run{points}"
    if not (run / "run.h5").exists():
        shutil.rmtree(run, ignore_errors=True)
        t0 = time.perf_counter()
        write_synthetic_run(run, n_points=points, incomplete=0)
        print(f"synthetic run, {points} points x 20 orbit frequencies: {time.perf_counter() - t0:.1f} s", flush=True)
    shutil.rmtree(run / "plots", ignore_errors=True)
    return run


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=PAPER_POINTS)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--run", type=Path, help="folder keeping the synthetic run between benches")
    ap.add_argument("--vector", action="store_true", help="also time --formats png,pdf,svg")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        run = synthetic(args.run or Path(tmp), args.points)
        cold = measure(run, [], args.workers, "cold, default (png, pdf)", args.points)
        measure(run, [], args.workers, "again, run unchanged", args.points)
        max((run / "plots" / ".figures").glob("*.json")).unlink()  # the last point: not drawn ahead
        measure(run, [], args.workers, "after a sweep", args.points)
        if args.vector:
            shutil.rmtree(run / "plots")
            measure(run, ["--formats", "png,pdf,svg"], args.workers, "--formats png,pdf,svg", args.points)
    ok = cold < TARGET_S
    print(
        f"{'PASS' if ok else 'MISS'}: cold {PAPER_POINTS}-point report {cold:.0f} s with {args.workers} workers "
        f"(target < {TARGET_S:.0f} s)"
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

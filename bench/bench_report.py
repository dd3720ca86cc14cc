"""Cost of `orbitrig report` on the paper's test matrix: 108 operating points of ~17 figures
each must be reported in under 2 minutes with 2 worker processes.

Synthesises a run of N points (tests/report/report_synthetic.py: the sweep's own storage,
the paper's 10 ratios x 2 directions and 4 models, the same 17 figures per point) and times
`make_report` with the default style (PNG 300 dpi, PDF, SVG, report.pdf) and 2 workers, then
PNG only. With fewer than 108 points the time is extrapolated linearly to 108 (the points are
independent; the summary figure and report.pdf are a small part). On a shared machine the
wall time says little: the CPU seconds of the main process and the workers, divided by the
workers, say what idle cores would take. Prints one line per measurement and exits 1 when
the 108-point report (the smaller projection of the default style) takes 2 minutes or more.

Run: python3 bench/bench_report.py [--points 108] [--workers 2]
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "report"))

from report_synthetic import write_synthetic_run  # noqa: E402

from orbitrig.analysis.plots import FigureFormat, FigureStyle  # noqa: E402
from orbitrig.analysis.report import ReportOptions, make_report  # noqa: E402

PAPER_POINTS = 108
TARGET_S = 120.0


def _cpu() -> float:
    """CPU seconds of this process and of its finished children (the pool's workers)."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def measure(run: Path, style: FigureStyle, workers: int, label: str, points: int) -> float:
    """Report `run` in `style`; print wall and CPU seconds, figures and the 108-point projection
    (wall time; on a shared machine also CPU time / workers, what idle cores would take); return
    the smaller projection."""
    t0, cpu0 = time.perf_counter(), _cpu()
    report = make_report(run, options=ReportOptions(style=style), workers=workers)
    dt, cpu = time.perf_counter() - t0, _cpu() - cpu0
    figures = len(report.plots)
    wall, idle = dt * PAPER_POINTS / points, cpu / workers * PAPER_POINTS / points
    print(f"{label:24s} {points:3d} points, {figures:4d} figures: {dt:6.1f} s wall, {cpu:6.1f} s CPU "
          f"({cpu / figures:.2f} CPU s per figure); {PAPER_POINTS} points: {wall:5.0f} s wall, "
          f"{idle:5.0f} s on {workers} idle cores (load average {os.getloadavg()[0]:.1f})", flush=True)  # fmt: skip
    return min(wall, idle)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=PAPER_POINTS)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        run = write_synthetic_run(Path(tmp) / "run", n_points=args.points, incomplete=0)
        print(f"synthetic run, {args.points} points x 20 orbit frequencies: {time.perf_counter() - t0:.1f} s", flush=True)
        projected = measure(run, FigureStyle(), args.workers, "default (png, pdf, svg)", args.points)
        measure(run, FigureStyle(formats=(FigureFormat.PNG,)), args.workers, "--formats png", args.points)
    ok = projected < TARGET_S
    print(f"{'PASS' if ok else 'MISS'}: {PAPER_POINTS}-point report {projected:.0f} s with {args.workers} workers "
          f"(target < {TARGET_S:.0f} s)")  # fmt: skip
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

"""Cost of `orbitrig report`: seconds per figure kind and per operating point, and what a
report of the paper's whole test matrix (108 operating points) costs.

Makes a run on the simulator with the paper's orbit frequencies and models but two
operating points (`orbitrig sweep --sim`, a few seconds), then times the report of each
figure kind alone and of everything, and extrapolates to the 108 points of
config/matrices/paper.toml (the report draws each point independently).

Run: python3 bench/bench_report.py [--points 2]   (prints one line per figure)
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from orbitrig import config as cfg  # noqa: E402
from orbitrig.analysis.report import FIGURES, ReportOptions, make_report  # noqa: E402

PAPER_POINTS = 108


def small_paper_matrix(points: int) -> str:
    """The paper's matrix with `points` operating points (static eccentricities) and 20 revolutions."""
    text = cfg.default_matrix_path("paper").read_text()
    eps = ", ".join(f"{0.15 * i:g}" for i in range(points))
    lines = []
    for line in text.splitlines():
        key = line.split("=")[0].strip()
        if key == "name":
            line = 'name = "bench-report"\nrevolutions = 20'
        elif key in ("spin_rpm", "recess_pressure_mpa", "pressure_ratio", "dynamic_eccentricity"):
            line = f"{key} = [{line.split('[')[1].split(',')[0].rstrip(']')}]"
        elif key == "static_eccentricity":
            line = f"static_eccentricity = [{eps}]"
        lines.append(line)
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=2)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        matrix = Path(tmp) / "bench.toml"
        matrix.write_text(small_paper_matrix(args.points))
        run = Path(tmp) / "run"
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "orbitrig", "sweep", "--sim", "--matrix", str(matrix), "--out", str(run)],
                       cwd=ROOT, check=True, capture_output=True)  # fmt: skip
        print(f"sweep --sim, {args.points} points x 20 frequencies: {time.perf_counter() - t0:.1f} s")
        for kind in FIGURES:
            t0 = time.perf_counter()
            report = make_report(run, options=ReportOptions(figures=frozenset({kind})))
            dt = time.perf_counter() - t0
            n = sum(1 for pr in report.points for p in pr.plots if Path(p).stem.startswith(kind))
            print(f"{kind:13s} {n:3d} figure(s) {dt:6.2f} s  ({dt / max(n, 1):.2f} s per figure, page and tables included)")
        t0 = time.perf_counter()
        report = make_report(run)
        dt = time.perf_counter() - t0
        n = len(report.plots)
        per_point = dt / len(report.points)
        print(f"everything    {n:3d} figure(s) {dt:6.2f} s  ({per_point:.1f} s per point)")
        t0 = time.perf_counter()
        make_report(run, options=ReportOptions(figures=frozenset()))
        tables = time.perf_counter() - t0
        print(f"page and tables only (--figures ''): {tables:.2f} s")
        print(f"paper matrix ({PAPER_POINTS} points), extrapolated: {PAPER_POINTS * per_point / 60:.1f} min "
              f"for everything; one point (--point N): {per_point:.1f} s")  # fmt: skip


if __name__ == "__main__":
    main()

"""`orbitrig identify` on long tables: cost linear in rows, memory bounded.

Writes orbit tables of 100,000 and 1,000,000 rows (kcd11 truth, forward and backward circles
at random frequencies 0.2..1.2 x spin, 1 % force noise, u_* columns), runs
`python -m orbitrig identify TABLE --model kcd11 --json` on one core (CPU affinity and one
BLAS thread) and reports the wall time and the peak resident memory of the run.
Target: the 1,000,000-row table in under 20 s and under 1 GB; exits 1 when missed. The time
judged is the run's CPU time (user + system), which is its wall time on an idle core and
stays meaningful on a shared machine; the wall time is printed beside it.

Run: python3 -m bench.bench_identify_long [ROWS ...]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from rigunits import RPM

ROOT = Path(__file__).resolve().parents[1]
TARGET_ROWS, TARGET_S, TARGET_MB = 1_000_000, 20.0, 1000.0
SPIN_RPM = 3000.0
K = np.array([[3.3e7, 1.1e7], [-0.9e7, 2.9e7]])
C = np.array([[4.0e4, 0.6e4], [0.8e4, 3.6e4]])
D = np.array([[12.0, 1.5], [1.5, 10.0]])


def write_table(path: Path, rows: int, seed: int = 0) -> None:
    """A kcd11 orbit table of ``rows`` rows (f = -Z d, Z = K + i Omega C - Omega^2 D)."""
    rng = np.random.default_rng(seed)
    spin = SPIN_RPM * RPM
    w = rng.uniform(0.2, 1.2, rows) * spin
    radius = 5e-6
    x = np.full(rows, radius, dtype=complex)
    y = np.where(rng.random(rows) < 0.5, -1j, 1j) * radius
    Z = K[None] + 1j * w[:, None, None] * C[None] - w[:, None, None] ** 2 * D[None]
    fx, fy = -(Z[:, 0, 0] * x + Z[:, 0, 1] * y), -(Z[:, 1, 0] * x + Z[:, 1, 1] * y)
    s = 0.01 * np.sqrt(np.mean(np.abs(fx) ** 2))
    fx = fx + s / np.sqrt(2) * (rng.standard_normal(rows) + 1j * rng.standard_normal(rows))
    fy = fy + s / np.sqrt(2) * (rng.standard_normal(rows) + 1j * rng.standard_normal(rows))
    cols = [
        np.full(rows, SPIN_RPM),
        w / (2 * np.pi),
        x.real,
        x.imag,
        y.real,
        y.imag,
        fx.real,
        fx.imag,
        fy.real,
        fy.imag,
        np.full(rows, 20e-9),
        np.full(rows, 20e-9),
        np.full(rows, s),
        np.full(rows, s),
    ]
    header = "spin_rpm,orbit_hz,x_re,x_im,y_re,y_im,fx_re,fx_im,fy_re,fy_im,u_x,u_y,u_fx,u_fy"
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=header, comments="", fmt="%.17g")


def run(path: Path) -> tuple[float, float, float, dict]:
    """(wall time s, CPU time s, peak RSS MB, result) of one identify run on one core."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    core = min(os.sched_getaffinity(0))
    out_path, err_path = path.with_suffix(".json"), path.with_suffix(".err")
    with open(out_path, "w") as out, open(err_path, "w") as err:
        start = time.perf_counter()
        p = subprocess.Popen(
            [sys.executable, "-m", "orbitrig", "identify", str(path), "--model", "kcd11", "--json"],
            cwd=ROOT,
            env=env,
            stdout=out,
            stderr=err,
            preexec_fn=lambda: os.sched_setaffinity(0, {core}),
        )
        _, status, usage = os.wait4(p.pid, 0)  # this child's own peak memory
        elapsed = time.perf_counter() - start
    p.returncode = os.waitstatus_to_exitcode(status)
    if p.returncode != 0:
        sys.exit(f"identify failed (exit {p.returncode}): {err_path.read_text()[-2000:]}")
    return elapsed, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024, json.loads(out_path.read_text())


def main() -> None:
    parser = argparse.ArgumentParser(prog="python3 -m bench.bench_identify_long", description=__doc__.split("\n\n")[0])
    parser.add_argument("rows", type=int, nargs="*", help=f"table sizes to identify (default 100000 and {TARGET_ROWS})")
    sizes = parser.parse_args().rows or [100_000, TARGET_ROWS]
    ok = True
    with tempfile.TemporaryDirectory() as tmp:
        for rows in sizes:
            path = Path(tmp) / f"table-{rows}.csv"
            write_table(path, rows)
            elapsed, cpu, mb, result = run(path)
            kxx = result["coefficients"]["Kxx"]
            print(
                f"identify kcd11, {rows} rows ({path.stat().st_size / 1e6:.0f} MB CSV), one core: CPU {cpu:.1f} s "
                f"(wall {elapsed:.1f} s), peak {mb:.0f} MB; Kxx = {kxx:.4g} N/m (true {K[0, 0]:.4g}), "
                f"{len(result['fit'])} fit rows"
            )
            if rows == TARGET_ROWS:
                met = cpu < TARGET_S and mb < TARGET_MB
                ok &= met
                print(
                    f"target {TARGET_ROWS} rows under {TARGET_S:g} s and {TARGET_MB:g} MB: "
                    + ("met" if met else "NOT met")
                )
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()

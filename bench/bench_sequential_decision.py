"""How long a sequential point's decision keeps the rig waiting.

After each block of a sequential point (matrix [orbit] sequential = true) the engine plans
the rest of the point (reduction.sequential.next_block, reduction.completion) before it can
move the orbit drive: the rig idles for as long as that takes. This bench runs the decisions
of one point as the engine's worker thread does (one BLAS thread, as every orbitrig command),
the nominal kcd11 bearing at 1000 rpm, matching the paper's ten ratios at 50 revolutions
from a five-ratio spread at 10, each direction a block, the drives' band on the 0.05 grid,
and prints each decision's wall time over several repeats.

Target: the slowest decision under 0.5 s (a quarter of the settle hold every block waits
anyway; the first decision also imports scipy.optimize once per process, timed apart).

    python3 -m bench.bench_sequential_decision [--repeats 5]
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from orbitrig.cli.design_inputs import NOMINAL
from reduction.frequency_list import allowed_ratios
from reduction.models import model_spec
from reduction.rig_time import list_time
from reduction.sequential import block_information, next_block, reference_errors
from reduction.whirl import Directions
from rigunits import RPM

TARGET_S = 0.5
SPIN = 1000 * RPM
U = np.array([20e-9, 20e-9, 15.0, 15.0])  # per-revolution noise: x, y (m), fx, fy (N)
RADIUS = 2.4e-6
PAPER = [0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.1, 1.2]
SPREAD = [0.2, 0.4, 0.65, 0.8, 1.2]
OVERHEAD = 2.05  # settle hold + store, s
RAMP = 600 * RPM  # rad/s per s
DIRECTIONS = (Directions.FORWARD, Directions.BACKWARD)


def noise_at(r):
    return np.broadcast_to(U, (np.size(r), 4))


def one_point() -> list[float]:
    """Wall seconds of each decision of one point, the stop included."""
    spec = model_spec("kcd11")
    theta = np.array([NOMINAL.get(n, 0.0) for n in spec.names])
    grid = allowed_ratios(0.1, 1.5)
    scales = reference_errors(spec, theta, SPIN, RADIUS, np.array(PAPER), noise_at(PAPER), 50)
    info = sum(block_information(spec, theta, SPIN, RADIUS, r, U, 10) for r in SPREAD)
    spent, orbit, times = list_time(SPREAD, SPIN, 10) + 20 * OVERHEAD, -SPREAD[-1] * SPIN, []
    while True:
        t0 = time.perf_counter()
        nb = next_block(
            spec,
            theta,
            SPIN,
            RADIUS,
            info,
            grid,
            noise_at,
            scales,
            target=1.0,
            spent_s=spent,
            cap_s=600.0,
            per_block_s=OVERHEAD,
            directions=DIRECTIONS,
            orbit_now=orbit,
            ramp_rate=RAMP,
        )
        times.append(time.perf_counter() - t0)
        if nb.ratio is None:
            return times
        info = info + block_information(spec, theta, SPIN, RADIUS, nb.ratio, U, nb.revolutions, nb.direction)
        spent, orbit = spent + nb.seconds, nb.direction.whirls[0].sign * nb.ratio * SPIN


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    t0 = time.perf_counter()
    import scipy.optimize  # noqa: F401  (what the first decision of a process also pays)

    print(f"first import of scipy.optimize   {time.perf_counter() - t0:.2f} s (once per process)")
    runs = [one_point() for _ in range(args.repeats)]
    every = np.concatenate(runs)
    worst = float(every.max())
    print(f"decisions per point              {len(runs[0])} (the last one the stop)")
    print(f"decision wall time               median {np.median(every) * 1e3:.0f} ms, max {worst * 1e3:.0f} ms")
    print(f"a point's decisions in all       {min(map(sum, runs)):.2f} to {max(map(sum, runs)):.2f} s")
    ok = worst < TARGET_S
    print(f"target: slowest decision < {TARGET_S:g} s: {'met' if ok else 'MISSED'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

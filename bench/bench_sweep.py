"""Sweep orchestration overhead on the simulator.

Runs a test matrix (default: the paper's full matrix, 108 points x 20 blocks)
on an in-process SimRig at a time speed-up and prints

- the wall time of the run,
- the physical time the rig cannot avoid (drive ramps + settle holds +
  acquisition of N revolutions, from the plan's estimates) divided by the
  speed-up,
- the orchestration overhead: wall / ideal - 1, in percent (target < 5 %),
- where the wall time went (settle waits, acquisitions, identification).

    python3 -m bench.bench_sweep [--speedup 25] [--matrix config/matrices/paper.toml] [--points N]

Not part of the test suite: the full paper matrix takes several minutes.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import sys
import tempfile
import time
from pathlib import Path

from orbitrig import config as cfg
from orbitrig.run.engine import RunEngine
from orbitrig.run.plan import make_plan
from orbitrig.run.states import ConfirmMode
from orbitrig.run.steps import Acquire, SetOrbit, SetSpin, Settle, StopDrives
from rigunits import format_duration

PHYSICAL = (SetSpin, SetOrbit, Settle, Acquire, StopDrives)


def _subset(matrix: cfg.MatrixConfig, points: int | None) -> cfg.MatrixConfig:
    if not points:
        return matrix
    text = matrix.text
    import tomllib

    data = tomllib.loads(text)
    op = data["operating"]
    # keep the first values of the outer loops until `points` points remain
    n = 1
    for key in ("spin_rpm", "dynamic_eccentricity", "static_eccentricity", "pressure_ratio", "recess_pressure_mpa"):
        keep = max(1, min(len(op[key]), points // n))
        op[key] = op[key][:keep]
        n *= keep
    m = cfg.MatrixConfig.model_validate(data)
    m._text, m._file = text, matrix.file
    return m


async def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--speedup", type=float, default=25.0)
    ap.add_argument("--matrix", type=Path, default=cfg.default_matrix_path("paper"))
    ap.add_argument("--config", type=Path, default=None)
    ap.add_argument("--points", type=int, default=None, help="run only about this many operating points")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    logging.basicConfig(level=logging.WARNING)

    from orbitrig.cli.simulated_rig import simulated_rig

    rig = cfg.load_rig(args.config)
    matrix = _subset(cfg.load_matrix(args.matrix), args.points)
    plan = make_plan(matrix, rig)
    steps = plan.steps
    physical = sum(s.duration for s in steps if isinstance(s, PHYSICAL))
    acquire = sum(s.duration for s in steps if isinstance(s, Acquire))
    ideal = physical / args.speedup
    n_points = len({s.point for s in steps if s.point is not None})
    blocks = sum(isinstance(s, Acquire) for s in steps)
    print(
        f"matrix {matrix.name}: {n_points} points, {blocks} blocks; physical ramps+settle+acquisition "
        f"{format_duration(physical)} (acquisition {format_duration(acquire)}); speed-up {args.speedup:g}"
    )
    out = args.out or Path(tempfile.mkdtemp(prefix="bench-sweep-")) / "run"
    async with simulated_rig(args.speedup) as (_, access):
        engine = RunEngine(rig, out_dir=out, access=access, confirm_mode=ConfirmMode.AUTO)
        t0 = time.monotonic()
        outcome = await engine.run(plan)
        wall = time.monotonic() - t0
    tm = engine.timing
    print(f"outcome: {outcome.status} ({outcome.message}), {len(outcome.completed_points)} points complete in {out}")
    print(f"wall time                 {wall:9.1f} s")
    print(f"ideal (physical/speed-up) {ideal:9.1f} s")
    overhead = wall / ideal - 1
    print(f"orchestration overhead    {100 * overhead:9.1f} %   (target < 5 %)")
    waits = sum(tm.get(k, 0) for k in ("settle", "acquire", "verify"))
    print(
        f"  waiting on the rig: settle {tm.get('settle', 0):.1f} s, acquisition {tm.get('acquire', 0):.1f} s "
        f"(ideal {acquire / args.speedup:.1f} s), CAN pressure checks {tm.get('verify', 0):.1f} s; "
        f"everything else {wall - waits:.1f} s"
    )
    print(
        f"  in the background, overlapping the waits: identification {tm.get('identify', 0):.1f} s, "
        f"storage {tm.get('store', 0):.1f} s; the run waited {tm.get('backlog', 0):.1f} s for earlier points "
        "to be identified and stored"
    )
    return 0 if overhead < 0.05 else 1


if __name__ == "__main__":
    sys.exit(asyncio.run(main()))

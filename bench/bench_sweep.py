"""Sweep orchestration overhead on the simulator.

Runs a test matrix (default: the paper's full matrix, 108 points x 20 blocks)
through the run engine against the simulator (`python -m sim` in a process of
its own, orbitrig.cli.simulated_rig) at a time speed-up and prints

- the wall time of the run (`RunEngine.run`: opening the rig to the run file's end),
- the wall time the rig cannot avoid (`ideal`): the drive ramps (the start from
  rest, every speed change, every stop, the last one included), the settle holds
  and the acquisitions divided by the speed-up, plus the CAN frames the pressure
  checks wait for. An acquisition of n revolutions takes n + 1/2 orbit periods on
  average: it begins at the first trigger after the call, half a revolution away
  on average (the plan's estimate counts a whole one, its bound). The pressure
  check of each point takes the first frame the CAN node sends after it began:
  half the node's period on average, in wall time at any speed-up (the simulated
  node sends every 0.1 s of wall time, as the real one does),
- the orchestration overhead: wall / ideal - 1, in percent (target < 5 %; exit 1 on a miss,
  and when the run does not complete),
- where the wall time went, each activity against its part of `ideal`,
- the simulated time the simulator fell behind by (its A/D board held its clock: docs/simulator.md),
  part of the wall time but not orchestration,
- the host's load average (1 min) at the start and the end: other work on the cores moves the
  figure by several percent (compare runs taken at like loads, or in turn).

    python3 -m bench.bench_sweep [--speedup 25] [--matrix config/matrices/paper.toml] [--points N]

Not part of the test suite: the full paper matrix takes several minutes.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import os
import sys
import tempfile
import time
from pathlib import Path

from orbitrig import config as cfg
from orbitrig.run.engine import RunEngine
from orbitrig.run.plan import make_plan
from orbitrig.run.states import COMPLETED, ConfirmMode
from orbitrig.run.steps import Acquire, SetOrbit, SetSpin, Settle, Step, StopDrives, VerifyPressures
from rigunits import format_duration
from sim.can_node import FRAME_PERIOD_S


def ideal_parts(steps: tuple[Step, ...], speedup: float) -> dict[str, float]:
    """Wall s the rig cannot avoid, per activity of `RunEngine.timing`: the ramps and holds of the
    speed changes (settle), the acquisitions at n + 1/2 orbit periods (acquire), the stops' ramps
    (stop) at `speedup`; half a CAN frame period per pressure check (verify), wall s at any speed-up."""
    motion = sum(s.duration for s in steps if isinstance(s, (SetSpin, SetOrbit, Settle)))
    acquire = sum(s.duration - s.block.period / 2 for s in steps if isinstance(s, Acquire))
    stops = sum(s.duration for s in steps if isinstance(s, StopDrives))
    checks = sum(isinstance(s, VerifyPressures) for s in steps)
    return {
        "settle": motion / speedup,
        "acquire": acquire / speedup,
        "stop": stops / speedup,
        "verify": checks * FRAME_PERIOD_S / 2,
    }


def first_points(matrix: cfg.MatrixConfig, points: int | None) -> cfg.MatrixConfig:
    """``matrix`` cut to about its first ``points`` operating points, the first values of the outer
    loops kept (spin speed, then dynamic and static eccentricity, pressure ratio, recess pressure);
    each point's orbit ratios all kept; the whole matrix for None or 0."""
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
    return cfg.build_model(cfg.MatrixConfig, data, matrix.file, text)  # the file's name and text kept


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
    matrix = first_points(cfg.load_matrix(args.matrix), args.points)
    plan = make_plan(matrix, rig)
    steps = plan.steps
    parts = ideal_parts(steps, args.speedup)
    ideal = sum(parts.values())
    n_points = len({s.point for s in steps if s.point is not None})
    blocks = sum(isinstance(s, Acquire) for s in steps)
    print(
        f"matrix {matrix.name}: {n_points} points, {blocks} blocks; ramps+settle+acquisition "
        f"{format_duration((ideal - parts['verify']) * args.speedup)} physical; speed-up {args.speedup:g}"
    )
    out = args.out or Path(tempfile.mkdtemp(prefix="bench-sweep-")) / "run"
    load0 = os.getloadavg()[0]
    async with simulated_rig(args.speedup) as (sim, access):
        engine = RunEngine(rig, out_dir=out, access=access, confirm_mode=ConfirmMode.AUTO)
        t0 = time.monotonic()
        outcome = await engine.run(plan)
        wall = time.monotonic() - t0
        lost = sim.link.call("state")["sim_time_lost"]  # simulated s the simulator could not keep up with
    tm = engine.timing
    print(f"outcome: {outcome.status} ({outcome.message}), {len(outcome.completed_points)} points complete in {out}")
    print(f"host load average (1 min): {load0:.1f} at the start, {os.getloadavg()[0]:.1f} at the end")
    print(f"simulated time the simulator fell behind by: {lost:.2f} s ({lost / args.speedup:.2f} s of the wall time)")
    if outcome.status != COMPLETED:  # a run cut short has no overhead to speak of
        print(f"wall time                 {wall:9.1f} s: no overhead (the run did not complete)")
        return 1
    print(f"wall time                 {wall:9.1f} s")
    print(f"ideal (rig's own time)    {ideal:9.1f} s")
    overhead = wall / ideal - 1
    print(f"orchestration overhead    {100 * overhead:9.1f} %   (target < 5 %)")
    said = {"settle": "settle (ramps, holds)", "acquire": "acquisition", "stop": "drive stops", "verify": "CAN checks"}
    for key, what in said.items():
        print(f"  {what:24s}{tm.get(key, 0):7.1f} s   (ideal {parts[key]:.1f} s)")
    rest = wall - sum(tm.get(k, 0) for k in (*said, "command"))
    print(f"  {'speed commands':24s}{tm.get('command', 0):7.1f} s   (status of both drives, then the REF written)")
    print(
        f"  {'everything else':24s}{rest:7.1f} s   (opening the rig, steps' bookkeeping, closing the links, run file)"
    )
    print(
        f"  in the background, overlapping the waits: identification {tm.get('identify', 0):.1f} s, "
        f"storage {tm.get('store', 0):.1f} s; the run waited {tm.get('backlog', 0):.1f} s for earlier points "
        "to be identified and stored"
    )
    return 0 if overhead < 0.05 else 1


if __name__ == "__main__":
    sys.exit(asyncio.run(main()))

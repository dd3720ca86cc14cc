"""Sustained A/D output rate of the simulator (samples/s), one core.

0. the bearing: periodic film solution per operating point (each new speed pair),
   for the paper's rig and the compressible scenario;
1. offline: physics + quantisation + frame encoding of 100-revolution batches,
   the paper's rig (chain, disturbances) and the clean scenario; and whole
   revolutions straight from the physics (sim.revolutions) of the design test's
   point (tests/design/test_predicted_spread.py: a new seed per point, six orbit
   ratios in both directions, 926 revolutions), CPU ms per revolution, exit 1
   above REVOLUTION_TARGET;
2. live: SimRig streaming to its pty at several speed-ups while a separate
   reader process drains the pty; delivered samples/s = bytes received
   converted with the frame layout (20 bytes overhead per 45-sample frame).
Run:  python3 -m bench.bench_sim_adc [--seconds 3]
"""

from __future__ import annotations

import argparse
import asyncio
import dataclasses
import math
import subprocess
import sys
import time

import numpy as np


from sim.config import SimConfig
from sim.scenario_files import scenario
from sim.physics import RigPhysics
from sim.revolutions import simulate_revolutions
from sim.rig import SimRig

#: the design test's simulated point: orbit ratios to the spin and revolutions per block
POINT = ([0.15, 0.4, 0.65, 0.8, 1.2, 1.5], [16, 10, 289, 10, 25, 113])
SPIN = 1000 * 2 * math.pi / 60  # rad/s
REVOLUTION_TARGET = 0.15  # ms CPU per simulated revolution (8 channels of 45 samples, every disturbance)
#: orbit speeds (rpm) of the slow orbits and the revolutions simulated at each (20 minutes of simulated time)
SLOW_ORBITS = ((1.0, 20), (3.0, 60), (10.0, 200))
#: ms CPU per revolution of the slowest of SLOW_ORBITS (the envelope tables at every sample cost 0.5 to 4 ms)
SLOW_REVOLUTION_TARGET = 0.6

READER = r"""
import os, sys, time, tty, termios
fd = os.open(sys.argv[1], os.O_RDONLY | os.O_NOCTTY)
tty.setraw(fd); termios.tcflush(fd, termios.TCIFLUSH)
t_end = time.monotonic() + float(sys.argv[2]); t_start = None; n = 0
while time.monotonic() < t_end:
    b = os.read(fd, 1 << 20)
    if t_start is None:
        t_start = time.monotonic(); continue
    n += len(b)
print(n, time.monotonic() - t_start)
"""


def film_solve(cfg: SimConfig, rounds: int = 200) -> float:
    """CPU seconds per periodic film solution (a new operating point every call)."""
    ph = RigPhysics(cfg)
    ph.set_manual(orbit_radius=0.096 * cfg.geometry.clearance)
    t0 = time.process_time()
    for i in range(rounds):
        ph.force_harmonics(104.7 + 0.01 * i, 60.0 + 0.01 * i)
    return (time.process_time() - t0) / rounds


def offline(revs: int = 100, rounds: int = 20, cfg: SimConfig | None = None) -> float:
    rig = SimRig(cfg or SimConfig())
    n = 360 * revs
    g = np.arange(n) + 360
    t = g * 1e-5
    spin_angle = g * 0.01
    orbit = np.full(n, 2 * math.pi * 40)
    t0 = time.process_time()  # CPU time of this process: the machine may be shared
    for _ in range(rounds):
        counts = rig.stream.convert(g, t, spin_angle, orbit, 200.0, 2 * math.pi * 40)
        rig.board.encode(int(g[0]), counts, t)
    return rounds * n / (time.process_time() - t0)


def revolutions(points: int = 5) -> float:
    """CPU ms per revolution of the design test's point (film solutions and disturbances included)."""
    ratios, counts = POINT
    t0 = time.process_time()
    for seed in range(1, points + 1):
        physics = RigPhysics(dataclasses.replace(scenario("paper"), seed=seed))
        t = 0.0
        for sign in (1, -1):
            for r, n in zip(ratios, counts):
                simulate_revolutions(physics, SPIN, sign * r * SPIN, n, t0=t)
                t += (n + 1) * 2 * math.pi / (r * SPIN)
    return (time.process_time() - t0) / (points * 2 * sum(counts)) * 1e3


def slow_orbits() -> dict[float, float]:
    """CPU ms per revolution of each of SLOW_ORBITS (rpm -> ms), the paper's rig at spin 1000 rpm,
    the film solved before."""
    rpm = 2 * math.pi / 60
    per_rev = {}
    for orbit, n in SLOW_ORBITS:
        physics = RigPhysics(dataclasses.replace(scenario("paper"), seed=3))
        simulate_revolutions(physics, SPIN, orbit * rpm, 1)  # the film solution of the operating point
        t0 = time.process_time()
        simulate_revolutions(physics, SPIN, orbit * rpm, n, t0=60.0 / orbit)
        per_rev[orbit] = (time.process_time() - t0) / n * 1e3
    return per_rev


async def live(speedup: float, seconds: float) -> tuple[float, float, int]:
    async with SimRig(SimConfig(), speedup=speedup, can_channel=None) as rig:
        rig.local_control(spin=200.0, orbit=2 * math.pi * 40.0)  # 2400 rpm orbit
        proc = await asyncio.create_subprocess_exec(
            sys.executable, "-c", READER, rig.adc_pty_path, str(seconds), stdout=subprocess.PIPE
        )
        cpu0 = time.process_time()
        t0 = time.monotonic()
        out, _ = await proc.communicate()
        cpu = (time.process_time() - cpu0) / (time.monotonic() - t0)
        dropped = rig.adc_server.pty.chunks_dropped
    nbytes, dt = out.split()
    frame = 20 + 2 * 45
    return int(nbytes) / frame * 45 / float(dt), cpu, dropped


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=3.0)
    args = ap.parse_args()
    per_rev = revolutions()
    print(
        f"revolutions (sim.revolutions, the design test's point, paper's rig): {per_rev:.3f} ms CPU per revolution "
        f"(target <= {REVOLUTION_TARGET})"
    )
    slow = slow_orbits()
    print(
        "revolutions at slow orbits (sim.revolutions, spin 1000 rpm, paper's rig): "
        + ", ".join(f"{orbit:g} rpm {ms:.3f}" for orbit, ms in slow.items())
        + f" ms CPU per revolution (target <= {SLOW_REVOLUTION_TARGET} for each)"
    )
    for name in ("paper", "compressible"):
        print(f"film solve per operating point ({name}, eps_d 0.096): {film_solve(scenario(name)) * 1e3:.2f} ms CPU")
    print(f"offline (physics + encode, 8 ch sequential, paper's rig): {offline() / 1e6:.2f} M samples per CPU second")
    print(
        f"offline (physics + encode, 8 ch sequential, clean): {offline(cfg=scenario('clean')) / 1e6:.2f} "
        "M samples per CPU second"
    )
    for speedup in (50, 100, 200, 400):
        rate, cpu, dropped = asyncio.run(live(speedup, args.seconds))
        generated = speedup * 40 * 360
        print(
            f"live pty, speed-up {speedup:4d} (board makes {generated / 1e6:.2f} M samples/s): "
            f"delivered {rate / 1e6:.2f} M samples/s, simulator CPU {cpu * 100:.0f} % of one core "
            f"({rate / cpu / 1e6:.1f} M samples per CPU second), chunks dropped {dropped}"
        )
    return 0 if per_rev <= REVOLUTION_TARGET and max(slow.values()) <= SLOW_REVOLUTION_TARGET else 1


if __name__ == "__main__":
    sys.exit(main())

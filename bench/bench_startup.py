"""Start-up: `orbitrig --version` and `orbitrig --help` against importing numpy and scipy.linalg.

Neither command needs the configuration, plan, store or numerics modules, so neither may
import them: each area module of orbitrig/cli imports its heavy dependencies inside its
command functions. Target: each command's wall time at most RATIO x the reference
`python -c 'import numpy, scipy.linalg'`.

Each figure is the median over `runs` fresh interpreter processes (wall time of the whole
process, measured here around subprocess.run); the three commands are interleaved run by
run, so load from other work on the machine falls on all of them alike. The current
PYTHONPATH is passed on, so a checkout's packages win (run with PYTHONPATH=$PWD).
Byte-code caching is on in the child processes (PYTHONDONTWRITEBYTECODE is dropped): an
installed orbitrig has its .pyc files, as numpy and scipy do, and the uncounted first run
of each command writes them for a checkout.

Run: python3 -m bench.bench_startup [runs]   (default 9; exit 1 if a command misses the target)
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time

RATIO = 0.6  # at most this fraction of the reference's time
REFERENCE = ("numpy + scipy.linalg", [sys.executable, "-c", "import numpy, scipy.linalg"])
COMMANDS = (
    ("orbitrig --version", [sys.executable, "-m", "orbitrig", "--version"]),
    ("orbitrig --help", [sys.executable, "-m", "orbitrig", "--help"]),
)


ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def wall_seconds(argv: list[str]) -> float:
    """Wall time of one fresh process running `argv`, s (it must exit 0)."""
    t0 = time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=ENV)
    return time.perf_counter() - t0


def medians(runs: int) -> dict[str, float]:
    """Median wall time of each command and the reference over `runs` interleaved rounds, s."""
    every = (REFERENCE, *COMMANDS)
    for _, argv in every:  # warm the file cache and the byte-code once, not counted
        wall_seconds(argv)
    times: dict[str, list[float]] = {name: [] for name, _ in every}
    for _ in range(runs):
        for name, argv in every:
            times[name].append(wall_seconds(argv))
    return {name: statistics.median(t) for name, t in times.items()}


def main() -> int:
    parser = argparse.ArgumentParser(prog="python3 -m bench.bench_startup", description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", type=int, nargs="?", default=9, help="runs of each command (median taken; default 9)")
    runs = parser.parse_args().runs
    med = medians(runs)
    ref = med[REFERENCE[0]]
    print(f"start-up, median of {runs} fresh processes each (target: at most {RATIO:.2f} x reference)")
    print(f"  {REFERENCE[0]:<22} {ref * 1e3:7.0f} ms  (reference)")
    missed = []
    for name, _ in COMMANDS:
        ratio = med[name] / ref
        ok = ratio <= RATIO
        print(f"  {name:<22} {med[name] * 1e3:7.0f} ms  {ratio:5.2f} x  {'ok' if ok else 'MISSED'}")
        if not ok:
            missed.append(name)
    if missed:
        print(f"missed: {', '.join(missed)}")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

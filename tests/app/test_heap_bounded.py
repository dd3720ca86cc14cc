"""orbitrig.run.heap: with the arenas capped, the mmap threshold fixed and the free arena
memory handed back, threads that allocate and free a point's worth of blocks again and
again (as identification and storage do) leave much less resident memory behind."""

from __future__ import annotations

import subprocess
import sys

import pytest

from support.paths import ROOT

pytestmark = pytest.mark.timeout(120)

CHURN = """
import sys, threading
import numpy as np
from orbitrig.run.heap import trim_heap, tune_heap

def rss():
    return next(int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmRSS:")) / 1024

tuned = sys.argv[1] == "tuned"
if tuned:
    tune_heap()
kept = []

def point_after_point(seed):
    rng = np.random.default_rng(seed)
    for _ in range(150):
        blocks = [np.ones(rng.integers(20_000, 80_000)) for _ in range(20)]  # 160 to 640 kB: a point's blocks
        small = [np.ones(rng.integers(10, 2000)) for _ in range(200)]  # and what identifying them leaves
        kept.append(small[0])  # a few numbers per point stay (the summary)
        del blocks, small

base = rss()
threads = [threading.Thread(target=point_after_point, args=(s,)) for s in range(4)]
for t in threads:
    t.start()
for t in threads:
    t.join()
if tuned:
    trim_heap()
print(rss() - base)
"""


def grown(mode: str) -> float:
    p = subprocess.run(
        [sys.executable, "-c", CHURN, mode],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=100,
        env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"},
    )
    assert p.returncode == 0, p.stderr
    return float(p.stdout)


def test_tuned_heap_keeps_less_of_what_threads_freed():
    plain, tuned = grown("plain"), grown("tuned")
    assert tuned < 0.6 * plain and tuned < 25.0, (plain, tuned)  # MB

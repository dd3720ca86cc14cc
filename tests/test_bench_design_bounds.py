"""The bounds bench's per-block overhead: the paper list's twenty blocks pay it as the designs' few
do, so a smaller settle hold or store would raise the least ratio, not lower it."""

from __future__ import annotations

import subprocess
import sys

from bench.bench_design_bounds import bounds_setup, case_bound
from orbitrig.config import load_rig
from support.cli_helpers import child_env
from support.paths import ROOT


def test_the_constant_models_bound_is_above_half_without_the_per_block_overhead() -> None:
    """Constant model alone, both directions: 0.65 and 1.5 at 323 and 125 revolutions; at the rig's
    2.05 s per block 0.49 of the paper list's 158.9 s, at 0 s (acquisition alone) 0.59 of 117.9 s."""
    rig = load_rig(ROOT / "config" / "rig.toml")
    assert rig.block_overhead_s == 2.05
    rows = {}
    for overhead in (rig.block_overhead_s, 0.0):
        setup, grid = bounds_setup(rig, overhead)
        rows[overhead] = case_bound("none", False, setup, grid), setup["ref_time"]
    (with_hold, ref_with), (without, ref_without) = rows[2.05], rows[0.0]
    assert round(ref_with, 1) == 158.9 and round(ref_without, 1) == 117.9
    assert with_hold["list"] == without["list"] == "0.65fb:323 1.5fb:125"
    assert 0.48 < with_hold["time_ratio"] < 0.5
    assert 0.58 < without["time_ratio"] < 0.6


def test_an_overhead_that_is_no_number_of_seconds_is_refused() -> None:
    """--block-overhead nan or inf: refused (exit 2), not a table of NaN ratios or a traceback."""
    for value in ("nan", "inf", "-1"):
        done = subprocess.run(
            [sys.executable, "-m", "bench.bench_design_bounds", f"--block-overhead={value}"],
            cwd=ROOT,
            env=child_env(),
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert done.returncode == 2, done.stderr
        assert f"--block-overhead: a finite number of s, at least 0, not {value}" in done.stderr

"""Adaptive averaging in the sweep (matrix [averaging] -> daq AveragingRule -> stored blocks),
on the real simulator over its loopback protocols, the engine in-process."""

from __future__ import annotations

import asyncio
from pathlib import Path

import h5py
import numpy as np
import pytest

from orbitrig import config as cfg
from orbitrig.cli.simulated_rig import simulated_access
from orbitrig.run.engine import RunEngine
from orbitrig.run.plan import make_plan
from orbitrig.run.steps import Acquire
from orbitrig.run.averaging import averaging_rule
from reduction.noise import revolution_residuals
from sim.rig import SimRig
from support.sweep_helpers import demo_text

pytestmark = pytest.mark.timeout(180)

RPM = 2 * np.pi / 60
SPEEDUP = 40.0


def matrix(averaging: str, ratios: str = "[0.5, 1.2]") -> cfg.MatrixConfig:
    text = demo_text("adaptive").replace("ratios = [0.3, 0.5, 0.7, 0.9, 1.2]", f"ratios = {ratios}")
    return cfg.matrix_from_text(text + "\n[averaging]\n" + averaging, "adaptive.toml")


def stored_blocks(out: Path) -> list[dict]:
    blocks = []
    with h5py.File(out / "run.h5", "r") as f:
        for g in f["points"].values():
            for tag, b in g["frequencies"].items():
                blocks.append(
                    {
                        "tag": tag,
                        "n": int(b.attrs["n_records"]),
                        "why": str(b.attrs["stop_reason"]),
                        "rows": b["raw_counts"].shape[0],
                        "used": int(b["stats"].attrs.get("revolutions_used", -1)) if "stats" in b else -1,
                        "dropped": int(b["stats"].attrs.get("revolutions_dropped", 0)) if "stats" in b else 0,
                        "record_phasors": b["record_phasors"][()],
                        "u": b["uncertainty"][()],
                        "revolutions": b["revolutions"][()],
                        "spin_turns": 1000 * RPM / abs(b.attrs["orbit"]),
                    }
                )
    return blocks


async def run_sweep(tmp_path: Path, mat, damage: bool = False, speedup: float = SPEEDUP) -> list[dict]:
    async with SimRig(speedup=speedup, adc_pty=False) as sim:
        eng = RunEngine(cfg.load_rig(), out_dir=tmp_path / "run", access=simulated_access(sim), confirm_mode="auto")
        run = asyncio.create_task(eng.run(mat))
        while damage and not run.done():  # a damaged frame every few revolutions, all run long
            sim.inject("corrupt_bytes", count=1)
            await asyncio.sleep(0.02)
        outcome = await run
    assert outcome.status == "completed", outcome.message
    return stored_blocks(tmp_path / "run")


def test_the_plan_carries_the_matrix_rule():
    rig = cfg.load_rig()
    plan = make_plan(matrix("target_pct = 0.5\nmin_revolutions = 12\nmax_revolutions = 80\n"), rig)
    steps = [s for s in plan.steps if isinstance(s, Acquire)]
    rules = [averaging_rule(s, plan.points[s.point].spin) for s in steps]
    assert {(r.min_revolutions, r.max_revolutions, round(r.target, 12)) for r in rules} == {(12, 80, 0.005)}
    # the stop check fits the spin tones out: omega/|Omega| of each block
    assert all(
        r.spin_turns == pytest.approx(plan.points[s.point].spin / abs(s.block.orbit)) for r, s in zip(rules, steps)
    )
    assert plan.revolutions == 80  # storage and time estimates take the maximum
    fixed = make_plan(cfg.load_matrix(cfg.matrix_file("demo")), rig)
    assert {
        (r.min_revolutions, r.max_revolutions, r.target)
        for r in (averaging_rule(s, 1.0) for s in fixed.steps if isinstance(s, Acquire))
    } == {(50, 50, None)}  # the paper's fixed 50


async def test_loose_target_stops_at_the_minimum(tmp_path):
    blocks = await run_sweep(tmp_path, matrix("target_pct = 50\nmin_revolutions = 7\nmax_revolutions = 40\n"))
    assert len(blocks) == 4
    for b in blocks:
        assert (b["n"], b["why"], b["rows"], b["used"]) == (7, "target", 7, 7), b["tag"]


async def test_unreachable_target_stops_at_the_maximum(tmp_path):
    blocks = await run_sweep(tmp_path, matrix("target_pct = 0.001\nmin_revolutions = 3\nmax_revolutions = 12\n"))
    for b in blocks:
        assert (b["n"], b["why"], b["rows"], b["used"]) == (12, "max", 12, 12), b["tag"]


async def test_damaged_revolutions_are_never_averaged(tmp_path):
    # at speed-up 10 a block lasts 0.05 to 0.4 s of wall time: injections (every 20 ms
    # of the test's loop) land in the blocks even when both cores are busy (at 40 a block of
    # 10 revolutions at ratio 1.2 lasted 15 ms, and once no damage reached any block)
    blocks = await run_sweep(
        tmp_path, matrix("target_pct = 3\nmin_revolutions = 10\nmax_revolutions = 30\n"), damage=True, speedup=10.0
    )
    assert sum(b["dropped"] for b in blocks) > 0  # the damage reached the blocks
    for b in blocks:
        assert 10 <= b["n"] <= 30 and b["rows"] == b["n"] == b["used"], b["tag"]
        assert b["why"] in ("target", "max")
        # no revolution is an outlier of its block: after the mean and the spin tones (fitted at
        # the board's revolution numbers, gaps where the damaged ones were dropped) every residual
        # is within 6 white-noise sigmas (complex Gaussian: P(|e| > 6 sigma) = e^-36); a revolution
        # cut from damaged frames would be off by the signal itself
        resid, white = revolution_residuals(b["record_phasors"], b["spin_turns"], b["revolutions"])
        assert np.max(np.abs(resid) / white) < 6.0, b["tag"]
        assert np.all(np.diff(b["revolutions"]) >= 1)

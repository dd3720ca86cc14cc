"""The engine bench's per-direction protocol: the design's blocks reach the sweep as written."""

from __future__ import annotations

from bench.bench_rig_time import PAPER, pilot_problem
from bench.bench_rig_time_engine import designed_list, list_matrix, plan_time_ratio
from orbitrig.config import load_rig, matrix_from_text
from orbitrig.run.plan import make_plan
from orbitrig.run.steps import Acquire
from rigunits import RPM
from support.paths import ROOT


def test_per_direction_list_runs_each_block_in_its_own_direction_in_less_time_than_designed() -> None:
    """`--protocols per-direction`: the pilot's --match --per-direction proposal becomes a matrix
    with an [orbit] whirl list, whose plan acquires each entry once, in its own direction (a ratio
    may come twice, once per direction), and which the plan puts below the designed list's time."""
    rig = load_rig(ROOT / "config" / "rig.toml")
    ratios, counts, whirl = designed_list(rig, pilot_problem, per_direction=True)
    assert whirl is not None and len(whirl) == len(ratios) == len(counts)
    assert set(whirl) <= {"forward", "backward"}
    plan = make_plan(matrix_from_text(list_matrix(ratios, counts, whirl), "bench.toml"), rig)
    blocks = sorted(
        (round(abs(s.block.orbit) / (1000 * RPM), 6), s.block.direction, s.revolutions)
        for s in plan.steps
        if isinstance(s, Acquire)
    )
    sign = {"forward": 1, "backward": -1}
    assert blocks == sorted((r, sign[w], n) for r, w, n in zip(ratios, whirl, counts))
    d_ratios, d_counts, d_whirl = designed_list(rig, pilot_problem)
    assert d_whirl is None
    per = plan_time_ratio(rig, ratios, counts, PAPER, whirl)
    assert per < plan_time_ratio(rig, d_ratios, d_counts, PAPER) < 1.0

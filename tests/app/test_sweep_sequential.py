"""A sequential matrix ([orbit] sequential = true) run by the engine on the simulator: blocks
chosen at run time only among the plan's candidates, each storing why and its predicted errors,
the point stopping at its target or at its time cap; a stopped sequential point restarts on resume."""

import asyncio
import re

import h5py
import numpy as np
import pytest

from orbitrig import config as cfg
from orbitrig.cli.dry_run import sequential_lines
from orbitrig.errors import ConfigError
from orbitrig.run.plan import make_plan, summarize
from orbitrig.run.steps import ChooseBlocks
from reduction.sequential import MAX_REVOLUTIONS, MIN_REVOLUTIONS

from support.sweep_helpers import running, wait_for

CANDIDATES = [0.3, 0.65, 1.5]
MATRIX = """
name = "seq"
[operating]
spin_rpm = [1000.0]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.4]
static_eccentricity = [0.0]
dynamic_eccentricity = [0.096]
[orbit]
ratios = [0.2, 0.5, 0.8, 1.2, 1.5]
revolutions = [10, 10, 10, 10, 10]
sequential = true
[sequential]
{target}
cap_s = {cap}
candidates = {candidates}
[[models]]
model = "kcd11"
"""
INITIAL = 10  # blocks of the initial list (5 ratios x 2 directions)
#: as precise as the demo's list at 30 revolutions per block (the initial list alone: about 1.6 times the
#: errors), reached in about a minute of blocks
MATCH = "match_ratios = [0.3, 0.5, 0.7, 0.9, 1.2]\nmatch_revolutions = {n}"


def matrix(target=MATCH.format(n=30), cap=600.0, candidates=CANDIDATES) -> cfg.MatrixConfig:
    return cfg.matrix_from_text(MATRIX.format(target=target, cap=cap, candidates=candidates), "seq.toml")


def _decisions(run_dir):
    """(chosen blocks [(tag, |orbit|/spin, attrs, before, after)], the point's last decision attrs)."""
    with h5py.File(run_dir / "run.h5") as f:
        p = f["points"]["0000"]
        spin = float(p.attrs["spin"])
        chosen = [
            (
                tag,
                abs(float(g.attrs["orbit"])) / spin,
                dict(g["sequential"].attrs),
                g["sequential"]["before"][()],
                g["sequential"]["after"][()],
            )
            for tag, g in sorted(p["frequencies"].items())
            if "sequential" in g
        ]
        tags = sorted(p["frequencies"])
        return chosen, dict(p["sequential"].attrs), p["sequential"]["before"][()], tags


def test_plan_lists_and_checks_the_candidates():
    rig = cfg.load_rig()
    plan = make_plan(matrix(), rig)
    (step,) = [s for s in plan.steps if isinstance(s, ChooseBlocks)]
    assert step.rule.candidates == tuple(CANDIDATES) and step.rule.directions == ("forward", "backward")
    assert step.first_freq == 5 and 0 < step.duration < 600
    assert plan.blocks() == {0: None}  # chosen at run time: an incomplete point says no "of N"
    lines = sequential_lines(plan, summarize(plan.steps).duration)
    assert "cap of 600 s" in lines[0] and "candidate ratios 0.3, 0.65, 1.5 (forward, backward)" in lines[1]
    default = make_plan(
        cfg.matrix_from_text(
            MATRIX.format(target="target_pct = 5", cap=600, candidates="[0.3]").replace("candidates = [0.3]\n", ""),
            "seq.toml",
        ),
        rig,
    )
    (rule,) = [s.rule for s in default.steps if isinstance(s, ChooseBlocks)]
    assert rule.candidates[0] == pytest.approx(0.1) and rule.candidates[-1] == pytest.approx(1.5)
    assert all(abs(r - 1) >= 0.1 - 1e-9 for r in rule.candidates)  # the drives' band, clear of Omega = omega
    with pytest.raises(ConfigError) as err:
        make_plan(matrix(candidates=[0.95, 1.8]), rig)
    text = str(err.value)
    assert "sequential.candidates': ratio 0.95 is within 0.1" in text and "ratio 1.8 is above" in text


def test_a_sequential_matrix_needs_its_bounds():
    with pytest.raises(ConfigError, match=r"needs a \[sequential\] table"):
        cfg.matrix_from_text(MATRIX.split("[sequential]")[0] + '[[models]]\nmodel = "kcd11"\n', "seq.toml")
    with pytest.raises(ConfigError, match="give one target"):
        cfg.matrix_from_text(
            MATRIX.format(target="target_pct = 40\nmatch_ratios = [0.5, 1.2]", cap=60, candidates=CANDIDATES),
            "seq.toml",
        )


async def test_sequential_point_chooses_among_the_candidates_until_its_target(tmp_path):
    async with running(tmp_path, matrix()) as (_, _, _, run):
        outcome = await asyncio.wait_for(run, 60)
    assert str(outcome.status) == "completed", outcome.message
    chosen, last, final, tags = _decisions(tmp_path / "run")
    assert chosen and len(tags) == INITIAL + len(chosen)
    for tag, ratio, a, before, after in chosen:
        assert int(tag[:2]) >= 5  # a block index of its own, after the initial list's
        assert a["reason"] == "next" and a["ratio"] in CANDIDATES and ratio == pytest.approx(a["ratio"], rel=1e-9)
        assert MIN_REVOLUTIONS <= a["revolutions"] <= MAX_REVOLUTIONS
        assert np.max(after) < np.max(before) and np.max(before) > 1.0  # chosen to lower the largest error
    assert last["reason"] == "target" and np.max(final) <= 1.0 and last["spent_s"] <= 600
    # each decision's 'before' is the previous one's outcome on the measured blocks: the spent time grows
    spent = [a["spent_s"] for _, _, a, _, _ in chosen] + [last["spent_s"]]
    assert spent == sorted(spent)


@pytest.mark.timeout(120)
async def test_stopped_sequential_point_restarts_on_resume_and_stops_at_its_cap(tmp_path):
    from orbitrig.cli.simulated_rig import simulated_rig
    from orbitrig.run.engine import RunEngine

    m = matrix(target=MATCH.format(n=500), cap=70.0)  # a target no block reaches in 70 s
    log = tmp_path / "run" / "run.log"
    async with running(tmp_path, m) as (_, eng, _, run):
        # stopped as soon as the first block is chosen, while it runs: a planned point may reach its cap
        # with that one block, and would then complete before a stop asked once it is stored
        await wait_for(
            lambda: log.exists() and re.search(r"point 0000: sequential: \w+ ratio", log.read_text()),
            40,
            "a block chosen",
        )
        eng.request_stop()
        outcome = await asyncio.wait_for(run, 30)
    assert str(outcome.status) == "stopped" and outcome.completed_points == []
    async with simulated_rig(40.0) as (_, access):
        outcome = await RunEngine(cfg.load_rig(), out_dir=tmp_path / "run", access=access, confirm_mode="auto").run(
            m, resume=True
        )
    assert str(outcome.status) == "completed", outcome.message
    assert list((tmp_path / "run" / "aside").iterdir())  # the stopped attempt, put aside whole
    chosen, last, final, _ = _decisions(tmp_path / "run")
    assert chosen and last["reason"] == "cap" and np.max(final) > 1.0
    assert last["spent_s"] <= 70.0 and all(a["spent_s"] + a["seconds"] <= 70.0 + 1e-9 for _, _, a, _, _ in chosen)


async def test_a_bug_in_the_sequential_design_names_the_point(tmp_path, monkeypatch, caplog):
    """The sequential design of point 0000 raises on a bug (a mock: no real part makes one): the run
    fails naming the point and the error's type, the traceback logged, the drives at rest and the
    initial list's blocks kept. It said only "KeyError: 'x'"."""
    from orbitrig.run import sequential_point

    def buggy(*args, **kwargs):
        raise KeyError("x")

    monkeypatch.setattr(sequential_point, "choose", buggy)
    async with running(tmp_path, matrix()) as (sim, _, _, run):
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
        assert str(outcome.status) == "failed", outcome.message
        assert outcome.message == "point 0000: sequential design failed: KeyError: 'x'"
        await wait_for(lambda: all(abs(s) < 1.0 for s in sim.speeds), 30, what="both drives at rest")
    blocks = sorted(p.name for p in (tmp_path / "run" / "points" / "0000").glob("*_*.h5"))
    assert len(blocks) == INITIAL, blocks
    assert any(r.exc_info and "point 0000: sequential design" in r.getMessage() for r in caplog.records)


async def test_a_per_direction_initial_list_then_chosen_blocks(tmp_path):
    """The initial list with a whirl list (1.5 written twice: forward, then backward with its own
    count): those blocks run as written, and the chosen blocks take indices after all six entries."""
    text = MATRIX.format(target=MATCH.format(n=30), cap=600.0, candidates=CANDIDATES).replace(
        "ratios = [0.2, 0.5, 0.8, 1.2, 1.5]\nrevolutions = [10, 10, 10, 10, 10]",
        "ratios = [0.2, 0.5, 0.8, 1.2, 1.5, 1.5]\nrevolutions = [10, 10, 10, 10, 10, 12]\n"
        'whirl = ["both", "both", "both", "both", "forward", "backward"]',
    )
    async with running(tmp_path, cfg.matrix_from_text(text, "seq.toml")) as (_, _, _, run):
        outcome = await asyncio.wait_for(run, 60)
    assert str(outcome.status) == "completed", outcome.message
    chosen, last, _, tags = _decisions(tmp_path / "run")
    initial = sorted(f"{k:02d}_{d}" for k in range(4) for d in ("fwd", "bwd")) + ["04_fwd", "05_bwd"]
    assert chosen and sorted(set(tags) - {tag for tag, *_ in chosen}) == initial
    with h5py.File(tmp_path / "run" / "run.h5") as f:
        blocks = f["points/0000/frequencies"]
        assert [int(blocks[t].attrs["n_records"]) for t in ("04_fwd", "05_bwd")] == [10, 12]
    assert all(int(tag[:2]) >= 6 for tag, *_ in chosen) and last["reason"] == "target"

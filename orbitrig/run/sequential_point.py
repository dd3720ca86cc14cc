"""A sequential point at run time: from the blocks measured so far to the next block.

`choose` (pure, CPU-bound: the engine calls it in a worker thread) takes the point so far
(:class:`PointSoFar`: its rule, spin, blocks, channels and corrections), builds its piezo
orbit table from its own blocks, identifies the rule's model on it (wls), takes each block's
measured per-revolution noise (its u x sqrt(n); smoothed across the ratios for the
candidates, reduction.frequency_list.smooth_noise), sums the blocks' Fisher information at
those coefficients and asks reduction.sequential.next_block for the next block among the
rule's candidates. The rig seconds spent are counted as the plan counts them: per block its
revolutions + 1 orbit periods, the settle hold and the store estimate, and the orbit ramps
between the blocks in the order they ran. `chosen_steps` turns the choice into the plan's
own step kinds (SetOrbit, Settle, Acquire of the chosen count, StoreBlock with the reason).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from orbitrig.config import LMS
from orbitrig.run.corrections import Corrections, spin_turns
from orbitrig.run.events import RunFailed
from orbitrig.run.identification import corrected_probes, orbit_table, runout_bases
from orbitrig.run.sequential_rule import SequentialRule
from orbitrig.run.steps import Acquire, Block, ChooseBlocks, SetOrbit, Settle, Step, StoreBlock
from orbitrig.store.layout import point_name
from orbitrig.store.records import BlockChoice, BlockRecord
from reduction.arrays import FloatArray, NoiseAt
from reduction.errors import ReductionError
from reduction.frequency_list import coefficient_scales, smooth_noise
from reduction.identify import identify
from reduction.methods import Method
from reduction.models import ModelSpec, model_spec
from reduction.rig_time import block_time
from reduction.sequential import Choice, block_information, next_block, reference_errors
from reduction.table import OrbitTable
from reduction.whirl import Directions, Whirl

log = logging.getLogger(__name__)

#: the most blocks a point can name (storage tags are two digits)
MAX_BLOCK_INDEX = 99


@dataclass(frozen=True)
class PointSoFar:
    """A sequential point so far, as its design reads it: the point's ``rule``, its ``spin``
    (rad/s), the ``blocks`` measured (in the order they ran), the ``channels`` (name -> index in
    the blocks' phasors) and the ``corrections`` of the rig's active record (none: as read)."""

    rule: SequentialRule
    spin: float
    blocks: tuple[BlockRecord, ...]
    channels: dict[str, int]
    corrections: Corrections = field(default_factory=Corrections)


def spent_seconds(rule: SequentialRule, recs: list[BlockRecord]) -> float:
    """Rig seconds of the blocks ``recs`` (in the order they ran): revolutions + trigger,
    settle hold and store per block, the orbit ramps between them."""
    orbits = np.array([r.block.orbit for r in recs])
    n = np.array([r.n_records if r.n_records is not None else len(r.record_phasors) for r in recs])
    ramps = float(np.sum(np.abs(np.diff(orbits)))) / rule.ramp_rate
    return float(np.sum(block_time(orbits, n))) + len(recs) * rule.per_block_s + ramps


def _noise(table: OrbitTable, ratios: FloatArray) -> tuple[FloatArray, NoiseAt]:
    """Per-revolution noise (k, 4) per block and the smoothed ``noise_at(ratios)`` of the candidates."""
    if table.u is None or table.n_records is None:
        raise ValueError("the blocks' phasor uncertainties are not finite")
    per_rev = table.u * np.sqrt(table.n_records)[:, None]
    at = np.unique(np.round(ratios, 9))
    smooth = smooth_noise(at, np.array([np.median(per_rev[np.round(ratios, 9) == r], axis=0) for r in at]))

    def noise_at(ratio: ArrayLike) -> FloatArray:
        r = np.atleast_1d(np.asarray(ratio, dtype=float))
        return np.stack([np.interp(r, at, smooth[:, c]) for c in range(4)], axis=1)

    return per_rev, noise_at


def choose(so_far: PointSoFar) -> BlockChoice:
    """The next block of the point ``so_far``, or the stop (reason target or cap). Raises
    ReductionError/ValueError when the blocks cannot identify the model."""
    rule, spin, recs, ch, corr = so_far.rule, so_far.spin, list(so_far.blocks), so_far.channels, so_far.corrections
    spec = model_spec(rule.model)
    turns = [spin_turns(r, ch, spin) for r in recs]  # the one fit of each block's spin ratio
    probes = corrected_probes(recs, ch, corr, runout_bases(recs, ch, corr, turns))
    table = orbit_table(spin, recs, ch, LMS[0], corr, probes, turns)
    theta = identify(table, rule.model, method=Method.WLS).theta
    ratios = np.array([abs(r.block.orbit) / spin for r in recs])
    per_rev, noise_at = _noise(table, ratios)
    radius = float(np.mean(np.sqrt((np.abs(table.x) ** 2 + np.abs(table.y) ** 2) / 2)))
    info = _information(spec, theta, spin, radius, table, ratios, per_rev, recs)
    scales, target = _scales(rule, spec, theta, spin, radius, noise_at)
    spent = spent_seconds(rule, recs)
    nb = next_block(
        spec,
        theta,
        spin,
        radius,
        info,
        rule.candidates,
        noise_at,
        scales,
        target=target,
        spent_s=spent,
        cap_s=rule.cap_s,
        per_block_s=rule.per_block_s,
        directions=rule.directions,
        orbit_now=recs[-1].block.orbit,
        ramp_rate=rule.ramp_rate,
    )
    return BlockChoice(
        nb.reason.name.lower(),
        nb.ratio,
        nb.direction,
        nb.revolutions,
        nb.seconds,
        spent,
        tuple(spec.names),
        tuple(float(v) for v in nb.before),
        tuple(float(v) for v in nb.after),
    )


def decide(point: int, so_far: PointSoFar) -> BlockChoice:
    """`choose` at operating point ``point``; its failure a RunFailed naming the point: a refusal
    of the numerics in its own words, a bug with its type (and its traceback in the log)."""
    try:
        return choose(so_far)
    except (ReductionError, ValueError, FloatingPointError) as err:
        raise RunFailed(f"point {point_name(point)}: sequential design: {err}") from err
    except Exception as err:
        log.error("point %s: sequential design failed", point_name(point), exc_info=err)
        raise RunFailed(f"point {point_name(point)}: sequential design failed: {type(err).__name__}: {err}") from err


def _information(
    spec: ModelSpec,
    theta: FloatArray,
    spin: float,
    radius: float,
    table: OrbitTable,
    ratios: FloatArray,
    per_rev: FloatArray,
    recs: list[BlockRecord],
) -> FloatArray:
    """The Fisher information of the point's blocks at ``theta``, summed over the blocks (each
    at its ratio, per-revolution noise, revolution count and whirl direction)."""
    n_records = table.n_records
    if n_records is None:
        raise ValueError("the blocks' revolution counts are not known")
    blocks = [
        block_information(
            spec,
            theta,
            spin,
            radius,
            ratios[k],
            per_rev[k],
            int(n_records[k]),
            Directions(Whirl.of(recs[k].block.direction)),
        )
        for k in range(len(recs))
    ]
    info = blocks[0]
    for b in blocks[1:]:  # in the blocks' order, as they ran
        info = info + b
    return info


def _scales(
    rule: SequentialRule, spec: ModelSpec, theta: FloatArray, spin: float, radius: float, noise_at: NoiseAt
) -> tuple[FloatArray, float]:
    """The coefficients' scales of the relative errors and the target on them: with no target
    in the rule, the errors the rule's matching design would reach (target 1); else each
    coefficient's own scale and the rule's target."""
    if rule.target is None:
        match = np.asarray(rule.match_ratios)
        every = Directions.of(rule.directions)
        return reference_errors(spec, theta, spin, radius, match, noise_at(match), rule.match_revolutions, every), 1.0
    return coefficient_scales(spec, theta, spin), rule.target


def chosen_steps(
    step: ChooseBlocks, spin: float, choice: BlockChoice, freq: int, orbit_now: float, store_s: float
) -> list[Step]:
    """The steps of the chosen block(s): per direction (forward first for both) SetOrbit,
    Settle, Acquire of exactly the chosen revolutions, StoreBlock carrying the choice."""
    if choice.ratio is None:
        raise ValueError(f"a {choice.reason} decision chooses no block")
    out: list[Step] = []
    for sign in (w.sign for w in Directions(choice.direction).whirls):
        b = Block(freq, sign, sign * float(choice.ratio) * spin)
        n = choice.revolutions
        out += [
            SetOrbit(step.point, abs(b.orbit - orbit_now) / step.rule.ramp_rate, b),
            Settle(step.point, step.hold, b, step.hold),
            Acquire(step.point, block_time(b.orbit, n), b, n, step.hold),
            StoreBlock(step.point, store_s, b, choice),
        ]
        orbit_now = b.orbit
    return out


def choice_line(point: int, c: BlockChoice) -> str:
    """The run log's line of one decision."""
    what = (
        f"{c.direction} ratio {c.ratio:g}, {c.revolutions} revolutions ({c.seconds:.1f} s)"
        if c.ratio is not None
        else "stop"
    )
    return (
        f"point {point_name(point)}: sequential: {what}: {Choice[c.reason.upper()].value}; "
        f"largest predicted relative error {max(c.before) * 100:.3g} % -> {max(c.after) * 100:.3g} % after {c.spent_s:.1f} s of blocks"
    )

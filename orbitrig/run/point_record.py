"""What becomes of a point's measured blocks: stored, chosen further, identified, completed.

The point procedure (orbitrig.run.procedure) hands :class:`PointRecord` its
StoreBlock, ChooseBlocks, Identify and CompletePoint steps. Files are written and
models identified in the background (orbitrig.run.background), in worker threads
where the work is numerics: nothing here holds up the loop that polls the drives.
"""

from __future__ import annotations

import asyncio
import dataclasses
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Awaitable, Callable

from orbitrig.run.control import StopRun
from orbitrig.run.corrections import Corrections
from orbitrig.run.events import ResultEvent, RunFailed
from orbitrig.run.heap import trim_heap
from orbitrig.run.identification import identify_operating_point
from orbitrig.run.calibration_dof import calibration_dof
from orbitrig.run.plan import OperatingPoint
from orbitrig.run.point_report import point_log_lines, result_payload
from orbitrig.run.sequential_point import MAX_BLOCK_INDEX, PointSoFar, choice_line, chosen_steps, decide
from orbitrig.run.steps import ChooseBlocks, CompletePoint, Identify, Step, StoreBlock
from orbitrig.run.truth import point_truth
from orbitrig.store.layout import point_name
from orbitrig.store.records import BlockChoice, BlockRecord, PointResults
from reduction.sequential import Choice

if TYPE_CHECKING:
    from orbitrig.run.procedure import RunParts


@dataclass
class PointState:
    """What one point's steps hand each other: the blocks measured and stored so far."""

    point: OperatingPoint
    always_confirm: bool  # the run's first point: its manual settings are confirmed even if unchanged
    last: BlockRecord | None = None
    records: dict[str, BlockRecord] = field(default_factory=dict)
    results: asyncio.Task[PointResults] | None = None  # computed in the background
    sequential: BlockChoice | None = None  # a sequential point's last decision (why it stopped)

    def measured(self) -> BlockRecord:
        """The block acquired last (a RuntimeError before the point's first Acquire: a plan out of order)."""
        if self.last is None:
            raise RuntimeError(f"point {point_name(self.point.index)}: no block acquired yet")
        return self.last


class PointRecord:
    """The record steps of a point. ``run_step(step, ps, counted)``: the procedure's own, for a
    sequential point's chosen blocks; ``add_time(key, t0)``: adds wall s since ``t0`` to the
    run's timing (returns time.monotonic())."""

    def __init__(
        self,
        parts: RunParts,
        run_step: Callable[[Step, PointState, bool], Awaitable[None]],
        add_time: Callable[[str, float], float],
    ):
        self.r = parts
        self._run_step = run_step
        self._add_time = add_time

    async def store_block(self, step: StoreBlock, ps: PointState) -> None:
        r = self.r
        rec = ps.measured() if step.choice is None else dataclasses.replace(ps.measured(), choice=step.choice)
        ps.records[step.block.tag] = rec
        r.background.defer_writes()  # until the next speeds are reached (PointProcedure._settle_once)
        r.background.spawn(self._write_block(ps.point, rec), f"store {point_name(ps.point.index)}/{step.block.tag}")
        if r.control.stop_requested and len(ps.records) < len(ps.point.blocks):
            raise StopRun

    async def _write_block(self, p: OperatingPoint, rec: BlockRecord) -> None:
        await self.r.background.write(self.r.store.write_block, p.index, rec)
        self.r.store.log(f"point {point_name(p.index)}: stored {rec.block.tag}")

    async def choose_blocks(self, step: ChooseBlocks, ps: PointState) -> None:
        """A sequential point after its initial list: choose the next block (in a worker thread:
        reduction numerics), run it through the plan's own step kinds, again, until the target
        or the cap. A stop request ends the point unfinished (a resume runs it again)."""
        r, p, freq = self.r, ps.point, step.first_freq
        while True:
            if r.control.stop_requested:
                raise StopRun
            recs = list(ps.records.values())
            so_far = PointSoFar(step.rule, p.spin, tuple(recs), r.rig.channel_index, Corrections.of_rig(r.rig))
            c = await asyncio.to_thread(decide, p.index, so_far)
            if c.ratio is not None and freq > MAX_BLOCK_INDEX:  # no block name left: as at the cap
                c = dataclasses.replace(
                    c, reason=Choice.CAP.name.lower(), ratio=None, revolutions=0, seconds=0.0, after=c.before
                )
            r.store.log(choice_line(p.index, c))
            if c.ratio is None:
                ps.sequential = c
                return
            if c.ratio not in step.rule.candidates:  # the plan's candidates only, whatever the numerics say
                raise RunFailed(
                    f"point {point_name(p.index)}: sequential design chose ratio {c.ratio:g}, not a candidate"
                )
            for sub in chosen_steps(step, p.spin, c, freq, recs[-1].block.orbit, r.rig.estimates.store_s):
                await self._run_step(sub, ps, False)
            freq += 1

    async def identify(self, step: Identify, ps: PointState) -> None:
        """Identify every model for both load measuring systems, in a worker thread: nothing of it
        holds up the loop that polls the drives. A simulated rig's truth is taken first, before the
        next step: it is the bearing at the present manual settings, which the next point changes."""
        r, p, recs = self.r, ps.point, list(ps.records.values())
        truth = None if r.access.truth is None else await asyncio.to_thread(point_truth, p, recs, r.access.truth)

        async def results() -> PointResults:
            t0 = time.monotonic()
            res = await asyncio.to_thread(
                identify_operating_point,
                p.spin,
                recs,
                r.rig.channel_index,
                step.models,
                truth,
                r.rig.calibration_uncertainty,
                Corrections.of_rig(r.rig),
                calibration_dof(r.rig.record),
            )
            res.sequential = ps.sequential
            self._add_time("identify", t0)
            for line in point_log_lines(p, res):
                r.store.log(line)
            await r.background.write(r.store.write_results, p.index, res)
            return res

        ps.results = r.background.spawn(results(), f"identify point {point_name(p.index)}")

    async def complete_point(self, step: CompletePoint, ps: PointState) -> None:
        """Once the results are stored: mark the point complete and publish its results."""
        r, p, results = self.r, ps.point, ps.results
        if results is None:
            raise RuntimeError(f"point {point_name(p.index)}: CompletePoint before its Identify step")

        async def complete() -> None:
            res = await results
            await r.background.write(r.store.complete_point, p.index)
            r.store.log(f"point {point_name(p.index)} {p.label}: complete")
            await asyncio.to_thread(trim_heap)  # the point's blocks are freed: back to the system
            await r.background.earlier_points_done()  # a later point identified sooner waits its turn
            r.emit(ResultEvent(r.run_id, result_payload(r.run_id, p, res)))

        r.background.spawn_point(complete(), f"complete point {point_name(p.index)}")

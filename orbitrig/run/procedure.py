"""The point procedure: manual settings, speeds, settle, acquire, verify; then the record.

Every step kind of the plan has one handler in `PointProcedure.handlers`
and one rule for what comes before it (`BEFORE`: a safe point where a pause
or a stop is honoured, and/or a hold while an interlock suspends the run).
Times in the plan are physical; waits on the rig are converted to wall time
by the rig's `TimeScale`. The steps that record a point (store, choose, identify,
complete) are handled by orbitrig.run.point_record.
"""

from __future__ import annotations

import asyncio
import functools
import logging
import math
import time
from dataclasses import dataclass
from typing import Awaitable, Callable, Iterable

from daq.errors import DaqError, DaqTimeoutError
from daq.stats import AcquisitionStats
from drives.errors import DriveError
from drives.waits import done_or_set
from orbitrig.config import RigConfig
from orbitrig.run.adc_link import (
    abandoned_attempt_line,
    acquisition_hint,
    between_blocks_line,
    block_link_line,
    board_silence,
    orbit_off_hint,
)
from orbitrig.run.averaging import acquire_waits, averaging_rule
from orbitrig.run.background import Background
from orbitrig.run.control import RunControl, StopRun
from orbitrig.run.events import Note, NoteKind, ResultEvent, RunFailed, Severity
from orbitrig.run.identification import block_record
from orbitrig.run.interlock_guard import Suspended, guarded
from orbitrig.run.plan import OperatingPoint
from orbitrig.run.point_record import PointRecord, PointState
from orbitrig.run.suspension import RECHECK_S
from orbitrig.run.steps import (
    Acquire,
    Block,
    ChooseBlocks,
    CompletePoint,
    Identify,
    SetManual,
    SetOrbit,
    SetSpin,
    Settle,
    Step,
    StopDrives,
    StoreBlock,
    VerifyGeometry,
    VerifyPressures,
)
from orbitrig.run.progress import ProgressMeter
from orbitrig.run.rig_io import RigAccess, RigIO
from orbitrig.run.states import ConfirmMode
from orbitrig.run.unanswered import NOBODY, UNANSWERED
from orbitrig.run.supervision import InterlockSupervisor
from orbitrig.run.verification import WrongWhirl, geometry_problems, pressures_settled, radius_missed, whirl_missed
from orbitrig.store.layout import point_name
from orbitrig.store.writer import RunStore
from rigunits import rpm_text

log = logging.getLogger(__name__)
#: wall s after the ramps' expected end by which their first status is read; the block stored
#: before waits for it: its file is built holding the interpreter lock, which that read needs
FIRST_READ_S = 0.015


@dataclass(frozen=True)
class Before:
    """What the engine does before a step: a safe point (None: none; False: pause only, a stop
    must let the step run) and a hold while an interlock suspends the run."""

    safe_point: bool | None
    interlocks: bool


#: every frequency of a point is stored before Identify: a stop lets the identification finish
BEFORE: dict[type[Step], Before] = {
    SetManual: Before(True, True),
    VerifyPressures: Before(None, True),
    SetSpin: Before(True, True),
    SetOrbit: Before(True, True),
    Settle: Before(None, True),
    Acquire: Before(None, True),
    VerifyGeometry: Before(None, True),
    StoreBlock: Before(None, False),
    ChooseBlocks: Before(None, False),
    Identify: Before(False, False),
    CompletePoint: Before(None, False),
    StopDrives: Before(None, False),
}


def last_safe_point(steps: Iterable[Step]) -> Step | None:
    """The last of `steps` (in the order they run) with a safe point before it: the last point's
    Identify; past it no pause can be reached (RunControl.no_safe_point_left). None: no such step."""
    return next((s for s in reversed(list(steps)) if BEFORE[type(s)].safe_point is not None), None)


@dataclass
class RunParts:
    """The run's parts the procedure works with."""

    rig: RigConfig
    access: RigAccess
    io: RigIO
    store: RunStore
    control: RunControl
    supervisor: InterlockSupervisor
    background: Background
    progress: ProgressMeter
    timing: dict[str, float]
    confirm_mode: ConfirmMode
    run_id: str
    emit: Callable[[ResultEvent], None]
    note: Note


class PointProcedure:
    def __init__(self, parts: RunParts):
        self.r = parts
        self.scale = parts.access.time_scale
        self._ramps_end: float | None = None  # monotonic s the last speed command's ramps should end
        self._link_drops = 0  # the A/D reader's link drops said so far (in a block's line or before it)
        self._written: tuple[float, float] | None = None  # rad/s, spin and orbit as last written to the drives
        self.last_safe: Step | None = None  # the run's last step with a safe point (`last_safe_point`)
        self.record = PointRecord(parts, self.run_step, self._add_time)  # the steps after the measurement
        self.handlers: dict[type[Step], Callable[..., Awaitable[None]]] = {  # (its step kind, PointState | None)
            SetManual: self.set_manual,
            VerifyPressures: self.verify_pressures,
            SetSpin: self.set_spin,
            SetOrbit: self.set_orbit,
            Settle: self.settle,
            Acquire: self.acquire,
            VerifyGeometry: self.verify_geometry,
            StoreBlock: self.record.store_block,
            ChooseBlocks: self.record.choose_blocks,
            Identify: self.record.identify,
            CompletePoint: self.record.complete_point,
            StopDrives: self.stop_drives,
        }

    # ------------------------------------------------------------- driving
    async def run_point(self, p: OperatingPoint, steps: list[Step], first: bool) -> None:
        r = self.r
        await self._wait_for_earlier_points()  # bounded memory: no pile of points waiting
        r.background.spawn(r.background.write(r.store.begin_point, p), f"begin point {point_name(p.index)}")
        r.store.log(f"point {point_name(p.index)} {p.label}: begin")
        r.supervisor.pressure_armed = False
        ps = PointState(p, first)
        for step in steps:
            await self.run_step(step, ps)

    async def _wait_for_earlier_points(self) -> None:
        """Until the points before (identified and stored in the background) are down to
        POINTS_IN_FLIGHT, the drives held at their speeds; a slow or stalled disk is noted every
        BACKLOG_NOTE_S. A stop asked meanwhile does not wait for the storage (StopRun at once: both
        drives ramp to zero first, the storage is then waited for with them at standstill,
        orbitrig.run.closing); nor, while nobody can answer the run (its unanswered limit,
        orbitrig.run.unanswered), does a wait longer than that limit: it stops the run."""
        r, t0 = self.r, time.monotonic()
        slow = functools.partial(r.note, severity=Severity.WARNING, kind=NoteKind.STORAGE_WAIT)
        waiting = asyncio.ensure_future(r.background.wait_for_points(note=slow))  # cancelled: no point is
        try:
            while not waiting.done():
                if r.control.stop_requested:
                    raise StopRun
                deadline, limit = r.control.unanswered.deadline_of(t0), r.control.unanswered.limit
                if deadline is not None and time.monotonic() >= deadline:
                    waited = f"waiting for {r.background.oldest_point()} for {limit:g} s, {NOBODY}"
                    r.control.stop_unanswered(
                        f"{UNANSWERED} (nobody can answer: {waited})", f"nobody can answer ({waited})"
                    )
                    raise StopRun
                left = RECHECK_S if deadline is None else min(RECHECK_S, deadline - time.monotonic())
                r.control.wake.clear()  # set by a stop, and by the limit set or lifted: read again
                await done_or_set(waiting, r.control.wake, timeout=left)
            waiting.result()
        finally:
            if not waiting.done():
                waiting.cancel()
                await asyncio.gather(waiting, return_exceptions=True)

    async def run_step(self, step: Step, ps: PointState | None, counted: bool = True) -> None:
        """Run one step after its safe point and interlock hold; ``counted``: its estimate leaves the
        ETA (a sequential point's chosen blocks are inside their ChooseBlocks step's bound)."""
        r = self.r
        r.background.check()
        before = BEFORE[type(step)]
        if before.safe_point is not None:
            await r.control.safe_point(allow_stop=before.safe_point)
            if step is self.last_safe:  # a pause from here on is refused: none could be reached
                r.control.no_safe_point_left()
        if before.interlocks:
            await self._hold_while_suspended()
        await self.handlers[type(step)](step, ps)
        if counted:
            r.progress.spent(self.estimate_of(step, r.confirm_mode))

    @staticmethod
    def estimate_of(step: Step, confirm_mode: ConfirmMode) -> float:
        """Physical seconds still to come for `step` (no operator time in auto mode)."""
        return 0.0 if isinstance(step, SetManual) and confirm_mode == ConfirmMode.AUTO else step.duration

    async def _hold_while_suspended(self) -> None:
        await self.r.control.hold_while_suspended(self.r.supervisor, self.r.rig.interlocks.suspend_timeout_s)

    def _add_time(self, key: str, t0: float) -> float:
        now = time.monotonic()
        self.r.timing[key] = self.r.timing.get(key, 0.0) + now - t0
        return now

    # ----------------------------------------------------- manual settings
    async def set_manual(self, step: SetManual, ps: PointState) -> None:
        await self.r.access.hands.set_manual(
            orbit_radius=step.orbit_radius,
            static_eccentricity=step.static_eccentricity,
            recess_pressure=step.recess_pressure,
            pressure_ratio=step.pressure_ratio,
        )
        if self.r.confirm_mode != ConfirmMode.AUTO and (step.changed or ps.always_confirm):
            said = f"set by hand and confirm: {step.describe()}; {self.r.io.open_drives.state.motion()}"
            await self.r.control.ask(step.step_id, said)

    async def _not_met(self, p: OperatingPoint, problems: list[str]) -> None:
        """Manual settings missed: the operator corrects and confirms (auto mode: the run fails)."""
        msg = f"point {point_name(p.index)}: manual settings not met: " + "; ".join(problems)
        if self.r.confirm_mode == ConfirmMode.AUTO:
            raise RunFailed(msg)
        await self.r.control.ask(
            f"verify:{point_name(p.index)}", f"{msg}; correct and confirm; {self.r.io.open_drives.state.motion()}"
        )

    async def verify_pressures(self, step: VerifyPressures, ps: PointState) -> None:
        r, t0 = self.r, time.monotonic()
        while problems := await self._pressures_settled(ps.point):
            await self._not_met(ps.point, problems)
        r.supervisor.pressure_armed = True
        r.store.log(f"point {point_name(ps.point.index)}: pressures verified")
        self._add_time("verify", t0)

    async def _pressures_settled(self, p: OperatingPoint) -> list[str]:
        """The pressure problems left after waiting for them to settle (`pressures_settled`)."""
        aux = self.r.io.open_aux
        hold = self._hold_while_suspended
        return await pressures_settled(aux.latest, p, self.r.rig.verify, self.scale, hold, lambda: aux.arrival)

    async def verify_geometry(self, step: VerifyGeometry, ps: PointState) -> None:
        """A missed orbit radius is corrected at standstill (the outer spindle's offset, by hand),
        then the block's speeds are set again; the rest with the drives turning."""
        while problems := geometry_problems(ps.measured(), ps.point, self.r.rig):
            hands_on_spindle = radius_missed(ps.measured(), ps.point, self.r.rig)
            if hands_on_spindle:
                await self.stop_drives(StopDrives(ps.point.index, 0.0), ps)
            await self._not_met(ps.point, problems)
            if hands_on_spindle:
                await self._set_speeds(ps.point.spin, step.acquire.block.orbit)
            await self._measure(step.acquire, ps, settle_first=True)
        self.r.store.log(f"point {point_name(ps.point.index)}: orbit radius and static eccentricity verified")

    # -------------------------------------------------------------- speeds
    async def _set_speeds(self, spin: float, orbit: float, ramp: float | None = None) -> None:
        """Command both speeds; `ramp`: the plan's physical s for the drives to get there (None: not known)."""
        t0, self._written = time.monotonic(), None
        try:
            self._written = await self.r.io.open_drives.set_speeds(spin, orbit)
        except DriveError as err:
            raise RunFailed(
                f"cannot set speeds spin {rpm_text(spin)}, orbit {rpm_text(orbit, signed=True)}: {err}"
            ) from err
        now = self._add_time("command", t0)
        self._ramps_end = None if ramp is None else now + self.scale.wall(ramp)
        self.r.note(f"speeds set: spin {rpm_text(spin)}, orbit {rpm_text(orbit, signed=True)}")

    async def set_spin(self, step: SetSpin, ps: PointState) -> None:
        await self._set_speeds(step.spin, step.orbit, step.duration)

    async def set_orbit(self, step: SetOrbit, ps: PointState) -> None:
        await self._set_speeds(ps.point.spin, step.block.orbit, step.duration)

    async def stop_drives(self, step: StopDrives, ps: PointState | None) -> None:
        t0, timeout = time.monotonic(), self.scale.wall(self.r.rig.drives.stop_timeout_s) + 5.0
        await self.r.io.open_drives.stop(emergency=False, wait=True, timeout=timeout)
        self._add_time("stop", t0)
        why = "" if ps is None else f"point {point_name(ps.point.index)}: for the orbit radius, set by hand: "
        self.r.note(f"{why}both drives ramped to zero")

    # -------------------------------------------------- settle and acquire
    async def _settle_once(self, p: OperatingPoint, step: Settle | Acquire) -> None:
        """Wait until both drives hold their setpoints for `step.hold` physical s (Suspended on an interlock)."""
        r, t0, expect, self._ramps_end = self.r, time.monotonic(), self._ramps_end, None
        r.background.resume_writes(None if expect is None else expect + FIRST_READ_S)  # the block stored before
        timeout = self.scale.wall(r.rig.settle.timeout_s) + 5.0
        try:
            settled = r.io.open_drives.wait_settled(hold=self.scale.wall(step.hold), timeout=timeout, expect=expect)
            await guarded(settled, r.supervisor)
        except DriveError as err:
            raise RunFailed(f"point {point_name(p.index)} [{step.block.tag}]: drives did not settle: {err}") from err
        self._add_time("settle", t0)

    async def settle(self, step: Settle, ps: PointState) -> None:
        while True:
            try:
                return await self._settle_once(ps.point, step)
            except Suspended:
                await self._hold_while_suspended()

    async def acquire(self, step: Acquire, ps: PointState) -> None:
        await self._measure(step, ps, settle_first=False)

    def _adc_link_drops(self) -> int:
        return 0 if self.r.io.adc is None else self.r.io.adc.link_drops

    def _say_drops_before(self, p: OperatingPoint, tag: str) -> None:
        """Say the A/D link drops since the last attempt at a block (or the rig's opening), once."""
        if (drops := self._adc_link_drops() - self._link_drops) > 0:
            self.r.note(between_blocks_line(p.index, tag, drops), Severity.WARNING, NoteKind.ADC_LINK_DROP)
        self._link_drops += drops

    def _say_abandoned(self, p: OperatingPoint, tag: str, begun: AcquisitionStats | None) -> None:
        """Say the A/D link drops of an attempt at a block that a suspension abandoned (`begun`: the
        board's counts as it began; None: no attempt had begun), once: the next attempt's drops start after them."""
        adc = self.r.io.adc
        if begun is not None and adc is not None:
            if (dropped := abandoned_attempt_line(p.index, tag, adc.stats.since(begun))) is not None:
                self.r.note(dropped, Severity.WARNING, NoteKind.ADC_LINK_DROP)

    def _why_failed(self, err: Exception, p: OperatingPoint, b: Block) -> str:
        """The end of an acquisition's failure line: the block's whirl, the board's silence, or the
        error and what to check (the orbit measured off its set speed: the drives' device ids)."""
        if isinstance(err, WrongWhirl):
            return f": {err}"
        silent, d = board_silence(self.r.io.adc), self.r.rig.drives
        if silent is not None:  # a board now silent says so, not the speeds it sent before
            return f": {silent}"
        said = f" ({type(err).__name__}: {err})"
        if isinstance(err, DaqTimeoutError):
            said += orbit_off_hint(err.orbit_measured, p.spin, b.orbit, d.spin_id, d.orbit_id)
        return said + acquisition_hint(isinstance(err, DaqTimeoutError) and err.heard)

    async def _measure(self, step: Acquire, ps: PointState, *, settle_first: bool) -> None:
        """Acquire one block (settled first if asked); after a suspension or a failed acquisition
        (retried `averaging.retries` times) the block is settled and acquired again; an attempt
        waits as `acquire_waits` says, for the block and for an A/D board that sends nothing."""
        r, p, b = self.r, ps.point, step.block
        av = r.rig.averaging
        timeout, silence = acquire_waits(av, b.orbit, step.revolutions, self.scale.wall)
        attempts = 0
        while True:
            begun = None  # the A/D board's counts as the attempt began
            try:
                if settle_first:
                    await self._settle_once(p, step)
                settle_first = True
                t0 = time.monotonic()
                r.progress.block(len(ps.records) + 1, step.revolutions)
                rule = averaging_rule(step, p.spin, av.speed_tolerance, r.rig.probe_channels, self._written)
                self._say_drops_before(p, b.tag)
                begun = None if r.io.adc is None else r.io.adc.stats
                try:
                    avg = await guarded(r.io.acquire(rule, timeout=timeout, silence=silence), r.supervisor)
                finally:
                    self._link_drops = self._adc_link_drops()  # the attempt's own: said with its outcome
                self._add_time("acquire", t0)
                if (dropped := block_link_line(p.index, b.tag, avg.stats)) is not None:
                    r.note(dropped, Severity.WARNING, NoteKind.ADC_LINK_DROP)
                rec = block_record(b, avg, r.rig, self._written or (math.nan, math.nan))
                if (wrong := whirl_missed(rec, r.rig)) is not None:
                    raise WrongWhirl(wrong)
                ps.last = rec
                r.progress.block_acquired()
                return
            except Suspended:
                self._say_abandoned(p, b.tag, begun)  # before the hold: the attempt's data is gone
                await self._hold_while_suspended()
            except (DaqError, TimeoutError, WrongWhirl) as err:
                attempts += 1
                msg = f"point {point_name(p.index)} [{b.tag}]: acquisition failed{self._why_failed(err, p, b)}"
                if attempts > av.retries:  # said again as the run's failure (its state line)
                    r.note(msg)
                    raise RunFailed(msg) from err
                r.note(msg, Severity.WARNING, NoteKind.ACQUISITION_RETRIED)

"""The run engine: one executor owns the drives and runs a plan (bluesky style).

States (docs/protocols/mqtt.md): idle -> running <-> paused | waiting -> stopping ->
idle, or faulted after a failure. Outcomes: completed | stopped | aborted |
failed.

- ``request_pause``: hold at the next safe point (before a point's manual
  settings, a speed change or the identification); drives keep their speeds.
- ``request_stop``: finish the current orbit frequency, store it, ramp both
  drives to zero; the run ends as stopped (a point whose every frequency is
  stored is identified and completed first).
- ``request_abort``: cancel at once, emergency ramp (OFF3), keep what is
  complete; the run ends as aborted.
- ``confirm(step)``: the operator confirms a manual setting the run waits for.
- Interlocks (orbitrig.run.interlocks) suspend the run (state paused, message
  says why) until the condition clears, then the block is settled and
  acquired again; a drive trip or a lost trigger fails the run.

Every exit path stops both drives (in a ``finally``; each cleanup failure is
logged and the rest still runs) and closes the run file with its status.
The engine does no terminal I/O: it publishes events to subscribers (the
terminal UI of `orbitrig sweep`, MQTT in `orbitrig serve`).
"""

from __future__ import annotations

import asyncio
import datetime as _dt
import logging
import math
import time
from dataclasses import asdict, dataclass, field, is_dataclass
from pathlib import Path
from typing import Callable, Literal

import numpy as np

from orbitrig.run import interlocks as interlocks
from orbitrig.config import LMS, MPA, RPM, ConfigError, MatrixConfig, RigConfig
from orbitrig.errors import OrbitrigError
from orbitrig.run.plan import (
    Acquire, Identify, OperatingPoint, SetManual, SetOrbit, SetSpin, Settle, Step, Store, Verify, expand,
    operating_points,
)  # fmt: skip
from orbitrig.run.rig_io import sim_speedup
from orbitrig.store.writer import BlockRecord, PointResults, RunStore, now_iso

log = logging.getLogger(__name__)

IDLE, RUNNING, PAUSED, WAITING, STOPPING, FAULTED = "idle", "running", "paused", "waiting", "stopping", "faulted"
COMPLETED, STOPPED, ABORTED, FAILED = "completed", "stopped", "aborted", "failed"
COHERENCE_PAIRS = (("x", "fx"), ("y", "fx"), ("x", "fy"), ("y", "fy"))


# ------------------------------------------------------------------ events
@dataclass(frozen=True)
class StatusEvent:
    state: str
    run_id: str | None
    since: str  # ISO-8601
    message: str = ""


@dataclass(frozen=True)
class ProgressEvent:
    run_id: str | None
    point: int  # 1-based count of points in this run
    points: int
    frequency: int  # 1-based count of blocks (frequency x direction) in the point
    frequencies: int
    revolutions: int  # good revolutions so far in the current block
    eta_s: float | None


@dataclass(frozen=True)
class ResultEvent:
    run_id: str | None
    payload: dict


Event = StatusEvent | ProgressEvent | ResultEvent


@dataclass
class RunOutcome:
    status: Literal["completed", "stopped", "aborted", "failed"]
    message: str
    run_id: str
    out_dir: Path
    completed_points: list[int] = field(default_factory=list)
    points: int = 0


class RunFailed(OrbitrigError):
    """The run cannot go on (interlock, verification, hardware)."""


class _Suspended(Exception):
    def __init__(self, trip: interlocks.Trip):
        super().__init__(trip.message)
        self.trip = trip


class _StopRun(Exception):
    """A stop request reached a safe point."""


class RunEngine:
    def __init__(self, rig: RigConfig, *, out_dir: Path, sim=None,
                 confirm_mode: Literal["prompt", "remote", "auto"] | None = None):  # fmt: skip
        self.rig = rig
        self.out_dir = Path(out_dir)
        self.sim = sim
        self.confirm_mode = confirm_mode or ("auto" if sim is not None else "prompt")
        if self.confirm_mode not in ("prompt", "remote", "auto"):
            raise ValueError(f"confirm_mode {self.confirm_mode!r} is not one of prompt, remote, auto")
        self.speedup = sim_speedup(sim)
        self.state: str = IDLE
        self.run_id: str | None = None
        self.waiting_step: str | None = None
        self.message = ""
        self.since = now_iso()
        self.timing: dict[str, float] = {}  # wall s per activity (bench)
        self._subs: list[Callable[[Event], None]] = []
        self.revolution_taps: list[Callable[[object], None]] = []  # every revolution (orbitrig.service.live)
        self._reset_requests()
        self._io = None
        self._pending: set[asyncio.Task] = set()  # storage and identification in the background
        self._bg_error: BaseException | None = None
        self._store: RunStore | None = None
        self._body: asyncio.Task | None = None
        self._t0 = time.monotonic()
        self._progress = dict(point=0, points=0, frequency=0, frequencies=0)
        self._revs = 0
        self._last_progress = 0.0
        self._remaining_est = 0.0
        self._pressure_armed = False

    # ------------------------------------------------------------- public API
    @property
    def io(self):
        """The open rig (orbitrig.rig_io.RigIO) while a run has it, else None."""
        return self._io

    def subscribe(self, callback: Callable[[Event], None]) -> None:
        self._subs.append(callback)

    def request_pause(self) -> None:
        if self.state in (RUNNING, WAITING):
            self._pause_req = True
            self._log_event("pause requested (honoured at the next safe point)")
        self._wake.set()

    def request_resume(self) -> None:
        self._pause_req = False
        self._wake.set()

    def request_stop(self) -> None:
        if self.state in (IDLE, FAULTED):
            return
        self._stop_req = True
        self._wake.set()
        if self.state != STOPPING:
            self._set_state(STOPPING, "stop requested: finishing the current orbit frequency")

    def request_abort(self) -> None:
        if self.state in (IDLE, FAULTED) or self._abort_req:
            return
        self._abort_req = True
        self._wake.set()
        self._set_state(STOPPING, "abort requested: emergency ramp down")
        if self._body is not None and not self._body.done():
            self._body.cancel()

    def confirm(self, step: str) -> None:
        """Confirm the manual setting `step` (e.g. 'manual:0003'); raises if not waiting for it."""
        if self.state != WAITING or self.waiting_step is None:
            raise OrbitrigError(f"not waiting for a confirmation (state {self.state})")
        if step != self.waiting_step:
            raise OrbitrigError(f"waiting for '{self.waiting_step}', not '{step}'")
        self._confirmed, self.waiting_step = step, None
        self._set_state(RUNNING, f"confirmed {step}")
        self._wake.set()

    # ----------------------------------------------------------------- run
    async def run(self, matrix: MatrixConfig, *, resume: bool = False) -> RunOutcome:
        if self.state not in (IDLE, FAULTED):
            raise OrbitrigError(f"a run is active (state {self.state})")
        steps = expand(matrix, self.rig)  # ConfigError before anything starts
        points = {p.index: p for p in operating_points(matrix, self.rig)}
        if resume:
            store = RunStore.open_existing(self.out_dir)
            rig_text, matrix_text, _ = store.stored_configs()
            if matrix.text and matrix.text != matrix_text:
                raise ConfigError(matrix.file, ["differs from the matrix of the run being resumed "
                                                f"in {store.path}; resume with the stored matrix"])  # fmt: skip
            done = store.prepare_resume()
        else:
            store = RunStore.create(self.out_dir, rig_text=self.rig.text, matrix_text=matrix.text,
                                    matrix_name=matrix.name, sim=self.sim is not None)  # fmt: skip
            done = []
        self._store = store
        self._reset_requests()
        now = _dt.datetime.now(_dt.timezone.utc)  # millisecond resolution: ids stay unique
        self.run_id = f"{matrix.name}-{now.strftime('%Y%m%dT%H%M%S')}.{now.microsecond // 1000:03d}Z"
        self._t0 = time.monotonic()
        self.timing = {"wall": 0.0, "settle": 0.0, "acquire": 0.0, "confirm": 0.0, "suspended": 0.0}
        todo = [i for i in points if i not in done]
        self._progress.update(point=0, points=len(todo), frequency=0, frequencies=0)
        self._remaining_est = sum(self._est(s) for s in steps if s.point is None or s.point in todo)
        status, message = FAILED, ""
        store.log(f"{'resume' if resume else 'start'} run {self.run_id}: matrix {matrix.name}, "
                  f"{len(todo)} of {len(points)} points to run, sim={self.sim is not None}")  # fmt: skip
        self._set_state(RUNNING, f"run {self.run_id} started" + (" (resumed)" if resume else ""))
        from orbitrig.run.rig_io import RigIO  # opens daq/drives: imported when a run starts

        io = RigIO(self.rig, sim=self.sim, on_revolution=self._on_revolution)
        entered = False
        monitor = None
        try:
            try:
                await io.__aenter__()
            except Exception as err:
                raise RunFailed(f"cannot open the rig: {type(err).__name__}: {err}") from err
            entered = True
            self._io = io
            monitor = asyncio.create_task(self._monitor(), name="run-monitor")
            self._body = asyncio.create_task(self._execute(steps, points, set(done)), name="run-body")
            status = await self._body
            message = {COMPLETED: "all points completed", STOPPED: "stopped by the operator"}[status]
        except asyncio.CancelledError:
            if not self._abort_req:
                status, message = ABORTED, "run cancelled"
                raise
            status, message = ABORTED, "aborted by the operator"
        except (RunFailed, OrbitrigError) as err:
            status, message = FAILED, str(err)
            log.error("run failed: %s", err)
        except Exception as err:  # a bug: still stop the drives and close the file
            status, message = FAILED, f"{type(err).__name__}: {err}"
            log.exception("run failed")
        finally:
            self._body = None
            if status == FAILED:
                self._set_state(FAULTED, message)
            elif self.state != STOPPING:
                self._set_state(STOPPING, message)
            await self._cleanup(io if entered else None, monitor, store, status, message)
            if status != FAILED:
                self._set_state(IDLE, f"run {self.run_id} {status}: {message}")
        completed = store.completed_points()
        return RunOutcome(status, message, self.run_id, self.out_dir, completed, len(points))

    async def _cleanup(self, io, monitor, store: RunStore, status: str, message: str) -> None:
        """Every exit path: stop the monitor, stop both drives, close links, close the file with its status."""
        emergency = status in (ABORTED, FAILED)

        async def stop_drives():
            timeout = self.rig.drives.stop_timeout_s / self.speedup + 5.0
            await io.drives.stop(emergency=emergency, wait=True, timeout=timeout)

        actions = []
        if monitor is not None:
            actions.append(("stop the monitor", self._cancel(monitor)))
        if io is not None and io.drives is not None:
            actions.append(("stop both drives", stop_drives()))
        if io is not None:
            actions.append(("close the rig links", io.__aexit__(None, None, None)))
        for what, coro in actions:
            try:
                await coro
            except BaseException as err:  # noqa: BLE001 - every cleanup step must run
                log.error("cleanup: cannot %s: %s: %s", what, type(err).__name__, err)
                self._log_event(f"cleanup: cannot {what}: {err}")
        self._io = None
        while self._pending:  # writes and identifications in flight finish first (never cut off)
            await asyncio.gather(*list(self._pending), return_exceptions=True)
        self.timing["wall"] = time.monotonic() - self._t0
        for what, fn in (("write the run status", lambda: store.set_status(status, message)),
                         ("write coefficients.csv", store.write_csv)):  # fmt: skip
            try:
                fn()
            except Exception as err:  # noqa: BLE001
                log.error("cleanup: cannot %s: %s", what, err)
        store.log(f"run {self.run_id} ended: {status}: {message}")

    async def _write(self, fn, *args):
        """One storage write, in a thread, in submission order (a FIFO lock)."""
        async with self._writes:
            t = time.monotonic()
            try:
                return await asyncio.to_thread(fn, *args)
            finally:
                self.timing["store"] = self.timing.get("store", 0.0) + time.monotonic() - t

    def _background(self, coro, name: str) -> None:
        """Storage and identification overlap the next motion; an abort or a stop waits for them."""
        task = asyncio.create_task(coro, name=name)
        self._pending.add(task)
        task.add_done_callback(self._background_done)

    def _background_done(self, task: asyncio.Task) -> None:
        self._pending.discard(task)
        if not task.cancelled() and task.exception() is not None and self._bg_error is None:
            self._bg_error = task.exception()
            log.error("%s failed: %s", task.get_name(), self._bg_error)

    def _check_background(self) -> None:
        if self._bg_error is not None:
            err = self._bg_error
            raise RunFailed(f"storage or identification failed: {type(err).__name__}: {err}") from err

    async def _drain(self) -> None:
        while self._pending:
            await asyncio.gather(*list(self._pending), return_exceptions=True)
        self._check_background()

    def _est(self, step: Step) -> float:
        """Estimated physical duration still to come for `step` (no operator time in auto mode)."""
        return 0.0 if isinstance(step, SetManual) and self.confirm_mode == "auto" else step.duration

    @staticmethod
    async def _cancel(task: asyncio.Task) -> None:
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)

    # --------------------------------------------------------------- body
    async def _execute(self, steps: list[Step], points: dict[int, OperatingPoint], done: set[int]) -> str:
        by_point: dict[int, list[Step]] = {}
        for s in steps:
            if s.point is not None:
                by_point.setdefault(s.point, []).append(s)
        first = True
        try:
            for idx, psteps in by_point.items():
                if idx in done:
                    continue
                await self._safe_point()
                self._progress.update(point=self._progress["point"] + 1, frequency=0,
                                      frequencies=len(points[idx].blocks))  # fmt: skip
                await self._run_point(points[idx], psteps, first)
                first = False
        except _StopRun:
            await self._drain()
            return STOPPED
        await self._drain()
        return STOPPED if self._stop_req else COMPLETED

    async def _run_point(self, p: OperatingPoint, steps: list[Step], first: bool) -> None:
        store = self._store
        self._background(self._write(store.begin_point, p), f"begin point {p.index:04d}")
        store.log(f"point {p.index:04d} {p.label}: begin")
        self._pressure_armed = False
        records: dict[str, BlockRecord] = {}
        last_pair = None
        last_rec = None
        i = 0
        while i < len(steps):
            step = steps[i]
            self._check_background()
            if isinstance(step, (SetManual, SetSpin, SetOrbit, Identify)):
                # every frequency of the point is stored before Identify: a stop lets it finish
                await self._safe_point(allow_stop=not isinstance(step, Identify))
            if not isinstance(step, (Store, Identify)):
                await self._interlocks()
            if isinstance(step, SetManual):
                await self._manual(step, prompt=step.changed or first)
            elif isinstance(step, Verify) and "pressures" in step.quantities:
                t = time.monotonic()
                await self._verify_pressures(p, step)
                self.timing["verify"] = self.timing.get("verify", 0.0) + time.monotonic() - t
            elif isinstance(step, SetSpin):
                await self._set_speeds(step.spin, step.orbit)
            elif isinstance(step, SetOrbit):
                await self._set_speeds(p.spin, step.block.orbit)
            elif isinstance(step, Settle):
                acq = steps[i + 1]
                assert isinstance(acq, Acquire) and acq.block == step.block
                last_pair = (step, acq)
                last_rec = await self._measure(p, step, acq)
                self._remaining_est -= self._est(acq)
                i += 1
            elif isinstance(step, Verify) and "geometry" in step.quantities:
                while not await self._verify_geometry(p, last_rec):
                    last_rec = await self._measure(p, *last_pair)
            elif isinstance(step, Store) and step.block is not None:
                records[step.block.tag] = last_rec
                self._background(self._store_block(p, last_rec), f"store {p.index:04d}/{step.block.tag}")
                if self._stop_req and len(records) < len(p.blocks):
                    raise _StopRun
            elif isinstance(step, Identify):
                truth = self._truth(p, list(records.values())) if self.sim is not None else None
                self._background(self._finish_point(p, dict(records), step, truth), f"finish point {p.index:04d}")
            elif isinstance(step, Store) and step.block is None:
                pass  # written last by _finish_point, after the identification
            self._remaining_est -= self._est(step)
            i += 1

    async def _store_block(self, p: OperatingPoint, rec: BlockRecord) -> None:
        await self._write(self._store.write_block, p.index, rec)
        self._store.log(f"point {p.index:04d}: stored {rec.block.tag}")

    async def _finish_point(self, p: OperatingPoint, records: dict, step: Identify, truth: dict | None) -> None:
        """Identify with every model for both load measuring systems, store, then mark the point complete."""
        t = time.monotonic()
        results = await asyncio.to_thread(self._reduce, p, records, step, truth)
        self.timing["identify"] = self.timing.get("identify", 0.0) + time.monotonic() - t
        await self._write(self._store.write_results, p.index, results)
        await self._write(self._store.complete_point, p.index)
        self._store.log(f"point {p.index:04d} {p.label}: complete")
        self._emit(ResultEvent(self.run_id, self._result_payload(p, results)))

    # ---------------------------------------------------------- steps
    async def _manual(self, step: SetManual, *, prompt: bool) -> None:
        if self.sim is not None:
            self._io.set_manual(orbit_radius=step.orbit_radius, static_eccentricity=step.static_eccentricity,
                                recess_pressure=step.recess_pressure, pressure_ratio=step.pressure_ratio)  # fmt: skip
        if self.confirm_mode != "auto" and prompt:
            await self._wait_confirm(step.step_id, "set by hand and confirm: " + step.describe())

    async def _verify_pressures(self, p: OperatingPoint, step: Verify) -> None:
        v = self.rig.verify
        while True:
            deadline = time.monotonic() + max(3.0, 20.0 / self.speedup)
            while True:
                await self._interlocks()
                aux = self._io.aux.latest()
                problems = _pressure_problems(aux, p, v)
                if not problems or time.monotonic() > deadline:
                    break
                await asyncio.sleep(0.1)
            if not problems:
                self._pressure_armed = True
                self._store.log(f"point {p.index:04d}: pressures verified")
                return
            msg = f"point {p.index:04d}: manual settings not met: " + "; ".join(problems)
            if self.confirm_mode == "auto":
                raise RunFailed(msg)
            await self._wait_confirm(f"verify:{p.index:04d}", msg + "; correct and confirm")

    async def _verify_geometry(self, p: OperatingPoint, rec: BlockRecord) -> bool:
        problems = _geometry_problems(rec, p, self.rig)
        if not problems:
            self._store.log(f"point {p.index:04d}: orbit radius and static eccentricity verified")
            return True
        msg = f"point {p.index:04d}: manual settings not met: " + "; ".join(problems)
        if self.confirm_mode == "auto":
            raise RunFailed(msg)
        await self._wait_confirm(f"verify:{p.index:04d}", msg + "; correct and confirm")
        return False

    async def _set_speeds(self, spin: float, orbit: float) -> None:
        from drives.errors import DriveError

        try:
            await self._io.drives.set_speeds(spin, orbit)
        except DriveError as err:
            raise RunFailed(f"cannot set speeds spin {spin / RPM:.0f} rpm, orbit {orbit / RPM:+.0f} rpm: {err}") from err
        self._log_event(f"speeds set: spin {spin / RPM:.0f} rpm, orbit {orbit / RPM:+.1f} rpm")

    async def _measure(self, p: OperatingPoint, settle: Settle, acq: Acquire) -> BlockRecord:
        """Settle, then acquire one block; suspend on interlocks, retry a failed acquisition."""
        from daq.errors import DaqError
        from drives.errors import DriveError

        b = acq.block
        period = 2 * math.pi / abs(b.orbit)
        acq_timeout = (self.rig.averaging.timeout_factor * (acq.revolutions + 1) * period
                       + self.rig.averaging.timeout_margin_s) / self.speedup + 2.0  # fmt: skip
        settle_timeout = self.rig.settle.timeout_s / self.speedup + 5.0
        attempts = 0
        while True:
            try:
                t = time.monotonic()
                try:
                    await self._guarded(self._io.drives.wait_settled(hold=settle.hold / self.speedup,
                                                                     timeout=settle_timeout))  # fmt: skip
                except DriveError as err:
                    raise RunFailed(f"point {p.index:04d} [{b.tag}]: drives did not settle: {err}") from err
                t1 = time.monotonic()
                self.timing["settle"] += t1 - t
                self._revs = 0
                self._progress["frequency"] = p.blocks.index(b) + 1
                self._emit_progress(force=True)
                a = await self._guarded(self._io.acquire(acq.revolutions, timeout=acq_timeout))
                self.timing["acquire"] += time.monotonic() - t1
                return self._record(b, a)
            except _Suspended as s:
                await self._suspend(s.trip)
            except (DaqError, TimeoutError) as err:
                attempts += 1
                msg = (f"point {p.index:04d} [{b.tag}]: acquisition failed ({type(err).__name__}: {err}); "
                       "orbit trigger lost or A/D link down?")  # fmt: skip
                self._log_event(msg)
                if attempts > self.rig.averaging.retries:
                    raise RunFailed(msg) from err

    async def _guarded(self, coro):
        """Await `coro` while watching the interlocks: fail or suspend as they say."""
        task = asyncio.ensure_future(coro)
        try:
            while True:
                done, _ = await asyncio.wait({task}, timeout=0.05)
                if done:
                    return task.result()
                trips = self._trips()
                for t in trips:
                    if t.action == interlocks.FAIL:
                        raise RunFailed(f"interlock: {t.message}")
                if trips:
                    raise _Suspended(trips[0])
        finally:
            if not task.done():
                task.cancel()
                await asyncio.gather(task, return_exceptions=True)

    async def _interlocks(self) -> None:
        """Between steps: fail on a fail-trip, hold on a suspend-trip until it clears."""
        for t in self._trips():
            if t.action == interlocks.FAIL:
                raise RunFailed(f"interlock: {t.message}")
            await self._suspend(t)
            return

    def _trips(self) -> list[interlocks.Trip]:
        return interlocks.check(self._io.aux.latest(), self._io.drives.state, self.rig.interlocks,
                                pressure_armed=self._pressure_armed)  # fmt: skip

    async def _suspend(self, trip: interlocks.Trip) -> None:
        t0 = time.monotonic()
        limit = self.rig.interlocks.suspend_timeout_s
        self._set_state(PAUSED, f"suspended by interlock: {trip.message}")
        while True:
            trips = self._trips()
            fail = [t for t in trips if t.action == interlocks.FAIL]
            if fail:
                raise RunFailed(f"interlock: {fail[0].message}")
            if not trips:
                break
            if self._stop_req:
                raise _StopRun
            if time.monotonic() - t0 > limit:
                raise RunFailed(f"interlock: {trips[0].message} for more than {limit:g} s")
            self._wake.clear()
            try:
                await asyncio.wait_for(self._wake.wait(), 0.1)
            except TimeoutError:
                pass
        self.timing["suspended"] += time.monotonic() - t0
        self._set_state(RUNNING, f"interlock cleared ({trip.kind}): settling and acquiring the block again")

    async def _safe_point(self, allow_stop: bool = True) -> None:
        if self._stop_req and allow_stop:
            raise _StopRun
        if not self._pause_req:
            return
        self._set_state(PAUSED, "paused at a safe point (drives keep their speeds)")
        while self._pause_req and not self._stop_req:
            self._wake.clear()
            await self._wake.wait()
        if self._stop_req and allow_stop:
            raise _StopRun
        self._set_state(RUNNING, "resumed")

    async def _wait_confirm(self, step_id: str, message: str) -> None:
        t0 = time.monotonic()
        self.waiting_step = step_id
        self._confirmed = None
        # the operator (terminal or MQTT) confirms by this id: {"cmd": "confirm", "step": ...}
        self._set_state(WAITING, f"{message} (confirm step {step_id!r})")
        try:
            while self._confirmed != step_id:
                if self._stop_req:
                    raise _StopRun
                self._wake.clear()
                await self._wake.wait()
        finally:
            self.waiting_step = None
        self.timing["confirm"] += time.monotonic() - t0
        if self._pause_req:
            await self._safe_point()

    # ------------------------------------------------------------ reduction
    def _record(self, b, a) -> BlockRecord:
        blk = a.block
        ch = self.rig.channel_index
        rp = np.asarray(blk.record_phasors)
        x, y = (rp[:, ch["x_a"]] + rp[:, ch["x_b"]]) / 2, (rp[:, ch["y_a"]] + rp[:, ch["y_b"]]) / 2
        coh = np.zeros((2, 4))
        from reduction.coherence import coherence

        for i, lms in enumerate(LMS):
            d = {"x": x, "y": y, "fx": rp[:, ch[f"fx_{lms}"]], "fy": rp[:, ch[f"fy_{lms}"]]}
            for j, (u, f) in enumerate(COHERENCE_PAIRS):
                coh[i, j] = float(coherence(d[u], d[f], axis=0))
        stats = blk.stats.to_dict() if hasattr(blk.stats, "to_dict") else (asdict(blk.stats) if is_dataclass(blk.stats) else {})
        stats = {k: v for k, v in stats.items() if isinstance(v, (int, float, dict))}
        return BlockRecord(
            block=b, measured_orbit_speed=float(blk.orbit_speed), raw_counts=a.raw_counts, slots=a.slots,
            gains=np.asarray(self.rig.gains), offsets=np.asarray(self.rig.offsets), mean=np.asarray(blk.mean),
            record_phasors=rp, phasors=np.asarray(blk.phasors), dc=np.asarray(blk.dc),
            rms_residual=np.asarray(blk.rms_residual), coherence=coh, stats=stats,
        )  # fmt: skip

    def _reduce(self, p: OperatingPoint, records: dict[str, BlockRecord], step: Identify,
                truth: dict | None) -> PointResults:  # fmt: skip
        return identify_point(p.spin, list(records.values()), self.rig.channel_index, step.models, truth)

    def _truth(self, p: OperatingPoint, recs: list[BlockRecord]) -> dict:
        out = {"orbit_hz": [], "orbit": [], "K": [], "C": [], "D": []}
        recs = sorted(recs, key=lambda r: (r.block.freq, -r.block.direction))  # orbit table order
        for r in recs:
            t = self._io.truth(p.spin, r.block.orbit)
            out["orbit_hz"].append(r.block.orbit_hz)
            out["orbit"].append(r.block.orbit)
            for k in "KCD":
                out[k].append(np.asarray(t[k], dtype=float).tolist())
        low = min(recs, key=lambda r: (abs(r.block.orbit), -r.block.direction))
        t0 = self._io.truth(p.spin, low.block.orbit)
        for k in "KCD":
            out[f"{k}0"] = np.asarray(t0[k], dtype=float).tolist()
        return out

    def _result_payload(self, p: OperatingPoint, res: PointResults) -> dict:
        rows = []
        for (lms, _), e in res.identifications.items():
            spec = e["spec"]
            row = {"lms": lms, "model": spec.model, "freq_dep": spec.freq_dep, "method": spec.method}
            if "json" in e:
                j = e["json"]
                row.update(coefficients=j["coefficients"], std_errors=j["std_errors"],
                           condition_number=j["condition_number"], residual_rms=j["residual_rms"])  # fmt: skip
            else:
                row["error"] = e["error"]
            rows.append(row)
        out = {"run_id": self.run_id, **p.settings(), "identification": rows, "lms_comparison": res.lms_comparison}
        if res.truth is not None:
            out["truth"] = {k: res.truth[k] for k in ("K0", "C0", "D0")}
        return out

    # -------------------------------------------------------- events, logs
    def _reset_requests(self) -> None:
        self._pause_req = self._stop_req = self._abort_req = False
        self._confirmed: str | None = None
        self._wake = asyncio.Event()
        self._writes = asyncio.Lock()
        self._bg_error = None

    def _emit(self, ev: Event) -> None:
        for cb in list(self._subs):
            try:
                cb(ev)
            except Exception:  # noqa: BLE001 - a subscriber must not break the run
                log.exception("event subscriber failed")

    def _set_state(self, state: str, message: str = "") -> None:
        self.state, self.message, self.since = state, message, now_iso()
        self._log_event(message, state)
        self._emit(StatusEvent(state, self.run_id, self.since, message))

    def _log_event(self, message: str, state: str | None = None) -> None:
        state = state or self.state
        log.info("[%s] %s", state, message)
        if self._store is not None:
            self._store.logs.add("events", (time.monotonic() - self._t0, state, message))
            try:
                self._store.log(f"[{state}] {message}")
            except OSError:
                pass

    def _on_revolution(self, rev) -> None:
        self._revs += 1
        for tap in self.revolution_taps:
            tap(rev)
        self._emit_progress()

    def _emit_progress(self, force: bool = False) -> None:
        now = time.monotonic()
        if not force and now - self._last_progress < 0.1:
            return
        self._last_progress = now
        pr = self._progress
        eta = max(0.0, self._remaining_est) / self.speedup
        self._emit(ProgressEvent(self.run_id, pr["point"], pr["points"], pr["frequency"], pr["frequencies"],
                                 self._revs, round(eta, 1)))  # fmt: skip

    async def _monitor(self) -> None:
        """CAN and drive logs every 0.5 s (wall), kept until the next write."""
        while True:
            t = time.monotonic() - self._t0
            io, store = self._io, self._store
            try:
                store.logs.add("can", _can_row(t, io.aux.latest()))
                store.logs.add("drives", _drive_row(t, io.drives.state))
            except Exception:  # noqa: BLE001 - logging must not break the run
                log.debug("monitor sample failed", exc_info=True)
            await asyncio.sleep(0.5)


# ------------------------------------------------------------- pure helpers
def identify_point(spin: float, recs: list[BlockRecord], ch: dict[str, int], models: list,
                   truth: dict | None = None) -> PointResults:
    """One operating point's results: the orbit table of each load measuring system (forward
    and backward blocks together), every model of ``models`` (ModelSpec) identified on each
    (a refused model keeps its reason), and the two systems compared. Pure: no I/O."""
    from reduction.errors import ReductionError
    from reduction.identify import identify

    recs = sorted(recs, key=lambda r: (r.block.freq, -r.block.direction))
    tables = {lms: orbit_table(spin, recs, ch, lms) for lms in LMS}
    idents = {}
    for lms in LMS:
        for spec in models:
            try:
                res = identify(tables[lms], model=spec.model, freq_dep=spec.freq_dep, method=spec.method)
                idents[(lms, spec.key)] = {"spec": spec, "json": res.to_dict()}
            except ReductionError as err:
                idents[(lms, spec.key)] = {"spec": spec, "error": str(err)}
    return PointResults(tables, idents, lms_comparison(recs, ch), truth)


def orbit_table(spin: float, recs: list[BlockRecord], ch: dict[str, int], lms: str):
    """Orbit table of one point for one load measuring system (Omega > 0, direction in the phasors)."""
    from reduction.table import OrbitTable

    ph = np.array([r.phasors for r in recs])
    orbit = np.array([r.measured_orbit_speed if math.isfinite(r.measured_orbit_speed) and r.measured_orbit_speed > 0
                      else abs(r.block.orbit) for r in recs])  # fmt: skip
    i = 0 if lms == "piezo" else 1
    return OrbitTable(
        spin=spin, orbit=orbit,
        x=(ph[:, ch["x_a"]] + ph[:, ch["x_b"]]) / 2, y=(ph[:, ch["y_a"]] + ph[:, ch["y_b"]]) / 2,
        fx=ph[:, ch[f"fx_{lms}"]], fy=ph[:, ch[f"fy_{lms}"]],
        gamma2=np.array([r.coherence[i] for r in recs]),
    )  # fmt: skip


def lms_comparison(recs: list[BlockRecord], ch: dict[str, int]) -> dict:
    """Strain vs piezo forces per block: amplitude ratio and phase difference (deg)."""
    out: dict = {"orbit_hz": [r.block.orbit_hz for r in recs], "direction": [r.block.direction for r in recs]}
    for f in ("fx", "fy"):
        ratio = np.array([r.phasors[ch[f"{f}_strain"]] / r.phasors[ch[f"{f}_piezo"]] for r in recs])
        out[f"{f}_amp_ratio"] = np.abs(ratio).round(6).tolist()
        out[f"{f}_phase_diff_deg"] = np.degrees(np.angle(ratio)).round(4).tolist()
    amp = np.abs(np.array(out["fx_amp_ratio"] + out["fy_amp_ratio"]) - 1) * 100
    ph = np.abs(np.array(out["fx_phase_diff_deg"] + out["fy_phase_diff_deg"]))
    out["max_amp_diff_pct"] = round(float(amp.max()), 4) if amp.size else None
    out["max_phase_diff_deg"] = round(float(ph.max()), 4) if ph.size else None
    return out


def _pressure_problems(aux, p: OperatingPoint, v) -> list[str]:
    if aux is None or getattr(aux, "node_lost", False):
        return ["no CAN sensor readings (node lost)"]
    stale = getattr(aux, "stale", None)
    if callable(stale) and (stale("p_recess") or stale("p_supply")):
        return ["CAN pressure readings are stale"]
    problems = []
    pr = float(np.mean(aux.p_recess))
    if abs(pr - p.recess_pressure) > v.recess_pressure_tol_pct / 100 * p.recess_pressure:
        problems.append(f"recess pressure {pr / MPA:.4f} MPa, want {p.recess_pressure / MPA:.4f} MPa "
                        f"+/- {v.recess_pressure_tol_pct:g} %")  # fmt: skip
    beta = float(aux.beta) if getattr(aux, "beta", None) is not None else pr / aux.p_supply
    if abs(beta - p.pressure_ratio) > v.pressure_ratio_tol:
        problems.append(f"pressure ratio {beta:.3f}, want {p.pressure_ratio:g} +/- {v.pressure_ratio_tol:g}")
    return problems


def _geometry_problems(rec: BlockRecord, p: OperatingPoint, rig: RigConfig) -> list[str]:
    ch, v, c = rig.channel_index, rig.verify, rig.bearing.clearance
    ph, dc = rec.phasors, rec.dc
    x = (ph[ch["x_a"]] + ph[ch["x_b"]]) / 2
    y = (ph[ch["y_a"]] + ph[ch["y_b"]]) / 2
    radius = (abs(x) + abs(y)) / 2
    ecc = math.hypot((dc[ch["x_a"]] + dc[ch["x_b"]]) / 2, (dc[ch["y_a"]] + dc[ch["y_b"]]) / 2) / c
    problems = []
    if abs(radius - p.orbit_radius) > v.orbit_radius_tol_pct / 100 * p.orbit_radius:
        problems.append(f"orbit radius {radius * 1e6:.2f} um, want {p.orbit_radius * 1e6:.2f} um "
                        f"+/- {v.orbit_radius_tol_pct:g} %")  # fmt: skip
    if abs(ecc - p.static_eccentricity) > v.static_eccentricity_tol:
        problems.append(f"static eccentricity {ecc:.3f}, want {p.static_eccentricity:g} "
                        f"+/- {v.static_eccentricity_tol:g}")  # fmt: skip
    return problems


def _can_row(t: float, aux) -> tuple:
    pr = list(np.asarray(getattr(aux, "p_recess", [math.nan] * 4), dtype=float).ravel()[:4])
    pr += [math.nan] * (4 - len(pr))
    g = lambda name: float(getattr(aux, name, math.nan) if getattr(aux, name, None) is not None else math.nan)  # noqa: E731
    return (t, g("t_recess"), g("t_groove"), g("t_supply"), g("flow"), g("p_supply"), *pr, g("beta"),
            g("sensor_fault"), g("pump_off"), g("node_lost"))  # fmt: skip


def _drive_row(t: float, st) -> tuple:
    vals = []
    for which in ("spin", "orbit"):
        d = getattr(st, which, None)
        vals.append([float(getattr(d, k, math.nan)) if d is not None else math.nan
                     for k in ("reference", "actual", "status_word", "fault_code", "torque")])  # fmt: skip
    s, o = vals
    return (t, s[0], s[1], o[0], o[1], s[2], o[2], s[3], o[3], s[4], o[4])

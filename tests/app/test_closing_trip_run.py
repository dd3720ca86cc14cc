"""A drive that trips during the run's closing stop fails the run, on the real simulator (its own
process, as `sweep --sim` runs it): the operator stops the run after its first point, the spin
drive trips (overcurrent 2310, the simulator's own fault) while the cleanup ramps both drives to
zero; the run ends failed ("drive tripped during the closing stop (fault 2310, standstill
confirmed)", the service's state faulted, `orbitrig sweep` exits 1), its first point still
stored. The next run on the still tripped drive fails because of that trip, and its own closing
stop does not report the same trip a second time.

The trip is injected through the simulator's control API as soon as the cleanup's stop word has
reached the spin drive: the test waits for it by wrapping RigDrives.stop (the real one runs)."""

from __future__ import annotations

import asyncio
from collections.abc import Callable

import pytest

from drives.rig import RigDrives
from orbitrig import config as cfg
from orbitrig.cli.simulated_rig import simulated_rig
from orbitrig.cli.sweep import EXIT
from orbitrig.run.engine import ProgressEvent, RunEngine
from orbitrig.run.states import ABORTED, FAILED, FAULTED, STOPPING
from orbitrig.store.journal import read_journal
from orbitrig.store.status import RunStatus
from support.sweep_helpers import Recorder, SimulatorView, small_matrix, wait_for

pytestmark = pytest.mark.timeout(120)

CW_RAMP_STOP = 0x047E  # spec control word, written out here on purpose
SPEEDUP = 10.0  # the closing ramp from 2000 rpm takes 0.33 s wall, the coast after the trip about 1.3 s
MATRIX = small_matrix(spin_rpm=[1000.0, 2000.0])


def _trip_in_the_closing_ramp(
    monkeypatch, sim: SimulatorView, engines: list[RunEngine], then: Callable[[], object] = lambda: None
) -> list[float]:
    """The first stop while the run is stopping (the cleanup's) trips the spin drive once its
    stop word is there, and calls `then`; returns the list the spin drive's rpm at the trip is put in."""
    real, at_trip = RigDrives.stop, []

    async def stop(self, *, emergency=False, wait=True, timeout=None):
        if at_trip or engines[-1].state is not STOPPING:
            return await real(self, emergency=emergency, wait=wait, timeout=timeout)
        stopping = asyncio.ensure_future(real(self, emergency=emergency, wait=wait, timeout=timeout))
        while sim.drive(1)["control_word"] != CW_RAMP_STOP and not stopping.done():
            await asyncio.sleep(0.002)
        at_trip.append(sim.drive(1)["rpm"])
        sim.inject("drive_trip", drive=1, code=2310)
        then()
        return await stopping

    monkeypatch.setattr(RigDrives, "stop", stop)
    return at_trip


async def _run(engine: RunEngine, rec: Recorder, stop_at_point_2: bool, runs: list[asyncio.Task] | None = None):
    run = asyncio.create_task(engine.run(MATRIX))
    if runs is not None:
        runs.append(run)
    try:
        if stop_at_point_2:

            def at_point_2() -> bool:
                return any(isinstance(e, ProgressEvent) and e.point >= 2 and e.frequency >= 1 for e in rec.events)

            await wait_for(at_point_2, 90, what="point 2")
            engine.request_stop(by="test")
        return await asyncio.wait_for(asyncio.shield(run), 60)
    finally:
        if not run.done():
            run.cancel()
            await asyncio.gather(run, return_exceptions=True)


async def test_closing_trip_fails_the_run_once_with_its_data_kept(tmp_path, monkeypatch):
    async with simulated_rig(SPEEDUP) as (proc, access):
        sim, engines = SimulatorView(proc), []
        at_trip = _trip_in_the_closing_ramp(monkeypatch, sim, engines)
        rec = Recorder()
        engines.append(RunEngine(cfg.load_rig(), out_dir=tmp_path / "run", access=access, confirm_mode="auto"))
        engines[-1].subscribe(rec)
        outcome = await _run(engines[-1], rec, stop_at_point_2=True)
        assert at_trip and at_trip[0] > 100, at_trip  # tripped with the spindle turning
        assert outcome.status is FAILED and EXIT[outcome.status] == 1, outcome.message
        assert outcome.message.startswith(
            "drive tripped during the closing stop (fault 2310, standstill confirmed): "
            "spin drive (id 1), register FAULT (6), fault 2310 (overcurrent): tripped during the ramp stop (OFF1); "
            "both drives at standstill"
        ), outcome.message
        assert outcome.message.endswith("(the run was ending stopped: stopped by test)"), outcome.message
        assert engines[-1].state is FAULTED and engines[-1].message == outcome.message
        assert outcome.completed_points == [0]  # drives first, storage second: the point is stored
        assert all(abs(s) < 1.0 for s in sim.speeds) and sim.drive(1)["fault"] == 2310
        assert read_journal(tmp_path / "run" / "journal.jsonl").status is RunStatus.FAILED
        assert "drive tripped during the closing stop (fault 2310" in (tmp_path / "run" / "run.log").read_text()

        # the next run: the trip (not reset) fails it, and is not reported again by its closing stop
        engines.append(RunEngine(cfg.load_rig(), out_dir=tmp_path / "next", access=access, confirm_mode="auto"))
        again = await _run(engines[-1], Recorder(), stop_at_point_2=False)
        assert again.status is FAILED and "2310" in again.message, again.message
        assert "closing stop" not in again.message and "not confirmed" not in again.message, again.message
        assert len(at_trip) == 1


async def test_a_trip_and_a_cancellation_in_the_closing_stop_abort_the_run(tmp_path, monkeypatch):
    """The run stopped by the operator is cancelled (the service's wait for it ran out, say) while
    its closing stop ramps the drives down and the spin drive trips in that ramp: the cancellation
    is an abort, so the run ends aborted once both drives are at standstill, the trip in its
    message; it does not keep its status 'stopped' with the trip only noted."""
    async with simulated_rig(SPEEDUP) as (proc, access):
        sim, engines, runs = SimulatorView(proc), [], []
        at_trip = _trip_in_the_closing_ramp(monkeypatch, sim, engines, then=lambda: runs[0].cancel())
        engines.append(RunEngine(cfg.load_rig(), out_dir=tmp_path / "run", access=access, confirm_mode="auto"))
        rec = Recorder()
        engines[-1].subscribe(rec)
        outcome = await _run(engines[-1], rec, stop_at_point_2=True, runs=runs)
        assert at_trip and at_trip[0] > 100, at_trip
        assert outcome.status is ABORTED, outcome.message
        assert outcome.message.startswith(
            "run cancelled while stopping (stopped by test; drive tripped during the closing stop "
            "(fault 2310, standstill confirmed): spin drive (id 1)"
        ), outcome.message
        assert engines[-1].message == f"run {outcome.run_id} aborted: {outcome.message}", engines[-1].message
        assert outcome.completed_points == [0]
        assert all(abs(s) < 1.0 for s in sim.speeds) and sim.drive(1)["fault"] == 2310
        assert read_journal(tmp_path / "run" / "journal.jsonl").status is RunStatus.ABORTED

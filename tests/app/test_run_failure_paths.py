"""Failures the engine must not let pass, on the real simulator: a helper task of the run (the
interlock watcher, the log monitor) that raises ends the run at once as a failure with the
drives stopped, and so does a drive poll that fails on a bug; a stop that is not delivered or
not confirmed at standstill ends the run failed, not stopped; a live-feed hook that raises is
detached and the run goes on.

A bug cannot be produced by the real parts: it is injected (a sensor read that raises, a
monitor that raises, a drive poll that raises, a standstill that is never confirmed, a hook
that raises)."""

import asyncio
import logging
import time

import pytest

from drives.errors import DriveTimeoutError
from drives.poll import DrivePoll
from drives.rig import RigDrives
from orbitrig.run import engine as engine_module
from orbitrig.run.supervision import InterlockSupervisor
from orbitrig.store.journal import read_journal
from orbitrig.config import load_rig
from orbitrig.store.status import RunStatus
from orbitrig import config as cfg
from support.paths import ROOT
from support.sweep_helpers import running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(90)

LONG = small_matrix(revolutions=200, spin_rpm=[1000.0, 1500.0, 2000.0])  # far longer than these tests wait


def _at_rest(sim) -> bool:
    return all(abs(s) < 1.0 for s in sim.speeds)


def _at_speed(sim) -> bool:
    return all(abs(s) > 10.0 for s in sim.speeds)


def _stored_status(tmp_path) -> RunStatus:
    return read_journal(tmp_path / "run" / "journal.jsonl").status


async def test_a_supervisor_that_raises_fails_the_run_at_once_with_the_drives_stopped(tmp_path, monkeypatch, caplog):
    real, calls = InterlockSupervisor.trips, [0]

    def buggy(self):
        calls[0] += 1
        if calls[0] == 30:
            raise AttributeError("'NoneType' object has no attribute 'p_recess'")
        return real(self)

    monkeypatch.setattr(InterlockSupervisor, "trips", buggy)
    async with running(tmp_path, LONG, cfg.load_rig()) as (sim, eng, rec, run):
        outcome = await asyncio.wait_for(asyncio.shield(run), 20)
        assert outcome.status == "failed", outcome.message
        assert "interlock supervision failed (AttributeError" in outcome.message
        assert eng.state == "faulted" and "interlock supervision failed" in eng.message
        assert _at_rest(sim), sim.speeds
    assert any(r.exc_info and "interlock supervision failed" in r.getMessage() for r in caplog.records)
    assert _stored_status(tmp_path) is RunStatus.FAILED


async def test_a_helper_task_that_raises_fails_the_run_at_once(tmp_path, monkeypatch, caplog):
    async def broken_monitor(store, io, t0):
        await asyncio.sleep(0.5)
        raise RuntimeError("monitor bug")

    monkeypatch.setattr(engine_module, "monitor", broken_monitor)
    caplog.set_level(logging.ERROR)
    async with running(tmp_path, LONG, cfg.load_rig()) as (sim, eng, rec, run):
        outcome = await asyncio.wait_for(asyncio.shield(run), 20)
        assert outcome.status == "failed", outcome.message
        assert "the run-monitor task failed (RuntimeError: monitor bug)" in outcome.message
        assert _at_rest(sim), sim.speeds
    assert any(r.exc_info and "run-monitor" in r.getMessage() for r in caplog.records)


async def test_a_stop_that_is_not_delivered_fails_the_run(tmp_path):
    # the shipped drive link (0.15 s a request, lost after 3 polls): the drives that stop answering
    # are this test's subject; the test lab's patient link (1 s a request, lost after 5) only made
    # it wait out each unanswered request of the stop and of the link's closing, about 25 s
    shipped = load_rig(ROOT / "config" / "rig.toml")
    async with running(tmp_path, small_matrix(spin_rpm=[1000.0, 2000.0]), shipped) as (sim, eng, rec, run):
        await wait_for(lambda: rec.blocks_done() >= 2, what="blocks")
        sim.inject("modbus_timeout", on=True)  # the drives no longer answer
        eng.request_stop_now("SIGTERM", by="test")
        outcome = await asyncio.wait_for(asyncio.shield(run), 80)
        assert outcome.status == "failed", outcome.message
        assert outcome.message.startswith("drives not confirmed stopped: DriveTimeoutError")
        assert eng.state == "faulted" and eng.message.startswith("drives not confirmed stopped")
    assert _stored_status(tmp_path) is RunStatus.FAILED
    assert "drives not confirmed stopped" in (tmp_path / "run" / "run.log").read_text()


@pytest.mark.parametrize("when", ["cleanup", "always"])
async def test_drives_not_confirmed_at_standstill_fail_a_completed_run(tmp_path, monkeypatch, when):
    """Never at standstill in time: in the cleanup only (the plan's own stop confirmed), or at
    every stop (the plan's last step fails first: a drive's timeout, not a storage failure)."""
    real, engines = RigDrives.stop, []

    async def never_confirmed(self, *, emergency=False, wait=True, timeout=None):
        if when == "cleanup" and engines[0].state != "stopping":
            return await real(self, emergency=emergency, wait=wait, timeout=timeout)
        await real(self, emergency=emergency, wait=False, timeout=timeout)  # the stop goes out
        raise DriveTimeoutError(f"drives not at zero speed within {timeout or 0:g} s: spin ACT 950 rpm")

    monkeypatch.setattr(RigDrives, "stop", never_confirmed)
    async with running(tmp_path, small_matrix(spin_rpm=[1000.0]), cfg.load_rig()) as (sim, eng, rec, run):
        engines.append(eng)
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
        assert outcome.status == "failed", outcome.message
        assert outcome.message.startswith("drives not confirmed stopped: DriveTimeoutError: drives not at zero")
        assert "storage failed" not in outcome.message
        assert eng.state == "faulted" and outcome.completed_points == [0]
    assert _stored_status(tmp_path) is RunStatus.FAILED


async def test_a_live_feed_hook_that_raises_is_detached_and_the_run_goes_on(tmp_path, caplog):
    calls = []

    def broken_tap(rev):
        calls.append(rev)
        raise ValueError("live feed bug")

    async with running(tmp_path, small_matrix(spin_rpm=[1000.0]), cfg.load_rig()) as (sim, eng, rec, run):
        eng.revolution_taps.append(broken_tap)
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
        assert outcome.status == "completed", outcome.message
        assert len(calls) == 1 and broken_tap not in eng.revolution_taps
    assert "live feed detached" in (tmp_path / "run" / "run.log").read_text()
    assert any(r.exc_info and "detached" in r.getMessage() for r in caplog.records)


async def test_a_drive_poll_that_fails_on_a_bug_fails_the_run_at_once(tmp_path, monkeypatch):
    """The drive poll fails on a bug during an acquisition (which waits on the A/D board, not on
    the drives): the poll ramps both drives to zero, and the run's interlock supervisor fails the
    run at once naming it, not only the next wait for the drives after the acquisition gave up.
    In the poll's words: the supervisor did not fail (it is no "interlock supervision failed")."""
    real, broken = DrivePoll.publish, [False]

    def publish(self, statuses, *, link_ok, link_error=None):
        if broken[0]:
            raise ValueError("status word decoding bug")
        return real(self, statuses, link_ok=link_ok, link_error=link_error)

    monkeypatch.setattr(DrivePoll, "publish", publish)
    async with running(tmp_path, small_matrix(revolutions=3000, spin_rpm=[1000.0]), cfg.load_rig()) as (
        sim,
        eng,
        rec,
        run,
    ):
        await wait_for(lambda: rec.blocks_done() >= 1, 60, what="a block")  # each block: several seconds
        await wait_for(lambda: _at_speed(sim), what="the next block's speeds")
        broken[0] = True
        t0 = time.monotonic()
        await wait_for(lambda: eng.state != "running", 30, what="the run ending")
        ended = time.monotonic() - t0
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
        assert outcome.status == "failed", outcome.message
        assert "poll failed: ValueError('status word decoding bug')" in outcome.message, outcome.message
        assert "supervision failed" not in outcome.message, outcome.message  # the supervisor works on
        assert ended < 3.0, ended  # supervisor samples every 50 ms: not the acquisition's timeout
        assert _at_rest(sim), sim.speeds


async def test_an_os_error_of_a_device_is_no_storage_failure(tmp_path, monkeypatch):
    """An OSError from the A/D board's link (not a storage write) fails the run with its own words
    and errno, the drives stopped; it was called "storage failed". Injected: the real link gives
    its own DaqError."""
    from orbitrig.run.rig_io import RigIO

    async def broken(self, rule, *, timeout, silence=None):
        raise OSError(5, "Input/output error", "/dev/ttyUSB0")

    monkeypatch.setattr(RigIO, "acquire", broken)
    async with running(tmp_path, small_matrix(spin_rpm=[1000.0]), cfg.load_rig()) as (sim, eng, rec, run):
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
        assert outcome.status == "failed", outcome.message
        assert "storage failed" not in outcome.message, outcome.message
        assert outcome.message.startswith("OSError: [Errno 5] Input/output error: '/dev/ttyUSB0'"), outcome.message
        await wait_for(lambda: _at_rest(sim), 30)


async def test_a_bug_in_one_points_identification_names_the_point(tmp_path, monkeypatch, caplog):
    """The identification of point 0000 raises on a bug (not a ReductionError, which refuses one
    model): the run fails at once naming the point, with the traceback logged, the drives stopped
    and every block of the point kept on disk. It said only "identification failed: ..."."""
    from orbitrig.run import point_record

    real = point_record.identify_operating_point

    def buggy(spin, *args):
        if spin < 150.0:  # rad/s: point 0000's 1000 rpm, not point 0001's 2000
            raise ZeroDivisionError("float division by zero")
        return real(spin, *args)

    monkeypatch.setattr(point_record, "identify_operating_point", buggy)
    async with running(tmp_path, small_matrix(spin_rpm=[1000.0, 2000.0]), cfg.load_rig()) as (sim, eng, rec, run):
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
        assert outcome.status == "failed", outcome.message
        assert outcome.message == "identify point 0000 failed: ZeroDivisionError: float division by zero"
        await wait_for(lambda: _at_rest(sim), 30, what="both drives at rest")
    blocks = sorted(p.name for p in (tmp_path / "run" / "points" / "0000").glob("*_*.h5"))
    assert len(blocks) == 10, blocks  # 5 ratios x 2 directions, measured before the failure
    assert _stored_status(tmp_path) is RunStatus.FAILED
    assert any(r.exc_info and "identify point 0000" in r.getMessage() for r in caplog.records)


async def test_a_drive_link_lost_for_a_moment_fails_the_run_naming_the_request(tmp_path):
    """The drives do not answer for 1 s (three polls of the shipped link: lost), then answer again
    in time for the run's stop: the run fails on the lost link, and its message says which drive
    and request went unanswered, as the stop's own failures do. It said only "interlock: Modbus
    link to the drives lost"."""
    shipped = load_rig(ROOT / "config" / "rig.toml")
    async with running(tmp_path, small_matrix(revolutions=3000, spin_rpm=[1000.0]), shipped) as (sim, eng, rec, run):
        await wait_for(lambda: rec.blocks_done() >= 1, 60, what="a block")  # each block: several seconds
        sim.inject("modbus_timeout", on=True)
        await wait_for(lambda: eng.state != "running", 10, what="the run ending")
        sim.inject("modbus_timeout", on=False)
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
        assert outcome.status == "failed", outcome.message
        lost = "interlock: Modbus link to the drives lost (spin drive (id 1), registers 0..6 (CW .. FAULT): "
        assert lost in outcome.message, outcome.message  # (after "drives not confirmed stopped: ..." if so)
        await wait_for(lambda: _at_rest(sim), 30, what="both drives at rest")

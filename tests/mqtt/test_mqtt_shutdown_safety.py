"""Shutting the service down never leaves the drives turning: a start (or anything
that moves the drives) during shutdown is refused or not read, a run the service
has to cut short says how its drives' closing stop ended (not confirmed, unless it was), and a start whose live
feed cannot be attached starts nothing. In process: the service the CLI builds,
on the simulator, with a real mosquitto."""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
from pathlib import Path

import pytest

from support.mqtt_helpers import Broker, RigClient, retained, run_dirs, service_in_process, wait
from support.polling import until
from orbitrig.cli.serve import build_service
from orbitrig.config import load_rig
from orbitrig.service import rig_service, run_handling
from orbitrig.service.rig_service import BrokerSettings, ServiceSettings
from orbitrig.service.settings import RECORD_END_S, STOP_MARGIN_S

RIG = "down"
DECEL_TIME = 103  # the drives' register: 0.1 s for SPEED_SCALE (3000) rpm along the ramp stop


class SlowDrained(asyncio.Event):
    """The broker's acknowledgements of the service's last messages take 3 s (a loaded
    broker): the only injected part, it holds the service in its wait for them."""

    async def wait(self):
        await asyncio.sleep(3.0)
        return await super().wait()


def standstill(sim_rig) -> bool:
    return all(abs(w) < 1e-3 for w in sim_rig.speeds)


@contextlib.asynccontextmanager
async def serving(tmp_path: Path, *, decel_counts: int | None = None, speedup: float = 20, **settings_kw):
    """(service, sim_rig, client, shutdown event, serve task) on a fresh broker and simulator;
    ``decel_counts``: both drives' DECEL_TIME (a slow ramp stop)."""
    from sim.rig import SimRig

    with Broker(tmp_path / "broker") as b:
        async with SimRig(speedup=speedup, adc_pty=False) as sim_rig:
            if decel_counts is not None:
                for drive in sim_rig.drives.values():
                    drive.write(DECEL_TIME, [decel_counts])
            svc = service_in_process(b.url, tmp_path, RIG, sim_rig=sim_rig, abort=False, **settings_kw)
            shutdown = asyncio.Event()
            task = asyncio.create_task(svc.serve(shutdown))
            rc = RigClient(b, RIG)
            try:
                await wait(rc.status, "idle")
                yield svc, sim_rig, rc, shutdown, task
            finally:
                rc.close()
                shutdown.set()
                svc.abort_run("test over")  # whatever went wrong, the drives stop before the simulator closes
                await asyncio.wait_for(asyncio.gather(task, return_exceptions=True), 120)


async def test_a_start_after_offline_is_not_carried_out_and_serve_returns(tmp_path):
    async with serving(tmp_path, speedup=4) as (svc, sim_rig, rc, shutdown, task):
        svc.link.drained = SlowDrained()
        mark = rc.watch.mark()
        shutdown.set()  # SIGTERM, the service idle
        await wait(rc.status, "offline", 10, mark)
        cid = await wait(rc.send, {"cmd": "start", "matrix": "long"})  # e.g. a dashboard's start
        await asyncio.wait_for(asyncio.shield(task), 15)  # serve returns
        replies = [m.json() for m in rc.watch.on("reply", mark) if m.json()["id"] == cid]
        assert all(r["ok"] is False for r in replies), replies  # not read, or refused: never started
        assert not svc.run_active
        for _ in range(10):  # the drives stay at standstill
            assert standstill(sim_rig), sim_rig.speeds
            await asyncio.sleep(0.1)
        assert (await wait(retained, rc.broker, f"orbitrig/{RIG}/status")).json()["state"] == "offline"


async def test_start_resume_and_confirm_are_refused_while_shutting_down(tmp_path):
    # a ramp stop of some 60 s simulated (3 s here): the shutdown waits for it
    async with serving(tmp_path, decel_counts=1800) as (svc, sim_rig, rc, shutdown, task):
        assert (await wait(rc.command, {"cmd": "start", "matrix": "long"}))["ok"] is True
        await wait(rc.status, "running")
        await asyncio.sleep(0.5)
        mark = rc.watch.mark()
        shutdown.set()
        await wait(rc.status, "stopping", 10, mark)
        for cmd in ({"cmd": "start", "matrix": "quick"}, {"cmd": "resume"}, {"cmd": "confirm", "step": "manual:0000"}):
            reply = await wait(rc.command, cmd)
            assert reply["ok"] is False and "the service is shutting down" in reply["error"], (cmd, reply)
        await asyncio.wait_for(asyncio.shield(task), 60)
        assert standstill(sim_rig), sim_rig.speeds
        await wait(rc.status, "offline", 10, mark)  # acknowledged by the broker; the watcher may see it later
        states = [m.json()["state"] for m in rc.watch.on("status", mark)]
        assert states[-1] == "offline" and "running" not in states, states


async def test_a_run_cancelled_with_the_service_says_how_its_closing_stop_ended(tmp_path):
    """The run's closing stop goes on through the cancellation (the emergency stop, waited for
    at standstill): its last status says the standstill confirmed, and so it is."""
    async with serving(tmp_path) as (svc, sim_rig, rc, shutdown, task):
        assert (await wait(rc.command, {"cmd": "start", "matrix": "long"}))["ok"] is True
        await wait(rc.status, "running")
        await asyncio.sleep(0.5)
        task.cancel()  # a fault of the service's own: its TaskGroup cancels the run
        await asyncio.gather(task, return_exceptions=True)
        message = json.loads(svc._status)["message"]
        assert message == "run of 'long' cancelled; its drives' closing stop: standstill confirmed (see run.log)"
        assert standstill(sim_rig), sim_rig.speeds  # as said: the engine's cleanup waited for it
        (log,) = (tmp_path / "runs").glob("*/run.log")
        assert "drives: emergency stop (OFF3); standstill after " in log.read_text()


def test_the_shutdown_waits_for_the_drives_stop_timeout_and_the_run_end(tmp_path):
    rig = load_rig()
    rig = rig.model_copy(update={"drives": rig.drives.model_copy(update={"stop_timeout_s": 1200.0})})
    svc = build_service(
        rig,
        ServiceSettings(rig_id=RIG, matrices_dir=tmp_path),
        BrokerSettings("127.0.0.1"),
        out=tmp_path / "runs",
    )
    svc._engine = svc._engine_factory("m", None)  # the run's engine: the real rig, time scale 1
    assert math.isclose(svc._run_end_timeout(), 1200.0 + STOP_MARGIN_S + RECORD_END_S)


def test_two_starts_in_one_millisecond_get_two_run_folders(tmp_path, monkeypatch):
    """Two services on one runs folder (threads here, racing) starting the same matrix at the same
    instant: each run's folder is made new by the one that names it (OUT/STAMP-m, OUT/STAMP-m-2),
    never one folder for both (before: each saw the name free and both took it)."""
    import threading

    import rigunits

    monkeypatch.setattr(rigunits, "utc_stamp", lambda *a: "20261207T033005.123Z")  # one instant
    services = [
        build_service(
            load_rig(),
            ServiceSettings(rig_id=RIG, matrices_dir=tmp_path),
            BrokerSettings("127.0.0.1"),
            out=tmp_path / "runs",
        )
        for _ in range(2)
    ]
    together, folders = threading.Barrier(2), []

    def start(svc) -> None:
        together.wait()
        folders.append(svc._engine_factory("m", None).out_dir)

    threads = [threading.Thread(target=start, args=(svc,)) for svc in services]
    for t in threads:
        t.start()
    for t in threads:
        t.join(10)
    assert sorted(f.name for f in folders) == ["20261207T033005.123Z-m", "20261207T033005.123Z-m-2"]
    assert all(f.is_dir() for f in folders)


async def test_a_live_feed_that_cannot_be_attached_starts_nothing(tmp_path, monkeypatch):
    def broken(*args, **kw):
        raise RuntimeError("no live feed")

    monkeypatch.setattr(run_handling.live_feed, "attach", broken)  # a fault the real parts do not produce
    async with serving(tmp_path) as (svc, sim_rig, rc, shutdown, task):
        reply = await wait(rc.command, {"cmd": "start", "matrix": "quick"})
        assert reply["ok"] is False and "no live feed" in reply["error"], reply
        await asyncio.sleep(1.0)
        assert not svc.run_active and svc.state == "idle"
        assert standstill(sim_rig), sim_rig.speeds
        runs = tmp_path / "runs"
        assert not runs.exists() or list(runs.iterdir()) == []  # the folder claimed for the run: removed


async def test_a_run_cancelled_before_it_began_leaves_no_folder(tmp_path):
    """A start and, read with it (one burst of the connection), an abort: the run's task is
    cancelled before its first step (as at a shutdown at that instant), and the folder claimed
    for it, still empty, goes. (The start's rig check left out: with it the abort comes during the
    check, the next test.)"""
    async with serving(tmp_path) as (svc, sim_rig, rc, shutdown, task):
        svc._rig_check = None  # the start claims its folder at once, as it did before the check
        runs = tmp_path / "runs"
        svc.handle_command(json.dumps({"cmd": "start", "id": "s1", "matrix": "quick"}).encode())
        claimed = run_dirs(runs)
        assert len(claimed) == 1 and list(claimed[0].iterdir()) == [] and svc.run_active, claimed
        svc.handle_command(json.dumps({"cmd": "abort", "id": "a1"}).encode())  # before the run task ran
        await asyncio.sleep(0.2)
        assert not svc.run_active and svc.state == "idle"
        assert run_dirs(runs) == [], run_dirs(runs)  # the folder claimed for the run: removed
        await until(lambda: standstill(sim_rig), 10, "standstill")


async def test_an_abort_while_a_start_asks_the_rig_withdraws_it(tmp_path):
    """A start and, read with it, an abort: the abort comes while the start asks the rig's
    transports; the start is withdrawn (ok: false), no folder is claimed, the abort is carried out
    as with no run (its emergency stop sent) and the service serves on."""
    async with serving(tmp_path) as (svc, sim_rig, rc, shutdown, task):
        mark = rc.watch.mark()
        svc.handle_command(json.dumps({"cmd": "start", "id": "s1", "matrix": "quick"}).encode())
        svc.handle_command(json.dumps({"cmd": "abort", "id": "a1"}).encode())  # during the check
        start = await wait(rc.reply, "s1", 30, mark)
        abort = await wait(rc.reply, "a1", 30, mark)
        assert start["ok"] is False and "withdrawn: abort came while the rig was asked" in start["error"], start
        assert abort["ok"] is True and "emergency stop (OFF3) sent to both drives" in abort["detail"], abort
        assert not (tmp_path / "runs").exists() or run_dirs(tmp_path / "runs") == []
        assert not svc.run_active and svc.state == "idle"
        assert (await wait(rc.command, {"cmd": "start", "matrix": "quick"}, 30))["ok"] is True  # ready for the next


async def test_a_run_whose_store_cannot_open_leaves_no_folder(tmp_path):
    """The runs folder's run-id register cannot be made (a file stands where its folder goes): the
    run fails before its store opens, the service says so and serves on, and the folder claimed
    for the run, empty, goes."""
    runs = tmp_path / "runs"
    runs.mkdir()
    (runs / ".run-ids").write_text("not a folder")
    async with serving(tmp_path) as (svc, sim_rig, rc, shutdown, task):
        mark = rc.watch.mark()
        await wait(rc.send, {"cmd": "start", "matrix": "quick"})
        await wait(rc.status, "faulted", 30, mark)
        await until(lambda: not svc.run_active, 10, "the run's task ended")
        assert run_dirs(runs) == [], [list(d.iterdir()) for d in run_dirs(runs)]  # the folder claimed: removed
        assert standstill(sim_rig)


async def test_a_failing_closing_summary_leaves_the_service_serving(tmp_path, monkeypatch):
    def broken(out_dir):
        raise RuntimeError("summary unreadable")

    monkeypatch.setattr(run_handling, "closing_warnings", broken)  # a fault the real parts do not produce
    async with serving(tmp_path) as (svc, sim_rig, rc, shutdown, task):
        assert (await wait(rc.command, {"cmd": "start", "matrix": "quick"}))["ok"] is True
        idle = await wait(rc.status, lambda s: s["state"] == "idle" and s["run_id"] is not None, 90)
        assert "closing summary failed: summary unreadable" in idle["message"], idle
        assert not task.done()
        assert (await wait(rc.command, {"cmd": "status"}))["ok"] is True


@pytest.mark.parametrize("value", [0.0, -1.0, math.inf, math.nan])
def test_a_shutdown_timeout_must_be_finite_and_positive(tmp_path, value):
    with pytest.raises(rig_service.ServiceError, match="shutdown timeout"):
        ServiceSettings(rig_id=RIG, matrices_dir=tmp_path, shutdown_timeout=value)

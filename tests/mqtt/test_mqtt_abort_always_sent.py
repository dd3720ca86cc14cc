"""An abort is never dropped and never answered ok with nothing sent:

- the same abort (the same id and bytes) sent again after the service's link to the broker was
  back is carried out and answered, also on the abort topic read by the abort connection and with
  a new run active (the service's memory of QoS 1 redeliveries leaves stop and abort alone);
- an abort that no run carries out, once a run's cleanup could not confirm the drives stopped
  ("drives not confirmed stopped"), sends both drives the emergency stop (OFF3) over a link of
  the service's own and says so in its reply; a stop in the same state, while the run still
  records its end, sends them the ramp stop (OFF1) the same way, or the emergency stop (OFF3) if a
  drive reads turning in its emergency ramp first (another program's emergency stop);
- the service `orbitrig serve` builds knows its rig's drives before any run: an abort to it
  before its first run, with the drives turned from their keypads, stops them the same way;
- a service that knows no drive link (built without one) answers such an
  abort ok: false, "not sent".

Real parts: mosquitto with the shipped ACL and accounts, the service `orbitrig serve --sim`
builds (in process, on the simulator), its broker link cut by a relay, a run's run.log a named
pipe nobody reads (a disk that hangs)."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import threading
import time
from pathlib import Path

import pytest

from drives import registers as R
from orbitrig.config import load_rig
from orbitrig.service import commands
from orbitrig.service.rig_service import BrokerSettings, RigService, ServiceSettings
from support.mqtt_helpers import (
    ACCOUNTS,
    Broker,
    CutProxy,
    RigClient,
    run_dirs,
    service_in_process,
    wait,
    write_matrices,
)
from support.polling import until

DECEL_TIME = 103  # the drives' register: 0.1 s for SPEED_SCALE (3000) rpm along the ramp stop


def standstill(sim_rig) -> bool:
    return all(abs(w) < 1e-3 for w in sim_rig.speeds)


@contextlib.asynccontextmanager
async def serving(
    broker: Broker,
    work: Path,
    rig_id: str,
    *,
    url: str | None = None,
    rig=None,
    speedup=20.0,
    decel=None,
    catalog_url: str | None = None,
):
    """(service, sim_rig, client): the service `orbitrig serve --sim` builds, with its abort
    connection, quick reconnects, on a fresh simulator (``decel``: both drives' DECEL_TIME;
    ``catalog_url``: the catalog it adds completed points to)."""
    from sim.rig import SimRig

    async with SimRig(speedup=speedup, adc_pty=False) as sim_rig:
        if decel is not None:
            for drive in sim_rig.drives.values():
                drive.write(DECEL_TIME, [decel])
        svc = service_in_process(
            url or broker.url,
            work,
            rig_id,
            rig=rig,
            sim_rig=sim_rig,
            reconnect_initial=0.2,
            reconnect_max=1.0,
            catalog_url=catalog_url,
        )
        shutdown = asyncio.Event()
        task = asyncio.create_task(svc.serve(shutdown))
        rc = RigClient(broker, rig_id)
        try:
            await wait(rc.status, "idle")
            await until(lambda: svc.abort_link.up, 30, "the abort connection up")
            yield svc, sim_rig, rc
        finally:
            rc.close()
            shutdown.set()
            svc.abort_run("test over")  # whatever went wrong, the drives stop before the simulator closes
            await asyncio.wait_for(asyncio.gather(task, return_exceptions=True), 120)


@contextlib.asynccontextmanager
async def coasting_run(broker: Broker, work: Path, rig_id: str):
    """(service, sim_rig, client) of :func:`serving` with a `quick` run under way and both drives
    turning; the drives' ramp stop lasts minutes (30 s and more here) while the run's cleanup waits
    2 s for standstill, so it gives up waiting."""
    rig = load_rig()
    rig = rig.model_copy(update={"drives": rig.drives.model_copy(update={"stop_timeout_s": 2.0})})
    async with serving(broker, work, rig_id, rig=rig, decel=18000) as (svc, sim_rig, rc):
        assert (await wait(rc.command, {"cmd": "start", "matrix": "quick"}))["ok"] is True
        await wait(rc.status, "running")
        await until(lambda: min(abs(w) for w in sim_rig.speeds) > 10.0, 60, "both drives turning")
        yield svc, sim_rig, rc


def publish_abort(rc: RigClient, cid: str) -> int:
    """The operator's abort on <prefix>/abort (as the dashboard sends it); the watcher's mark before."""
    mark = rc.watch.mark()
    done = rc.broker.pub(f"{rc.prefix}/abort", json.dumps({"cmd": "abort", "id": cid}))
    assert done.returncode == 0, done.stderr
    return mark


def emergency_stopped(reply: dict, sim_rig, t_abort: float) -> None:
    """The abort's reply says the emergency stop went to both drives, and both got its word
    (OFF3) after `t_abort` (monotonic s)."""
    assert reply["ok"] is True and "emergency stop (OFF3) sent to both drives" in reply["detail"], reply
    for device, drive in sim_rig.drives.items():
        words = [cw for t, cw in drive.control_words if t >= t_abort]
        assert R.CW_EMERGENCY_STOP in words, (device, [hex(w) for w in words])


async def stop_sends_only_the_emergency_stop(rc: RigClient, sim_rig, cid: str) -> dict:
    """A `stop` command's reply, once both drives got the emergency stop word (OFF3) for it and no
    ramp stop word (OFF1) since it was sent."""
    t_stop = time.monotonic()
    reply = await wait(rc.command, {"cmd": "stop", "id": cid})
    for device, drive in sim_rig.drives.items():
        words = [cw for t, cw in drive.control_words if t >= t_stop]
        assert R.CW_EMERGENCY_STOP in words and R.CW_RAMP_STOP not in words, (device, [hex(w) for w in words])
    return reply


async def test_the_same_abort_after_a_reconnection_aborts_the_new_run(broker, tmp_path, monkeypatch, caplog):
    # the redelivery window made wide, so that a slow machine cannot close it before the abort
    monkeypatch.setattr(commands, "REDELIVERY_S", 600.0)
    proxy = CutProxy(broker.port)
    try:
        async with serving(broker, tmp_path, "again-rig", url=proxy.url, speedup=4) as (svc, sim_rig, rc):
            assert (await wait(rc.command, {"cmd": "start", "matrix": "long"}))["ok"] is True
            await wait(rc.status, "running")
            # the run holds the drives (before, its abort is the service's own emergency stop, said in the reply)
            await until(lambda: min(abs(w) for w in sim_rig.speeds) > 1.0, 60, "both drives turning")
            mark = await wait(publish_abort, rc, "a1")  # e.g. mosquitto_pub from the shell's history
            assert await wait(rc.reply, "a1", 10, mark) == {"id": "a1", "ok": True}
            await wait(rc.status, lambda s: s["state"] == "idle" and "aborted" in s["message"], 60, mark)

            mark = rc.watch.mark()
            assert (await wait(rc.command, {"cmd": "start", "matrix": "long"}))["ok"] is True
            running = await wait(rc.status, "running", 30, mark)
            await until(lambda: min(abs(w) for w in sim_rig.speeds) > 1.0, 60, "both drives turning again")
            before = svc.link.connections
            proxy.cut()
            await until(lambda: not svc.link.online.is_set(), 30, "the service sees its link drop")
            proxy.restore()
            await until(lambda: svc.link.connections > before and svc.abort_link.up, 60, "both links back")
            assert svc.run_active and svc.state == "running"

            mark = await wait(publish_abort, rc, "a1")  # the same bytes again: a new abort
            assert await wait(rc.reply, "a1", 10, mark) == {"id": "a1", "ok": True}
            ended = await wait(rc.status, lambda s: s["state"] == "idle" and s["run_id"] == running["run_id"], 60, mark)
            assert "aborted" in ended["message"], ended
            assert "dropped redelivered command abort" not in caplog.text
    finally:
        proxy.close()


async def test_an_abort_after_an_unconfirmed_stop_sends_the_emergency_stop(broker, tmp_path):
    async with coasting_run(broker, tmp_path, "coast-rig") as (svc, sim_rig, rc):
        mark = rc.watch.mark()
        assert (await wait(rc.command, {"cmd": "stop"}))["ok"] is True
        faulted = await wait(rc.status, "faulted", 90, mark)
        assert "drives not confirmed stopped" in faulted["message"], faulted
        await until(lambda: not svc.run_active, 150, "the run's end recorded")
        assert not standstill(sim_rig), sim_rig.speeds  # still coasting: nothing holds them

        t_abort = time.monotonic()
        emergency_stopped(await wait(rc.command, {"cmd": "abort"}), sim_rig, t_abort)


async def test_a_stop_after_an_abort_no_run_carried_out_keeps_the_emergency_stop(broker, tmp_path):
    """A stop that no run carries out, while the emergency stop of an abort before it may still be
    ramping the drives down (within [drives] stop_timeout_s of it), is that emergency stop again:
    its ramp stop (OFF1) would turn the drives' emergency ramp back into their ramp stop, minutes
    long here."""
    async with coasting_run(broker, tmp_path, "abort-then-stop-rig") as (svc, sim_rig, rc):
        mark = rc.watch.mark()
        assert (await wait(rc.command, {"cmd": "stop"}))["ok"] is True
        await wait(rc.status, "faulted", 90, mark)
        await until(lambda: not svc.run_active, 150, "the run's end recorded")
        t_abort = time.monotonic()
        emergency_stopped(await wait(rc.command, {"cmd": "abort"}), sim_rig, t_abort)
        assert not standstill(sim_rig), sim_rig.speeds  # the emergency ramp under way

        reply = await stop_sends_only_the_emergency_stop(rc, sim_rig, "stop-after-abort")
        assert reply["ok"] is True and "emergency stop (OFF3) sent to both drives" in reply["detail"], reply
        await until(lambda: standstill(sim_rig), 30, "both drives at standstill along the emergency ramp")


async def test_a_stop_after_a_runs_own_abort_keeps_its_emergency_stop(broker, tmp_path):
    """A stop that no run carries out within [drives] stop_timeout_s of the emergency stop a run
    sent (its abort; the run gave up waiting for standstill and ended meanwhile) is the emergency
    stop again, as after the service's own abort: the drives are still in their emergency ramp.
    (At 4 x the run gives up 14 / 4 + 5 = 8.5 s wall after its abort, 5.5 s inside the 14 s of
    stop_timeout_s; the emergency ramp from 1000 rpm, DECEL_TIME 1800 s for 3000 rpm, takes 15 s.)"""
    rig = load_rig()
    rig = rig.model_copy(update={"drives": rig.drives.model_copy(update={"stop_timeout_s": 14.0})})
    async with serving(broker, tmp_path, "run-abort-then-stop-rig", rig=rig, speedup=4, decel=18000) as (
        svc,
        sim_rig,
        rc,
    ):
        assert (await wait(rc.command, {"cmd": "start", "matrix": "quick"}))["ok"] is True
        await wait(rc.status, "running")
        await until(lambda: abs(sim_rig.speeds[0]) > 95.0, 90, "the spin drive at its 1000 rpm")
        t_abort = time.monotonic()
        assert await wait(rc.command, {"cmd": "abort", "id": "run-abort"}) == {"id": "run-abort", "ok": True}
        await until(lambda: not svc.run_active, 150, "the run's end recorded")
        for device, drive in sim_rig.drives.items():  # the run sent the emergency stop itself
            assert R.CW_EMERGENCY_STOP in [cw for t, cw in drive.control_words if t >= t_abort], device
        assert not standstill(sim_rig), sim_rig.speeds  # the emergency ramp under way
        assert time.monotonic() - t_abort < 14.0  # within stop_timeout_s of it

        reply = await stop_sends_only_the_emergency_stop(rc, sim_rig, "stop-after-run-abort")
        assert reply["ok"] is True and "emergency stop (OFF3) sent to both drives" in reply["detail"], reply


async def test_a_run_stopped_before_its_first_speed_keeps_an_earlier_emergency_stop(broker, tmp_path):
    """A run started and stopped within [drives] stop_timeout_s of an emergency stop (the service's
    abort of drives turned from their keypads), no speed commanded since: its closing stop is the
    emergency stop again, not a ramp stop into the drives' emergency ramp."""
    rig = load_rig()
    rig = rig.model_copy(update={"drives": rig.drives.model_copy(update={"stop_timeout_s": 60.0})})
    async with serving(broker, tmp_path, "abort-start-stop-rig", rig=rig, speedup=2, decel=18000) as (svc, sim_rig, rc):
        sim_rig.local_control(spin=100.0, orbit=-50.0, hand_back=True)  # someone at the drives, no run
        await until(lambda: min(abs(w) for w in sim_rig.speeds) > 10.0, 30, "both drives turning")
        t_abort = time.monotonic()
        emergency_stopped(await wait(rc.command, {"cmd": "abort", "id": "idle-abort"}), sim_rig, t_abort)
        mark = rc.watch.mark()
        assert (await wait(rc.command, {"cmd": "start", "matrix": "quick"}))["ok"] is True
        assert (await wait(rc.command, {"cmd": "stop", "id": "stop-at-once"}))["ok"] is True
        ended = await wait(rc.status, lambda s: s["state"] in ("idle", "faulted") and s.get("run_id"), 120, mark)
        await until(lambda: not svc.run_active, 150, "the run's end recorded")
        assert time.monotonic() - t_abort < 60.0, ended  # all within stop_timeout_s of the abort
        for device, drive in sim_rig.drives.items():
            words = [cw for t, cw in drive.control_words if t >= t_abort]
            assert R.CW_RAMP_STOP not in words and R.CW_RUN not in words, (device, [hex(w) for w in words])


async def test_a_stop_with_no_run_into_another_clients_emergency_ramp_is_the_emergency_stop(broker, tmp_path):
    """A stop that no run carries out, a drive turning in the emergency ramp of an emergency stop
    the service did not send (another program's, over a Modbus connection of its own): the service
    reads it there first and sends both drives the emergency stop (OFF3), never the ramp stop that
    would turn that ramp into its ten times slower ramp stop; the reply says why. (DECEL_TIME 1800
    s for 3000 rpm at 2 x: the emergency ramp 3.5 rad/s per wall s, the ramp stop 0.35.)"""
    from drives.link import ModbusLink

    async with serving(broker, tmp_path, "other-off3-rig", speedup=2, decel=18000) as (svc, sim_rig, rc):
        for drive in sim_rig.drives.values():
            drive.write(R.COMM_LOSS_TIMEOUT, [0])  # the other program leaves no watchdog behind
        sim_rig.local_control(spin=100.0, orbit=-50.0, hand_back=True)  # someone at the drives, no run
        async with ModbusLink(sim_rig.modbus_url, timeout=0.5) as other:
            await other.write(1, R.CW, [R.CW_EMERGENCY_STOP])  # the other program's emergency stop
        await until(lambda: 10.0 < sim_rig.speeds[0] < 99.0, 30, "the spin drive in its emergency ramp")
        reply = await stop_sends_only_the_emergency_stop(rc, sim_rig, "stop-into-off3")
        before, t_before = sim_rig.speeds, time.monotonic()
        await asyncio.sleep(1.0)
        after, took = sim_rig.speeds, time.monotonic() - t_before
        assert (before[0] - after[0]) / took > 2.0, (before, after)  # the emergency ramp, not 0.35 rad/s per s
        assert (after[1] - before[1]) / took > 2.0, (before, after)
        said = "emergency stop (OFF3, as spin (id 1) read turning in its emergency ramp) sent to both drives"
        assert reply["ok"] is True and said in reply["detail"], reply


async def test_an_abort_before_the_first_run_stops_drives_turned_from_their_keypads(broker, tmp_path):
    async with serving(broker, tmp_path, "keypad-rig") as (svc, sim_rig, rc):
        sim_rig.local_control(spin=50.0, orbit=-30.0, hand_back=True)  # someone at the drives, no run
        await until(lambda: min(abs(w) for w in sim_rig.speeds) > 10.0, 30, "both drives turning")
        t_abort = time.monotonic()
        mark = await wait(publish_abort, rc, "before-any-run")
        emergency_stopped(await wait(rc.reply, "before-any-run", 15, mark), sim_rig, t_abort)
        await until(lambda: standstill(sim_rig), 30, "both drives at standstill")


async def test_a_stop_with_no_run_ramps_the_drives_down(broker, tmp_path):
    """The contract accepts a stop always: with no run holding the drives, turning from their
    keypads, it is not answered ok with nothing sent: both get the ramp stop (OFF1)."""
    async with serving(broker, tmp_path, "idle-stop-rig") as (svc, sim_rig, rc):
        sim_rig.local_control(spin=50.0, orbit=-30.0, hand_back=True)  # someone at the drives, no run
        await until(lambda: min(abs(w) for w in sim_rig.speeds) > 10.0, 30, "both drives turning")
        t_stop = time.monotonic()
        reply = await wait(rc.command, {"cmd": "stop", "id": "s-idle"})
        assert reply["ok"] is True and "ramp stop (OFF1) sent to both drives" in reply["detail"], reply
        for device, drive in sim_rig.drives.items():
            words = [cw for t, cw in drive.control_words if t >= t_stop]
            assert R.CW_RAMP_STOP in words and R.CW_EMERGENCY_STOP not in words, (device, [hex(w) for w in words])
        await until(lambda: standstill(sim_rig), 60, "both drives at standstill")


async def test_an_abort_with_no_drive_link_known_says_it_was_not_sent(broker, tmp_path):
    settings = ServiceSettings(rig_id="unknown-rig", matrices_dir=write_matrices(tmp_path / "matrices"))
    creds = BrokerSettings.from_url(broker.url, username="orbitrig-service", password=ACCOUNTS["orbitrig-service"])
    service = RigService(settings, creds, engine_factory=None, load_matrix=None)  # no drive link given
    stop = asyncio.Event()
    task = asyncio.create_task(service.serve(stop))
    rc = RigClient(broker, "unknown-rig")
    try:
        await wait(rc.status, "idle")
        mark = await wait(publish_abort, rc, "ab-1")
        reply = await wait(rc.reply, "ab-1", 10, mark)
        assert reply["ok"] is False and reply["error"].startswith("not sent: no run holds the drives"), reply
        assert "use the rig's emergency stop" in reply["error"], reply
        halt = await wait(rc.command, {"cmd": "stop"})  # nor is a stop answered ok with nothing sent
        assert halt["ok"] is False and halt["error"].startswith("not sent: no run holds the drives"), halt
    finally:
        rc.close()
        stop.set()
        await asyncio.wait_for(task, 10)


class _StalledRunLog:
    """run.log made a named pipe nobody reads (a disk that hangs): the run's end, which waits for
    every run.log line, is held while the drives are no longer the run's. `back()` reads it
    (kept open until `close`, which gives run.log back as a file first), so the lines go through."""

    def __init__(self, run_dir: Path, spare: Path):
        os.mkfifo(spare)
        os.link(spare, run_dir / "run.log.stalled")  # same file system: the pipe takes run.log's name at once
        os.replace(run_dir / "run.log.stalled", run_dir / "run.log")
        self.run_log, self.spare, self.fd = run_dir / "run.log", spare, None
        self._done = threading.Event()
        self._reader = threading.Thread(target=self._drain, daemon=True)

    def back(self) -> None:
        if self.fd is None:
            self.fd = os.open(self.spare, os.O_RDONLY | os.O_NONBLOCK)
            self._reader.start()

    def _drain(self) -> None:
        while not self._done.is_set():
            with contextlib.suppress(BlockingIOError):
                while os.read(self.fd, 65536):
                    pass
            time.sleep(0.01)

    def close(self) -> None:
        self.back()  # whatever happened, nothing is left waiting for the pipe
        self.run_log.with_name("run.log.back").write_text("")
        os.replace(self.run_log.with_name("run.log.back"), self.run_log)  # later lines: a file again
        time.sleep(0.5)  # a line already opening the pipe is read
        self._done.set()
        self._reader.join(5)
        os.close(self.fd)


@pytest.mark.parametrize("how", ["mqtt stop", "SIGTERM"])
async def test_a_stop_once_the_run_has_let_go_of_the_drives_reaches_them(broker, tmp_path, how):
    """A run whose cleanup could not confirm the drives stopped has closed their link and records
    its end (held here by a stalled run.log): a stop then is no run's to carry out. A `stop` is not
    answered ok with nothing sent: both drives get the ramp stop (OFF1) over the service's own link;
    the first shutdown signal (what `orbitrig serve`'s handler asks of the service) sends them the
    emergency stop (OFF3), as with no run active."""
    async with coasting_run(broker, tmp_path, "let-go-rig") as (svc, sim_rig, rc):
        (run_dir,) = run_dirs(tmp_path / "runs")
        stall = _StalledRunLog(run_dir, tmp_path / "stall")
        try:
            mark = rc.watch.mark()
            assert (await wait(rc.command, {"cmd": "stop"}))["ok"] is True  # the run holds them: its stop
            faulted = await wait(rc.status, "faulted", 90, mark)
            assert "drives not confirmed stopped" in faulted["message"], faulted
            assert svc.run_active  # its end not recorded yet: run.log does not take a line
            assert not standstill(sim_rig), sim_rig.speeds  # still coasting: nothing holds them

            t_stop = time.monotonic()
            if how == "mqtt stop":
                reply = await wait(rc.command, {"cmd": "stop", "id": "s-let-go"})
                assert reply["ok"] is True and "ramp stop (OFF1) sent to both drives" in reply.get("detail", ""), reply
                word = R.CW_RAMP_STOP
            else:
                svc.stop_drives_on_signal("SIGTERM")
                await svc.settle_signal_stop()
                assert svc.signal_stop_failed is None
                word = R.CW_EMERGENCY_STOP
            for device, drive in sim_rig.drives.items():
                words = [cw for t, cw in drive.control_words if t >= t_stop]
                assert word in words, (device, [hex(w) for w in words])
            assert svc.run_active  # the stop went out while the run was still recording its end
            stall.back()
            await until(lambda: not svc.run_active, 60, "the run's end recorded")
        finally:
            stall.close()

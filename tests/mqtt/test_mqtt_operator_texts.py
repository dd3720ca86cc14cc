"""What the operator is told over MQTT is what the run does: a resume during an interlock
suspension is refused (the run resumes by itself) and a pause then holds the run once the
interlock clears, said meanwhile by the suspension's retained status with who asked; a pause of the supervision policy says when the run stops unless resumed, and
that stop says what was true (the broker was back, nobody resumed); the last will says that its
run_id and since are of the connection; a service that has never reached its broker says where
the broker's set-up is told. Real mosquitto, the service on the simulator."""

from __future__ import annotations

import asyncio
import json
import signal
from pathlib import Path

import pytest

from orbitrig.config import load_rig
from orbitrig.store.journal import read_journal
from support.mqtt_helpers import Broker, RigClient, retained, run_dirs, serving_unsupervised, sim_service, wait
from support.polling import until
from support.ports import free_port

pytestmark = pytest.mark.timeout(180)


def rig_with(**interlocks):
    rig = load_rig()
    return rig.model_copy(update={"interlocks": rig.interlocks.model_copy(update=interlocks)})


def run_log(work: Path) -> str:
    return next((work / "runs").glob("*/run.log")).read_text()


async def started_and_suspended(rc: RigClient, sim_rig) -> dict:
    """Bob's run of the long matrix started, measuring, then suspended by the CAN heartbeat's loss:
    the suspension's status."""
    await wait(rc.status, "idle")
    assert (await wait(rc.command, {"cmd": "start", "matrix": "long", "by": "bob"}))["ok"] is True
    await wait(rc.watch.wait_for, lambda m: m.topic.endswith("/progress") and m.json()["frequency"] >= 1, 30)
    sim_rig.inject("can_heartbeat_loss", on=True)
    return await wait(rc.status, lambda s: s["message"].startswith("suspended by interlock: CAN"), 20)


async def test_resume_during_a_suspension_is_refused_and_a_pause_holds_after_it(broker, tmp_path: Path):
    rc = None
    rig = rig_with(can_heartbeat_timeout_s=60.0)  # the suspension lasts as long as the test needs
    async with serving_unsupervised(broker, tmp_path, "susp", "keep", rig=rig) as (service, sim_rig):
        try:
            rc = RigClient(broker, "susp")
            await started_and_suspended(rc, sim_rig)

            refused = await wait(rc.command, {"cmd": "resume", "by": "bob"})
            assert refused["ok"] is False, refused
            assert "suspended by interlock" in refused["error"] and "resumes by itself" in refused["error"], refused
            assert service.state == "paused"
            assert (await wait(rc.command, {"cmd": "pause", "by": "bob"}))["ok"] is True  # stay paused after it

            mark = rc.watch.mark()
            sim_rig.inject("can_heartbeat_loss", on=False)
            await wait(rc.status, lambda s: s["message"].startswith("interlock cleared"), 20, mark)
            held = await wait(rc.status, "paused", 20, mark)
            assert held["message"].startswith("paused at a safe point"), held
            assert "asked by bob" in held["message"], held  # who holds the run
            await asyncio.sleep(1.5)
            assert service.state == "paused"  # held: nothing resumes it but the operator
            assert [s.json()["state"] for s in rc.watch.on("status", mark)][-1] == "paused"

            assert (await wait(rc.command, {"cmd": "resume", "by": "bob"}))["ok"] is True
            await wait(rc.status, "running", 20, mark)
            assert (await wait(rc.command, {"cmd": "abort"}))["ok"] is True
            await wait(rc.status, "idle", 60, mark)
            log = run_log(tmp_path)
            assert log.count("command resume by bob") == 1, log[-3000:]  # the refused one is not recorded
            assert "command pause by bob" in log
        finally:
            if rc is not None:
                rc.close()


async def test_a_pause_asked_during_a_suspension_is_on_the_retained_status_with_who_asked(broker, tmp_path: Path):
    """Another supervisor subscribing later sees the pause pending and who asked it: the suspension's
    status said again, the same `since`, the cause kept; and again without it once a resume withdraws it."""
    rc = None
    rig = rig_with(can_heartbeat_timeout_s=60.0)  # the suspension lasts as long as the test needs
    async with serving_unsupervised(broker, tmp_path, "susp-pause", "keep", rig=rig) as (service, sim_rig):
        try:
            rc = RigClient(broker, "susp-pause")
            suspended = await started_and_suspended(rc, sim_rig)

            mark = rc.watch.mark()
            reply = await wait(rc.command, {"cmd": "pause", "by": "ada"})
            assert reply == {"id": reply["id"], "ok": True, "detail": "the run stays paused once the interlock clears"}
            asked = suspended["message"] + "; pause requested by ada: the run stays paused once the interlock clears"
            said = await wait(rc.status, lambda s: "pause requested" in s["message"], 10, mark)
            assert said["message"] == asked, said
            assert (said["state"], said["since"], said["run_id"]) == ("paused", suspended["since"], suspended["run_id"])
            seen = await asyncio.to_thread(retained, broker, f"{rc.prefix}/status")  # a later subscriber, as viewer
            assert seen is not None and seen.json()["message"] == asked, seen

            mark = rc.watch.mark()
            assert (await wait(rc.command, {"cmd": "resume", "by": "ada"}))["ok"] is True  # withdraws it
            back = await wait(rc.status, lambda s: "pause requested" not in s["message"], 10, mark)
            assert (back["state"], back["since"], back["message"]) == (
                "paused",
                suspended["since"],
                suspended["message"],
            )
            assert service.state == "paused"
            assert (await wait(rc.command, {"cmd": "abort"}))["ok"] is True
            await wait(rc.status, "idle", 60, mark)
        finally:
            if rc is not None:
                rc.close()


async def test_a_supervision_pause_says_its_deadline_and_the_stop_what_was_true(tmp_path: Path):
    b = Broker(tmp_path / "broker")
    b.start()
    rc = None
    try:
        async with serving_unsupervised(b, tmp_path, "sup", "pause", rig=rig_with(unanswered_pause_s=6.0)) as (
            service,
            _,
        ):
            rc = RigClient(b, "sup")
            await wait(rc.status, "idle")
            assert (await wait(rc.command, {"cmd": "start", "matrix": "long"}))["ok"] is True
            run_id = (await wait(rc.status, "running"))["run_id"]
            rc.close()
            rc = None
            b.stop()
            for _ in range(100):  # the policy pauses the run after 1 s without the broker
                await asyncio.sleep(0.1)
                if service.state == "paused":
                    break
            paused = json.loads(service._status)["message"]
            assert service.state == "paused", paused
            assert "the run stops at " in paused and "unless resumed" in paused and "6 s" in paused, paused

            b.start()
            rc = RigClient(b, "sup")
            again = await wait(rc.status, lambda s: s["run_id"] == run_id, 20)  # republished
            assert again["state"] == "paused" and "the run stops at " in again["message"], again
            idle = await wait(rc.status, "idle", 60)  # nobody resumes: the deadline stops the run
            why = idle["message"]
            assert "nobody resumed within 6 s" in why and "MQTT back since " in why, why
            assert "no MQTT" not in why, why
            log = run_log(tmp_path)
            assert "command pause by service (supervision lost: no broker for 1 s, policy pause)" in log
    finally:
        if rc is not None:
            rc.close()
        b.stop()


def test_the_last_will_says_its_run_id_and_since_are_of_the_connection(broker, tmp_path: Path):
    svc = sim_service(broker.url, "will", tmp_path)
    rc = RigClient(broker, "will", svc)
    try:
        rc.ready()
        assert rc.command({"cmd": "start", "matrix": "long"})["ok"] is True
        running = rc.status("running")
        run_id = running["run_id"]
        mark = rc.watch.mark()
        svc.kill(signal.SIGKILL)
        rc.status("offline", start=mark, timeout=15)
        offline = retained(broker, "orbitrig/will/status").json()
        assert offline["state"] == "offline" and offline["run_id"] is None, offline  # as when it connected
        note = offline["last_will"]
        assert offline["since"] in note and "registered when the service connected" in note, offline
        assert offline["since"] < running["since"], (offline, running)  # the connection's time, before the run
        # where the note sends the operator: the statuses before it named the run; stored, it is still running
        assert [s.json()["run_id"] for s in rc.watch.on("status")][-2] == run_id
        (run_dir,) = run_dirs(tmp_path / "runs")
        assert read_journal(run_dir / "journal.jsonl").status == "running"
    finally:
        rc.close()
        svc.kill()


async def test_a_service_that_never_reached_its_broker_says_where_its_set_up_is_told(tmp_path: Path):
    port = free_port()  # no broker listens there
    service = sim_service(f"mqtt://127.0.0.1:{port}", "nobroker", tmp_path)
    try:
        await until(lambda: "cannot connect to" in service.text(), 60, "the service tried its broker")
    finally:
        service.stop()
    line = next(line for line in service.text().splitlines() if "cannot connect to" in line)
    assert f"cannot connect to 127.0.0.1:{port}: " in line and "Connection refused" in line, line
    assert "is a broker running there? start it as config/mosquitto/README.md says; retrying" in line, line

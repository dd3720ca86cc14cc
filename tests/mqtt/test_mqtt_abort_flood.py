"""An abort that gets through while another operator floods the rig service:
a real mosquitto with the shipped client-id binding and flow limits, `orbitrig
serve --sim` running a sweep, a flooding operator client (mqtt_flood.py, 5000
QoS 1 commands at full speed) and an abort from a second operator client on
<prefix>/abort in the middle of the flood. The abort's first act is the drives'
emergency stop (run.log says when it went out), before the run unwinds. Timing
bounds here are generous (the machine may be busy); bench/bench_abort_flood.py
holds the 200 ms target.

The service reads <prefix>/abort on a connection of its own (the account
orbitrig-service-abort of config/mosquitto/) besides its main connection; with
that account refused it takes aborts on the main connection alone. Both ways are
run with a flood; an abort arriving on both connections is carried out and
answered once, whichever copy is read first."""

from __future__ import annotations

import asyncio
import json
import re
import sys
import time
from pathlib import Path

import pytest

from orbitrig.service.rig_service import BrokerSettings, RigService, ServiceSettings
from orbitrig.service.settings import AbortAccount
from support.cli_helpers import reaped, started
from support.rig_configs import patient_rig_config
from support.mqtt_helpers import ACCOUNTS, Broker, RigClient, Service, Watcher, broker_fixture, sim_service_args
from support.polling import until

RIG = "flood-rig"
FLOODER = Path(__file__).with_name("mqtt_flood.py")
ENV = {"ORBITRIG_MQTT_PASSWORD": ACCOUNTS["orbitrig-service"]}


bound = broker_fixture(bind_ids=True)


#: how the service's abort connection fares: its account (the shipped setup), or refused
ABORT_ACCOUNT = {"abort account": {}, "account refused": {"ORBITRIG_MQTT_ABORT_PASSWORD": "not-the-password"}}


@pytest.fixture(params=sorted(ABORT_ACCOUNT))
def running(bound, tmp_path, request):
    svc = Service(
        sim_service_args(
            bound.service_url,
            RIG,
            tmp_path,
            "--confirm",
            "auto",
            "--config",  # the drive polls may wait behind the flood: what is measured is the abort
            str(patient_rig_config(tmp_path / "lab")),
            speedup=5,
        ),
        tmp_path,
        env={**ENV, **ABORT_ACCOUNT[request.param]},
    )
    svc.abort_account = request.param
    # status and progress only: with the flood's commands and replies a viewer's own
    # queue at the broker would overflow too (the broker drops what does not fit)
    rc = RigClient(bound, RIG, svc, watch=("status", "progress"))
    try:
        rc.ready()
        rc.send({"cmd": "start", "matrix": "long"})
        rc._wait(
            lambda m: m.topic.endswith("/progress") and m.json()["revolutions"] >= 10,
            60,
            0,
            "both drives at speed, the orbit being acquired",
        )
        yield svc, rc
    finally:
        rc.close()
        svc.stop()


def test_abort_gets_through_a_flood_of_commands(bound, running, tmp_path):
    svc, rc = running
    if svc.abort_account == "abort account":
        assert "abort connection to 127.0.0.1" in svc.text(), svc.text()[-2000:]
    else:
        assert "refused the abort connection's account 'orbitrig-service-abort'" in svc.text(), svc.text()[-2000:]
        # where to read on, and the usual cause: its password is the service's unless given one
        assert "unless --abort-password-file gives one" in svc.text(), svc.text()[-2000:]
    flood = started(
        [sys.executable, str(FLOODER), "--port", str(bound.port), "--prefix", rc.prefix, "--count", "5000"]
        + ["--qos", "1", "--password", ACCOUNTS["operator"]],
        stderr=None,
        text=False,
    )
    with reaped(flood):
        assert flood.stdout.readline().strip() == b"half"
        mark = rc.watch.mark()
        t_abort = time.monotonic()
        assert bound.pub(f"{rc.prefix}/abort", json.dumps({"cmd": "abort", "id": "operator-abort"})).returncode == 0
        stopping = rc._wait(
            lambda m: m.topic.endswith("/status") and m.json()["state"] == "stopping", 20, mark, "status stopping"
        )
        assert stopping.t - t_abort < 3.0, f"abort took {stopping.t - t_abort:.2f} s to reach the executor"
        ended = rc.status("idle", timeout=60, start=mark)
        assert "aborted" in ended["message"], ended
        summary = json.loads(flood.communicate(timeout=150)[0].decode().strip().splitlines()[-1])
    # the emergency stop went to both drives on the abort itself, before the run unwound
    # and its cleanup stopped them again (run.log, in order)
    run_log = next((tmp_path / "runs").rglob("run.log")).read_text()
    sent = re.search(r"drives: emergency stop \(OFF3\) sent on the abort in (\d+) ms(.*)", run_log)
    assert sent and not sent.group(2), run_log[-2000:]
    assert int(sent.group(1)) < 2000, sent.group(0)
    assert sent.start() < run_log.index("drives: emergency stop (OFF3); standstill after"), run_log[-2000:]
    # every flood command the service took was answered or counted as dropped (the flooder
    # counts replies to ids "flood-...": not the abort's), and
    # it answered its last one soon after the flood was out: no endless backlog
    log = svc.text()
    dropped = sum(int(n) for n in re.findall(r"answered busy, (\d+) dropped unanswered", log))
    answered = summary["ok"] + summary["busy"] + summary["refused"]
    assert answered > 0 and answered + dropped <= 5000, (summary, dropped)
    assert summary["out_s"] is not None and summary["seconds"] - summary["out_s"] < 10, summary
    if summary["busy"] or dropped:
        assert "command flood:" in log
    # the main connection, left unread for a moment after the abort, kept its session
    assert "connection to 127.0.0.1" not in log.split("command abort (id 'operator-abort')")[1], log[-3000:]
    assert "Traceback" not in log, log[-3000:]
    # carried out and answered once: off the main connection when the abort account is
    # refused; with the account, off whichever connection's copy the event loop read first
    # (the broker writes both at once; under load the main one's may come first)
    assert log.count("command abort (id 'operator-abort')") == 1, log[-3000:]
    # the main connection (the flood) was left unread until the stop words were out, also when it
    # is the only one (without that the flood, read meanwhile, held them back: 1.5 s at load 15)
    unread = re.findall(r"abort: the drives' stop words out after (\d+) ms, the main connection left unread", log)
    assert len(unread) == 1, log[-3000:]
    read_off = re.findall(r"abort topic: abort read off the (\w+) connection", log)
    vias = ["abort", "main"] if svc.abort_account == "abort account" else ["main"]
    assert len(read_off) == 1 and read_off[0] in vias, (read_off, log[-3000:])
    replies = RigClient(bound, RIG, svc, watch=("reply",))
    try:
        assert replies.command({"cmd": "status"}, timeout=10)["ok"] is True  # ordinary commands work again
    finally:
        replies.close()


# -- each message on the abort topic carried out and answered once --------------------


def _idle_service(broker: Broker, tmp_path: Path, rig: str, abort_password: str) -> RigService:
    """The service in process, no run (nothing to start), with its abort connection."""
    settings = ServiceSettings(rig_id=rig, matrices_dir=tmp_path)
    account = AbortAccount("orbitrig-service-abort", abort_password)
    creds = BrokerSettings.from_url(
        broker.service_url, username="orbitrig-service", password=ACCOUNTS["orbitrig-service"], abort=account
    )
    return RigService(settings, creds, engine_factory=None, load_matrix=None)


async def _replies_to(service: RigService, broker: Broker, rig: str, messages: list[tuple[str, dict]]) -> list:
    """Publish each (topic, command) as the operator; every reply seen within 2 s after the last."""
    stop = asyncio.Event()
    serving = asyncio.create_task(service.serve(stop))
    watch = Watcher(broker, f"orbitrig/{rig}/reply")
    try:
        await until(
            lambda: service.link.online.is_set() and (service.abort_link.up or service.abort_link.refused),
            60,
            "both connections up (or the abort connection given up)",
        )
        for topic, cmd in messages:
            done = await asyncio.to_thread(broker.pub, f"orbitrig/{rig}/{topic}", json.dumps(cmd))
            assert done.returncode == 0, done.stderr
        await asyncio.sleep(2.0)
        return [m.json() for m in watch.messages]
    finally:
        watch.close()
        stop.set()
        await asyncio.wait_for(serving, 10)


@pytest.mark.parametrize("abort_password", [ACCOUNTS["orbitrig-service-abort"], "not-the-password"])
async def test_an_abort_on_both_connections_is_answered_once(bound, tmp_path, caplog, abort_password):
    service = _idle_service(bound, tmp_path, "twice-rig", abort_password)
    replies = await _replies_to(
        service,
        bound,
        "twice-rig",
        [
            ("abort", {"cmd": "abort", "id": "a1"}),
            ("abort", {"cmd": "abort", "id": "a1"}),  # the same again: a second abort, answered again
            ("abort", {"cmd": "stop", "id": "s1"}),
            ("abort", {"cmd": "status", "id": "q1"}),  # not taken there: refused, once
        ],
    )
    ids = [r["id"] for r in replies]
    assert sorted(ids) == ["a1", "a1", "q1", "s1"], replies
    for reply in (r for r in replies if r["id"] in ("a1", "s1")):  # no run, no drive link known: not sent, said so
        assert reply["ok"] is False and reply["error"].startswith("not sent: no run holds the drives"), reply
    assert "only stop and abort are taken on the abort topic" in next(r for r in replies if r["id"] == "q1")["error"]
    if abort_password == ACCOUNTS["orbitrig-service-abort"]:
        assert service.abort_link.connections == 1 and service.abort_link.refused is None
        assert service.triage.counts["second copy"] == 4  # each message's later copy, dropped
    else:  # the main connection alone takes them; the warning says so
        assert service.abort_link.connections == 0 and "refused" in service.abort_link.refused
        assert service.triage.counts["second copy"] == 0
        assert "still taken on orbitrig/twice-rig/abort through the main connection" in caplog.text

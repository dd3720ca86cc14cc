"""An abort that gets through while another operator floods the rig service:
a real mosquitto with the shipped client-id binding and flow limits, `orbitrig
serve --sim` running a sweep, a flooding operator client (mqtt_flood.py, 5000
QoS 1 commands at full speed) and an abort from a second operator client on
<prefix>/abort in the middle of the flood. The abort's first act is the drives'
emergency stop (run.log says when it went out), before the run unwinds. Timing
bounds here are generous (the machine may be busy); bench/bench_abort_flood.py
holds the 200 ms target."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from support.mqtt_helpers import ACCOUNTS, Broker, RigClient, Service, write_matrices

RIG = "flood-rig"
FLOODER = Path(__file__).with_name("mqtt_flood.py")
ENV = {"ORBITRIG_MQTT_PASSWORD": ACCOUNTS["orbitrig-service"]}


@pytest.fixture(scope="module")
def bound(tmp_path_factory):
    b = Broker(tmp_path_factory.mktemp("flood-broker"), bind_ids=True)
    b.start()
    yield b
    b.stop()


@pytest.fixture
def running(bound, tmp_path):
    svc = Service(
        [
            "--sim",
            "--broker",
            bound.service_url,
            "--rig-id",
            RIG,
            "--username",
            "orbitrig-service",
            "--matrices",
            str(write_matrices(tmp_path / "matrices")),
            "--out",
            str(tmp_path / "runs"),
            "--speedup",
            "5",
            "--confirm",
            "auto",
        ],
        tmp_path,
        env=ENV,
    )
    # status and progress only: with the flood's commands and replies a viewer's own
    # queue at the broker would overflow too (the broker drops what does not fit)
    rc = RigClient(bound, RIG, svc, watch=("status", "progress"))
    try:
        rc.status("idle", timeout=30)
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
    flood = subprocess.Popen(
        [
            sys.executable,
            str(FLOODER),
            "--port",
            str(bound.port),
            "--prefix",
            rc.prefix,
            "--count",
            "5000",
            "--qos",
            "1",
            "--password",
            ACCOUNTS["operator"],
        ],
        stdout=subprocess.PIPE,
    )
    try:
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
    finally:
        if flood.poll() is None:
            flood.kill()
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
    replies = RigClient(bound, RIG, svc, watch=("reply",))
    try:
        assert replies.command({"cmd": "status"}, timeout=10)["ok"] is True  # ordinary commands work again
    finally:
        replies.close()

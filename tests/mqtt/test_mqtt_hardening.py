"""The MQTT link no viewer can disrupt, against a real mosquitto with the
shipped client-id binding (config/mosquitto/mosquitto.conf): nobody can take
the service's client id, QoS 1 commands published while the service reconnects
are executed once, any unreadable payload gets ok:false, and ``offline`` is
retained on every way out."""

from __future__ import annotations

import asyncio
import re
import signal
import subprocess
import threading
import time
from pathlib import Path

import pytest

from support.mqtt_helpers import (
    ACCOUNTS,
    Broker,
    CutProxy,
    RigClient,
    Service,
    broker_fixture,
    engineless_service,
    retained,
    sim_service_args,
    write_matrices,
)
from support.polling import until
from orbitrig.service.rig_service import BrokerSettings, RigService, ServiceSettings, default_client_id

RIG = "hard-rig"
ENV = {"ORBITRIG_MQTT_PASSWORD": ACCOUNTS["orbitrig-service"]}


bound = broker_fixture(bind_ids=True)


def serve(url: str, work: Path, rig: str = RIG) -> Service:
    args = sim_service_args(url, rig, work, "--confirm", "auto")
    return Service(args, work, env=ENV)


@pytest.fixture
def started(bound, tmp_path):
    svc = serve(bound.service_url, tmp_path)
    rc = RigClient(bound, RIG, svc)
    try:
        rc.ready()
        yield svc, rc
    finally:
        rc.close()
        svc.stop()


def _connect_as(broker: Broker, port: int, client_id: str) -> subprocess.CompletedProcess:
    """A viewer connects with ``client_id`` for about 2 s (mosquitto_sub)."""
    return subprocess.run(
        ["mosquitto_sub", *broker.client_args("viewer", port), "-i", client_id, "-t", "orbitrig/none", "-W", "2"],
        capture_output=True,
        timeout=15,
    )


def test_a_viewer_cannot_take_the_service_client_id(bound, started):
    svc, rc = started
    asked = default_client_id(RIG)
    assert asked.startswith("mosq-")
    attempts = [
        (bound.port, asked),  # the id the service asks for: another session, no takeover
        (bound.port, "orbitrig-service"),  # the id the broker gave the service: refused
        (bound.service_port, asked),  # the service listener: the viewer's id becomes "viewer"
        (bound.service_port, "orbitrig-service"),
    ]
    for port, cid in attempts:
        _connect_as(bound, port, cid)
        assert rc.command({"cmd": "status"})["ok"] is True, (port, cid)
    text = svc.text()
    assert text.count("connected to 127.0.0.1") == 1 and " lost" not in text, text[-2000:]
    broker_log = bound.log.read_text()
    assert "closing old connection" not in broker_log and "taken over" not in broker_log
    assert "not authorised" in broker_log  # the attempt with the service's name was refused


def test_the_log_names_each_connection_as_the_broker_logs_it(bound, started):
    """The service's log gives the address each of its connections comes from and the name the
    broker knows it by (its account, on the binding listener), as the broker's log line has them."""
    svc, rc = started
    for said, account in (("connected to", "orbitrig-service"), ("abort connection to", "orbitrig-service-abort")):
        deadline = time.monotonic() + 30  # the abort connection may come up after the status
        while not (lines := [ln for ln in svc.text().splitlines() if f" {said} 127.0.0.1" in ln]):
            assert time.monotonic() < deadline, svc.text()[-2000:]
            time.sleep(0.05)
        line = lines[0]
        broker_log = bound.log.read_text()
        m = re.search(rf"from (127\.0\.0\.1:\d+) as '{account}' ", line)
        assert m, line
        assert f"New client connected from {m.group(1)} as {account} (" in broker_log, (line, broker_log[-2000:])


def test_without_the_binding_a_viewer_kicks_the_service(broker, tmp_path):
    """The control: on a broker without the binding the same attempt succeeds."""
    svc = serve(broker.url, tmp_path, rig="unbound-rig")
    rc = RigClient(broker, "unbound-rig", svc)
    try:
        rc.ready()
        _connect_as(broker, broker.port, default_client_id("unbound-rig"))
        assert " lost" in svc.text()
    finally:
        rc.close()
        svc.stop()


def test_deep_json_gets_ok_false_and_serve_keeps_running(started):
    svc, rc = started
    mark = rc.watch.mark()
    deep = b"[" * 1500 + b"]" * 1500
    nested = b'{"cmd":"status","id":"deep","x":' + b"[" * 1400 + b"]" * 1400 + b"}"  # (an abort is read whole)
    for payload in (deep, nested):
        rc.send(payload)
    deadline = time.monotonic() + 10
    while len(rc.watch.on("reply", mark)) < 2 and time.monotonic() < deadline:
        time.sleep(0.05)
    replies = [m.json() for m in rc.watch.on("reply", mark)]
    assert [r["ok"] for r in replies] == [False, False], replies
    assert all("nested too deeply" in r["error"] for r in replies), replies
    assert rc.command({"cmd": "status"})["ok"] is True
    assert svc.proc.poll() is None and "Traceback" not in svc.text()


def test_a_command_sent_while_the_service_reconnects_runs_once(bound, tmp_path):
    proxy = CutProxy(bound.service_port)
    svc = serve(proxy.url, tmp_path)
    rc = RigClient(bound, RIG, svc)
    try:
        rc.ready()
        mark = rc.watch.mark()
        proxy.cut()
        rc.status("offline", start=mark, timeout=15)  # the broker saw the link drop: the last will
        cid = rc.send({"cmd": "start", "matrix": "quick"})
        time.sleep(1.5)
        assert rc.watch.on("reply", mark) == [], "answered while cut off?"
        proxy.restore()
        assert rc.reply(cid, timeout=30, start=mark)["ok"] is True
        rc.status("running", start=mark, timeout=30)
        assert rc.command({"cmd": "abort"})["ok"] is True
        rc.status("idle", start=mark, timeout=60)
        replies = [m.json()["id"] for m in rc.watch.on("reply", mark)]
        assert replies.count(cid) == 1, replies
        assert svc.text().count("run of matrix 'quick' starting") == 1
    finally:
        rc.close()
        svc.stop()
        proxy.close()


@pytest.mark.parametrize("how", ["SIGINT", "SIGKILL"])
def test_offline_is_retained_after_any_exit(bound, tmp_path, how):
    svc = serve(bound.service_url, tmp_path)
    rc = RigClient(bound, RIG, svc)
    try:
        rc.ready()
        svc.kill(getattr(signal, how))
        if how == "SIGINT":
            assert svc.proc.returncode == 0, svc.text()[-2000:]
        msg = retained(bound, f"orbitrig/{RIG}/status")
        assert msg is not None and msg.retain and msg.json()["state"] == "offline", msg
        want = "service stopped" if how == "SIGINT" else "connection to the rig service lost"
        assert msg.json()["message"] == want
    finally:
        rc.close()
        svc.stop()


async def test_a_cancelled_service_says_offline(bound, tmp_path):
    """A way out that is neither a shutdown request nor a lost link."""
    service = engineless_service(bound.service_url, tmp_path, "cancelled")
    task = asyncio.create_task(service.serve(asyncio.Event()))
    await until(lambda: service.connections > 0, 60, "the service connected")
    await asyncio.sleep(0.3)
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task
    msg = await asyncio.to_thread(retained, bound, "orbitrig/cancelled/status")
    assert msg is not None and msg.json()["state"] == "offline" and msg.json()["message"] == "rig service stopped"


class HeldProxy(CutProxy):
    """Relays the service's first connection to the broker, but of what the broker sends it only
    the first `passed` reads (1: its CONNACK), dropping the rest (its SUBACK, ...) until `release`;
    `held` is set once the service's CONNECT went on and those were passed. Later connections
    (the session's discard) pass."""

    def __init__(self, target_port: int, passed: int):
        self.passed, self.held, self.released = passed, threading.Event(), threading.Event()
        super().__init__(target_port)

    def release(self) -> None:
        """Pass on what the broker sends from now on (what was held is dropped)."""
        self.released.set()

    def _relay(self, client, broker) -> None:
        if self.accepted > 1:
            super()._relay(client, broker)
            return
        threading.Thread(target=self._held_first, args=(client, broker), daemon=True).start()

    def _held_first(self, client, broker) -> None:
        try:
            broker.sendall(client.recv(65536))  # its CONNECT
            threading.Thread(target=self._pump, args=(client, broker), daemon=True).start()
            for _ in range(self.passed):
                client.sendall(broker.recv(65536))
            self.held.set()
            while data := broker.recv(65536):
                if self.released.is_set():
                    client.sendall(data)
        except OSError:
            pass


@pytest.mark.parametrize("passed", [0, 1], ids=["before-connack", "while-subscribing"])
async def test_a_shutdown_right_after_connecting_says_offline(bound, tmp_path, passed):
    """The shutdown (SIGTERM, SIGINT: `orbitrig serve` sets the service's shutdown) comes as the first
    connection waits for its CONNACK (the broker holds the will: the service leaving unconnected
    leaves it to the broker) or its SUBACK (its status not published yet). The service's status
    retained after it is its own ``offline`` ('rig service stopped'), not the last will, nor none."""
    rig = f"early{passed}"
    proxy = HeldProxy(bound.service_port, passed)
    service = engineless_service(proxy.url, tmp_path, rig)
    stop = asyncio.Event()
    task = asyncio.create_task(service.serve(stop))
    try:
        await until(proxy.held.is_set, 30, "the service's CONNECT relayed")
        await asyncio.sleep(0.2)
        assert not service.link.online.is_set() and service.connections == 0
        proxy.release()  # the broker's answers from now on pass (those held stay dropped)
        stop.set()
        await asyncio.wait_for(task, 20)
    finally:
        proxy.close()
    msg = await asyncio.to_thread(retained, bound, f"orbitrig/{rig}/status")
    assert msg is not None and msg.retain and msg.json()["state"] == "offline", msg
    assert msg.json()["message"] == "rig service stopped" and "last_will" not in msg.json(), msg.json()


async def test_backoff_is_not_reset_by_connections_that_carry_no_traffic(bound, tmp_path):
    """Every connection is cut 0.3 s after it was made (CONNACK and SUBACK get
    through): reconnections thin out (jittered exponential backoff, reset only
    after a session stayed up for a while) instead of repeating every 0.1 s."""
    proxy = CutProxy(bound.service_port, lifetime=0.3)
    service = engineless_service(proxy.url, tmp_path, "dropped", reconnect_initial=0.2, reconnect_max=30.0)
    stop = asyncio.Event()
    task = asyncio.create_task(service.serve(stop))
    try:
        await asyncio.sleep(6.0)
        # growing delays 0.1-0.2, 0.2-0.4, 0.4-0.8, 0.8-1.6, 1.6-3.2 s after 0.3 s sessions: <= 6
        # connections in 6 s; a backoff reset at each connection would make about 12
        assert 3 <= service.connections <= 6, service.connections
    finally:
        proxy.close()
        stop.set()
        await asyncio.wait_for(task, 20)


def test_a_command_sent_again_after_a_reconnection_is_answered(tmp_path):
    """The same command (id and bytes) sent again, also right after a reconnection, is a new
    command: carried out and answered, never dropped in silence. (The broker's own redelivery
    is recognised on the link by DUP and packet id: test_reconnect_delivery_once.)"""
    import time as _time

    settings = ServiceSettings(rig_id="redeliver", matrices_dir=write_matrices(tmp_path / "m"))
    service = RigService(
        settings, BrokerSettings("127.0.0.1"), engine_factory=lambda name, m: None, load_matrix=lambda p: None
    )
    sent = []
    service.link.send = lambda topic, payload, qos, retain=False, behind=False: sent.append((topic, payload))
    payload = b'{"cmd":"status","id":"a1"}'
    service.link.connections, service.link.connected_at = 1, _time.monotonic()
    service.handle_command(payload)
    service.handle_command(payload)  # the operator repeats it
    assert sum(t.endswith("/reply") for t, _ in sent) == 2
    service.link.connections, service.link.connected_at = 2, _time.monotonic()  # reconnected
    service.handle_command(payload)  # sent again right after it
    assert sum(t.endswith("/reply") for t, _ in sent) == 3

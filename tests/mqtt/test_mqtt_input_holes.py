"""Command payloads that cannot be read unambiguously, through a real
mosquitto to `orbitrig serve --sim`: each is answered ok:false and changes
nothing (no run starts), while stop and abort stay always accepted, also on
the abort topic (an abort with no run since the service started: both drives
get the emergency stop over a link of the service's own, and the reply says so)."""

from __future__ import annotations

import time

import pytest

from support.mqtt_helpers import ACCOUNTS, RigClient, Service, sim_service_args

RIG = "holes-rig"
ENV = {"ORBITRIG_MQTT_PASSWORD": ACCOUNTS["orbitrig-service"]}


@pytest.fixture(scope="module")
def rig(broker, tmp_path_factory):
    work = tmp_path_factory.mktemp("holes")
    svc = Service(
        sim_service_args(broker.url, RIG, work, "--confirm", "auto"),
        work,
        env=ENV,
    )
    rc = RigClient(broker, RIG, svc)
    try:
        rc.ready()
        yield rc
    finally:
        rc.close()
        assert svc.stop() == 0, svc.text()[-3000:]


def refused_without_effect(rig: RigClient, payload: bytes, cid: str | None) -> str:
    """Publish ``payload`` on <prefix>/cmd; its one reply (ok:false, carrying ``cid``);
    no status other than idle follows. Returns the reason."""
    mark = rig.watch.mark()
    rig.send(payload)
    reply = rig.reply(cid, start=mark)
    assert reply["ok"] is False, reply
    assert rig.command({"cmd": "status"})["ok"] is True  # handled after the refused one
    time.sleep(0.3)
    states = [m.json()["state"] for m in rig.watch.on("status", mark)]
    assert set(states) <= {"idle"}, states
    replies = [m.json() for m in rig.watch.on("reply", mark) if m.json()["id"] == cid]
    assert len(replies) == 1, replies
    return reply["error"]


def test_duplicate_keys_are_refused(rig):
    reason = refused_without_effect(rig, b'{"cmd":"status","cmd":"start","id":"dup-1","matrix":"quick"}', "dup-1")
    assert "'cmd' given more than once" in reason
    reason = refused_without_effect(rig, b'{"cmd":"start","id":"dup-2","matrix":"nope","matrix":"quick"}', "dup-2")
    assert "'matrix' given more than once" in reason


def test_an_id_that_cannot_be_encoded_is_refused_before_anything_runs(rig):
    reason = refused_without_effect(rig, b'{"cmd":"start","id":"\\ud800","matrix":"quick"}', None)
    assert "field 'id' cannot be encoded as UTF-8" in reason
    reason = refused_without_effect(rig, b'{"cmd":"confirm","id":"c-1","step":"\\udc00x"}', "c-1")
    assert "field 'step' cannot be encoded as UTF-8" in reason


def test_deeply_nested_json_is_refused(rig):
    depth = 1500  # past the parser's recursion limit, within the 4096-byte bound
    payload = b'{"cmd":"status","id":"deep-1","x":' + b"[" * depth + b"]" * depth + b"}"
    assert len(payload) < 4096
    reason = refused_without_effect(rig, payload, None)  # the id is never reached
    assert "nested too deeply" in reason


def test_stop_and_abort_stay_always_accepted(rig):
    """A stop with an unencodable id is carried out (answered with id null); on the
    abort topic only stop and abort are taken."""
    mark = rig.watch.mark()
    rig.send(b'{"cmd":"stop","id":"\\ud800"}')
    assert rig.reply(None, start=mark)["ok"] is True
    prefix = rig.prefix
    mark = rig.watch.mark()
    assert rig.broker.pub(f"{prefix}/abort", '{"cmd":"abort","id":"ab-1"}').returncode == 0
    reply = rig.reply("ab-1", start=mark)  # taken, not refused; no run has held the drives yet
    assert reply["ok"] is True and "emergency stop (OFF3) sent to both drives" in reply["detail"], reply
    assert rig.broker.pub(f"{prefix}/abort", '{"cmd":"start","id":"ab-2","matrix":"quick"}').returncode == 0
    reply = rig.reply("ab-2", start=mark)
    assert reply["ok"] is False and "only stop and abort" in reply["error"], reply
    time.sleep(0.3)
    assert {m.json()["state"] for m in rig.watch.on("status", mark)} <= {"idle"}

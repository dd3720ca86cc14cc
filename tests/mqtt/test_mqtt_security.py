"""The broker side of the security contract, with the shipped example ACL:
no anonymous clients, passwords checked, operators may command, viewers may
only read."""

from __future__ import annotations

import subprocess
import time

from support.mqtt_helpers import ACCOUNTS, Watcher


def _sub_once(broker, user, password=None):
    args = ["mosquitto_sub", "-h", "127.0.0.1", "-p", str(broker.port), "-t", "orbitrig/#", "-C", "1", "-W", "3"]
    if user:
        args += ["-u", user, "-P", password if password is not None else ACCOUNTS[user]]
    return subprocess.run(args, capture_output=True, text=True, timeout=10)


def test_anonymous_client_is_refused(broker):
    done = _sub_once(broker, None)
    assert done.returncode != 0
    assert "not authori" in done.stderr.lower()


def test_wrong_password_is_refused(broker):
    done = _sub_once(broker, "operator", "not-the-password")
    assert done.returncode != 0
    assert "not authori" in done.stderr.lower()


def test_operator_may_command_viewer_may_not(broker):
    # The service's account listens to the commands, as the rig service does.
    svc = Watcher(broker, "orbitrig/+/cmd", user="orbitrig-service")
    try:
        assert broker.pub("orbitrig/r1/cmd", '{"cmd":"status","id":"by-viewer"}', user="viewer").returncode == 0
        v5 = broker.pub("orbitrig/r1/cmd", '{"cmd":"status","id":"by-viewer-v5"}', user="viewer", version=5)
        assert "not authorized" in v5.stderr.decode().lower()  # MQTT 5 PUBACK reason code
        assert broker.pub("orbitrig/r1/cmd", '{"cmd":"status","id":"by-operator"}').returncode == 0
        got = svc.wait_for(lambda m: b"by-operator" in m.payload, 5)
        assert got.qos == 1
        time.sleep(0.3)
        assert [m.payload for m in svc.messages] == [got.payload]  # nothing from the viewer
    finally:
        svc.close()


def test_viewer_reads_but_cannot_fake_status(broker):
    view = Watcher(broker, "orbitrig/r2/#", user="viewer")
    try:
        broker.pub("orbitrig/r2/status", '{"state":"idle"}', user="viewer")
        broker.pub("orbitrig/r2/status", '{"state":"idle"}', user="operator")
        broker.pub("orbitrig/r2/reply", '{"id":"x","ok":true}', user="orbitrig-service")
        view.wait_for(lambda m: m.topic == "orbitrig/r2/reply", 5)
        time.sleep(0.2)
        assert [m.topic for m in view.messages] == ["orbitrig/r2/reply"]
    finally:
        view.close()


def test_service_account_cannot_command(broker):
    svc = Watcher(broker, "orbitrig/+/cmd", user="orbitrig-service")
    try:
        broker.pub("orbitrig/r3/cmd", '{"cmd":"stop","id":"self"}', user="orbitrig-service")
        broker.pub("orbitrig/r3/cmd", '{"cmd":"stop","id":"op"}', user="operator")
        svc.wait_for(lambda m: b'"op"' in m.payload, 5)
        time.sleep(0.2)
        assert len(svc.messages) == 1
    finally:
        svc.close()


def test_only_operators_may_publish_on_the_abort_topic(broker):
    svc = Watcher(broker, "orbitrig/+/abort", user="orbitrig-service")  # the service reads it
    try:
        broker.pub("orbitrig/r4/abort", '{"cmd":"abort","id":"by-viewer"}', user="viewer")
        broker.pub("orbitrig/r4/abort", '{"cmd":"abort","id":"by-service"}', user="orbitrig-service")
        assert broker.pub("orbitrig/r4/abort", '{"cmd":"abort","id":"by-operator"}').returncode == 0
        svc.wait_for(lambda m: b"by-operator" in m.payload, 5)
        time.sleep(0.2)
        assert [m.payload for m in svc.messages] == [b'{"cmd":"abort","id":"by-operator"}']
    finally:
        svc.close()


def test_the_abort_account_only_reads_the_abort_topic(broker):
    # the service's abort connection: reads <prefix>/abort, nothing else, and publishes nothing
    abort = Watcher(
        broker, ("orbitrig/r5/abort", "orbitrig/r5/cmd", "orbitrig/r5/status"), user="orbitrig-service-abort"
    )
    view = Watcher(broker, "orbitrig/r5/#", user="viewer")
    try:
        assert broker.pub("orbitrig/r5/cmd", '{"cmd":"status","id":"c"}').returncode == 0
        broker.pub("orbitrig/r5/status", '{"state":"idle"}', user="orbitrig-service-abort")
        broker.pub("orbitrig/r5/abort", '{"cmd":"abort","id":"by-abort-account"}', user="orbitrig-service-abort")
        assert broker.pub("orbitrig/r5/abort", '{"cmd":"abort","id":"by-operator"}').returncode == 0
        abort.wait_for(lambda m: b"by-operator" in m.payload, 5)
        view.wait_for(lambda m: b"by-operator" in m.payload, 5)
        time.sleep(0.2)
        assert [m.payload for m in abort.messages] == [b'{"cmd":"abort","id":"by-operator"}']
        assert [m.topic for m in view.messages] == ["orbitrig/r5/cmd", "orbitrig/r5/abort"]
    finally:
        abort.close()
        view.close()

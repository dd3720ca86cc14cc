"""docs/protocols/mqtt.md: the topic tree lives under a configurable prefix (default
orbitrig/<rig_id>). `orbitrig serve --prefix P` with a real mosquitto (the example
ACL grants orbitrig/+/..., so the test prefix has two levels)."""

from __future__ import annotations


from support.cli_helpers import orbitrig
from support.mqtt_helpers import ACCOUNTS, RigClient, Service, retained, write_matrices


def test_serve_uses_the_configured_prefix(broker, tmp_path):
    args = [
        "--broker",
        broker.url,
        "--rig-id",
        "rig9",
        "--prefix",
        "orbitrig/labA",
        "--username",
        "orbitrig-service",
        "--matrices",
        str(write_matrices(tmp_path / "matrices")),
        "--out",
        str(tmp_path / "runs"),
    ]
    svc = Service(args, tmp_path, env={"ORBITRIG_MQTT_PASSWORD": ACCOUNTS["orbitrig-service"]})
    rc = RigClient(broker, "labA", svc)  # watches orbitrig/labA/#
    try:
        assert rc.status("idle", timeout=60)["run_id"] is None  # a busy host's start-up: no log line in 20 s
        assert rc.command({"cmd": "status"}) == {"id": "t1-status", "ok": True}
        assert retained(broker, "orbitrig/labA/status").json()["state"] == "idle"
        assert retained(broker, "orbitrig/rig9/status", wait=0.5) is None  # not under the default prefix
    finally:
        rc.close()
        svc.stop()
    assert retained(broker, "orbitrig/labA/status").json()["state"] == "offline"


def test_bad_prefix_is_a_usage_error(tmp_path):
    p = orbitrig("serve", "--broker", "mqtt://127.0.0.1:1", "--prefix", "orbitrig/+/x", timeout=60, columns=None)
    assert p.returncode == 2 and p.stdout == "" and "--prefix" in p.stderr and "wildcards" in p.stderr

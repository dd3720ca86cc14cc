"""A retained abort (spec: cmd is not retained, and stop and abort are always accepted) is carried
out once: when the service subscribes. The broker hands it over again at every reconnection of the
service; that copy is dropped, also once hundreds of other commands have come since (the service's
memory of redeliveries keeps the last 256 commands), so a run started since is not aborted by a
stale request. Real mosquitto, the service in its own process on the simulator, its link cut by a
relay."""

from __future__ import annotations

import json
import subprocess
import time

from support.mqtt_helpers import ACCOUNTS, CutProxy, RigClient, Service, sim_service_args

RIG = "stale-rig"


def test_a_retained_abort_is_carried_out_once_not_at_each_reconnection(broker, tmp_path):
    topic = f"orbitrig/{RIG}/cmd"
    broker.pub(topic, json.dumps({"cmd": "abort", "id": "stale-abort"}), retain=True)
    proxy = CutProxy(broker.service_port)
    svc = Service(
        sim_service_args(proxy.url, RIG, tmp_path, "--confirm", "auto", speedup=2),  # a run of about a minute
        tmp_path,
        env={"ORBITRIG_MQTT_PASSWORD": ACCOUNTS["orbitrig-service"]},
    )
    rc = RigClient(broker, RIG, svc)
    try:
        rc.ready()
        reply = rc.reply("stale-abort", timeout=10)  # carried out: no run since the start, the drives stopped
        assert reply["ok"] is True and "emergency stop (OFF3) sent to both drives" in reply["detail"], reply
        assert rc.command({"cmd": "start", "matrix": "long"})["ok"] is True
        rc.status("running", timeout=30)
        for batch in range(6):  # 300 commands since the abort, each handled
            _status_commands(broker, topic, range(50 * batch, 50 * batch + 50))
            rc.reply(f"s{50 * batch + 49}", timeout=30)
        mark = rc.watch.mark()
        proxy.cut()
        rc.status("offline", start=mark, timeout=15)  # the broker saw the link drop
        back = rc.watch.mark()
        proxy.restore()
        rc.status("running", start=back, timeout=30)  # reconnected: the retained abort handed over again
        dropped = "dropped retained abort (id 'stale-abort'): carried out once already"
        deadline = time.monotonic() + 30
        while dropped not in svc.text() and time.monotonic() < deadline:
            time.sleep(0.1)  # the handed-over copy read and dropped
        log = svc.text()
        assert dropped in log, log[-3000:]
        states = [m.json()["state"] for m in rc.watch.on("status", back)]
        assert set(states) <= {"running"}, states  # not aborted by the stale copy
        assert rc.command({"cmd": "abort"})["ok"] is True
    finally:
        broker.pub(topic, b"", retain=True)
        rc.close()
        svc.stop()
        proxy.close()


def _status_commands(broker, topic: str, ids) -> None:
    """Status commands `s<id>` published by one mosquitto_pub (one per line)."""
    lines = "".join(json.dumps({"cmd": "status", "id": f"s{k}"}) + "\n" for k in ids)
    args = ["mosquitto_pub", *broker.client_args("operator"), "-q", "1", "-t", topic, "-l"]
    done = subprocess.run(args, input=lines.encode(), capture_output=True, timeout=30)
    assert done.returncode == 0, done.stderr

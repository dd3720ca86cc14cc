"""The real `orbitrig serve --sim` under a real mosquitto: a subscriber that comes later learns
where the run is from the retained status, which names the run's latest progress (an extension:
docs/protocols/mqtt.md). A fresh subscription (mosquitto_sub, a dashboard signed in at a shift
change) made while the run waits for the operator's manual setting of its second point gets
point 2 of 2, although the service sends no progress until that is confirmed. The progress
itself stays as the contract has it: QoS 0, never retained."""

from __future__ import annotations

import pytest

from support.mqtt_helpers import RigClient, retained, serving_sim, two_pressures

RIG = "late-rig"
STATUS, PROGRESS = f"orbitrig/{RIG}/status", f"orbitrig/{RIG}/progress"
TWO = two_pressures("two")


@pytest.fixture(scope="module")
def service(broker, tmp_path_factory):
    yield from serving_sim(broker, tmp_path_factory, RIG, two=TWO)


@pytest.fixture
def rig(broker, service):
    rc = RigClient(broker, RIG, service)
    rc.ready(lambda s: s["state"] in ("idle", "faulted"))
    try:
        yield rc
        statuses = rc.watch.on("status")
        if statuses and statuses[-1].json()["state"] not in ("idle", "faulted"):  # a test that failed mid-run
            mark = rc.watch.mark()
            rc.command({"cmd": "abort"})
            rc.status(lambda s: s["state"] in ("idle", "faulted"), start=mark, timeout=30)
    finally:
        rc.close()


def test_a_late_subscriber_learns_the_waiting_runs_point_from_the_status(broker, rig):
    mark = rig.watch.mark()
    started = rig.command({"cmd": "start", "matrix": "two"})
    assert started["ok"] is True, started
    rig.status(lambda s: s.get("step") == "manual:0000", start=mark)
    assert rig.command({"cmd": "confirm", "step": "manual:0000"})["ok"] is True
    rig.status(lambda s: s.get("step") == "manual:0001", start=mark, timeout=60)

    late = retained(broker, STATUS)  # a fresh subscription while the run waits for the operator
    assert late is not None and late.retain and late.qos == 1
    s = late.json()
    assert (s["state"], s["step"]) == ("waiting", "manual:0001"), s
    p = s["progress"]
    assert (p["run_id"], p["point"], p["points"]) == (s["run_id"], 2, 2), p
    assert (p["frequency"], p["frequencies"], p["revolutions"], p["block_revolutions"]) == (0, 2, 0, 0), p
    assert p["point_label"] == s["point_label"] and p["fraction"] == 0.5, p  # point 1 of 2 measured
    assert p["eta_s"] is not None and p["eta_s"] > 0, p
    said = [m for m in rig.watch.messages[mark:] if m.topic == PROGRESS]
    assert said and said[-1].json() == p, said[-1:]  # the run's latest progress message, as it was said
    assert all(not m.retain and m.qos == 0 for m in said), said  # the contract's progress: QoS 0, not retained
    assert retained(broker, PROGRESS, wait=1.0) is None  # nothing for a late subscriber on progress itself

    mark = rig.watch.mark()
    assert rig.command({"cmd": "abort"})["ok"] is True
    idle = rig.status("idle", start=mark, timeout=30)
    assert "progress" not in idle, idle  # the run has ended: no progress is the present


def test_the_status_said_again_names_the_latest_progress_not_that_of_its_first_saying(rig):
    """A status said again (the `status` command; the first message of every reconnection) while the run
    measures names the progress as it is then, not as it was when the state last changed."""
    mark = rig.watch.mark()
    assert rig.command({"cmd": "start", "matrix": "long"})["ok"] is True
    rig.status(lambda s: s.get("step") == "manual:0000", start=mark)
    confirmed = rig.watch.mark()
    assert rig.command({"cmd": "confirm", "step": "manual:0000"})["ok"] is True
    running = rig.status("running", start=confirmed)
    assert running["progress"]["frequency"] == 0, running  # the point's first block not begun then
    rig.watch.wait_for(
        lambda m: m.topic == PROGRESS and m.json()["frequency"] >= 2, 30, start=confirmed, what="the second block"
    )
    asked = rig.watch.mark()
    assert rig.command({"cmd": "status"})["ok"] is True
    again = rig.status("running", start=asked)
    p = again["progress"]
    assert (again["run_id"], again["since"]) == (running["run_id"], running["since"]), again  # the same status
    assert (p["run_id"], p["point"], p["points"]) == (running["run_id"], 1, 1) and p["frequency"] >= 2, p
    said = [m.json() for m in rig.watch.messages[confirmed:] if m.topic == PROGRESS]
    assert p in said, p  # one the run said, the latest then
    mark = rig.watch.mark()
    assert rig.command({"cmd": "abort"})["ok"] is True
    rig.status("idle", start=mark, timeout=30)

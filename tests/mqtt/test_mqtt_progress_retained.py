"""The real `orbitrig serve --sim` under a real mosquitto: a subscriber that comes later learns
where the run is at once. The progress is retained, so a fresh subscription (mosquitto_sub, a
dashboard signed in at a shift change) made while the run waits for the operator's manual setting
of its second point gets point 2 of 2, although the service sends no progress until that is
confirmed. The run's end marks it `ended` (where the run ended), and the service's start replaces
what a killed service left by a progress naming no run: neither is taken for a live run's."""

from __future__ import annotations

import json

import pytest

from orbitrig.service.protocol import NO_RUN_PROGRESS, progress_payload
from support.mqtt_helpers import MATRIX, RigClient, Service, retained, service_password_file, sim_service_args

RIG = "late-rig"
PROGRESS = f"orbitrig/{RIG}/progress"
#: two points differing in the recess pressure only (the operator sets each by hand), two orbit blocks each
TWO = MATRIX.format(name="two", revs=10, ratios="[0.5, 0.8]", directions='["forward"]').replace(
    "recess_pressure_mpa = [0.4826]", "recess_pressure_mpa = [0.4826, 0.6895]"
)
#: the retained progress while no run is under way since the service started
NO_RUN = json.loads(progress_payload(NO_RUN_PROGRESS))
#: what a service killed during a run left retained
LEFT_OVER = {"run_id": "dead@1", "point": 7, "points": 9, "frequency": 2, "frequencies": 4, "revolutions": 5}


@pytest.fixture(scope="module")
def service(broker, tmp_path_factory):
    done = broker.pub(PROGRESS, json.dumps(LEFT_OVER), user="orbitrig-service", retain=True)
    assert done.returncode == 0, done.stderr
    work = tmp_path_factory.mktemp("serve")
    args = sim_service_args(broker.url, RIG, work, "--password-file", str(service_password_file(work)))
    (work / "matrices" / "two.toml").write_text(TWO)
    svc = Service(args, work)
    yield svc
    assert svc.stop() == 0, svc.text()[-3000:]


@pytest.fixture
def rig(broker, service):
    rc = RigClient(broker, RIG, service)
    rc.status(lambda s: s["state"] in ("idle", "faulted"), timeout=60)
    yield rc
    rc.close()


def test_a_late_subscriber_gets_the_waiting_runs_point_and_the_end_marks_it(broker, rig):
    rig.watch.wait_for(lambda m: m.topic == PROGRESS and m.json().get("run_id") is None, what="no run's progress")
    first = retained(broker, PROGRESS)  # the killed service's progress: replaced as the service started
    assert first is not None and first.json() == {**NO_RUN, "ended": True}, first
    mark = rig.watch.mark()
    started = rig.command({"cmd": "start", "matrix": "two"})
    assert started["ok"] is True, started
    rig.status(lambda s: s.get("step") == "manual:0000", start=mark)
    assert rig.command({"cmd": "confirm", "step": "manual:0000"})["ok"] is True
    waiting = rig.status(lambda s: s.get("step") == "manual:0001", start=mark, timeout=60)

    late = retained(broker, PROGRESS)  # a fresh subscription while the run waits for the operator
    assert late is not None and late.retain and late.qos == 0
    p = late.json()
    assert (p["run_id"], p["point"], p["points"]) == (waiting["run_id"], 2, 2), p
    assert (p["frequency"], p["frequencies"], p["revolutions"], p["block_revolutions"]) == (0, 2, 0, 0), p
    assert p["point_label"] == waiting["point_label"] and p["fraction"] == 0.5, p  # point 1 of 2 measured
    assert p["eta_s"] is not None and p["eta_s"] > 0, p

    mark = rig.watch.mark()
    assert rig.command({"cmd": "abort"})["ok"] is True
    rig.status("idle", start=mark, timeout=30)
    end = retained(broker, PROGRESS)
    assert end is not None and end.json() == {**p, "ended": True}, end  # where the run ended: no run under way
    # said once, just before the status that ends the run
    said = [
        m.json()["state"] if m.topic.endswith("/status") else "ended" if m.json().get("ended") else "progress"
        for m in rig.watch.messages[mark:]
        if m.topic.endswith(("/status", "/progress"))
    ]
    assert said.count("ended") == 1 and said.index("ended") == said.index("idle") - 1, said

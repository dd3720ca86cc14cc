"""The real `orbitrig serve --sim` under a real mosquitto: a pause requested and not yet
reached is withdrawn by resume (the run never pauses); one asked while the run waits for a
manual setting is said truthfully (reply and status: it takes effect once the setting is
confirmed) and holds the run right after the confirmation; and a result numbers its point
0-based as `index` (the run files' PPPP) while progress counts it 1-based."""

from __future__ import annotations

import time

import pytest

from support.mqtt_helpers import RigClient, serving_sim

RIG = "pause-rig"


@pytest.fixture(scope="module")
def service(broker, tmp_path_factory):
    yield from serving_sim(broker, tmp_path_factory, RIG)


@pytest.fixture
def rig(broker, service):
    rc = RigClient(broker, RIG, service)
    assert rc.ready(lambda s: True)["state"] in ("idle", "faulted"), service.text()[-3000:]
    yield rc
    if service.proc.poll() is None and rc.watch.on("status")[-1].json()["state"] not in ("idle", "faulted"):
        rc.command({"cmd": "abort"})
        rc.status("idle", timeout=30)
    rc.close()


def test_resume_withdraws_a_pause_requested_while_waiting(rig):
    mark = rig.watch.mark()
    assert rig.command({"cmd": "start", "matrix": "quick"})["ok"] is True
    rig.status("waiting", start=mark)
    assert rig.command({"cmd": "pause"})["ok"] is True  # honoured once the setting is confirmed
    rig.status(lambda s: s["state"] == "waiting" and "pause requested" in s["message"], start=mark)
    m = rig.watch.mark()
    assert rig.command({"cmd": "resume"})["ok"] is True  # withdraws it
    time.sleep(0.3)
    after = [s.json() for s in rig.watch.on("status", m)]  # the state stays: still waiting, said without the pause
    assert [s["state"] for s in after] == ["waiting"] and "pause" not in after[-1]["message"], after
    assert rig.command({"cmd": "confirm", "step": "manual:0000"})["ok"] is True
    idle = rig.status("idle", start=mark, timeout=60)
    assert "completed" in idle["message"], idle
    states = [s.json()["state"] for s in rig.watch.on("status", mark)]
    assert "paused" not in states, states  # the run never paused


def test_result_index_is_0_based_and_progress_counts_from_1(rig, service):
    mark = rig.watch.mark()
    assert rig.command({"cmd": "start", "matrix": "quick"})["ok"] is True
    rig.status("waiting", start=mark)
    assert rig.command({"cmd": "confirm", "step": "manual:0000"})["ok"] is True
    assert "completed" in rig.status("idle", start=mark, timeout=60)["message"]
    # the result: `index` 0-based (the run files' 0000), progress 1-based (point 1 of 1)
    (result,) = (r.json() for r in rig.watch.on("result", mark))
    assert result["index"] == 0 and result["point"] == 0
    progress = [p.json() for p in rig.watch.on("progress", mark)]
    assert progress and max(p["point"] for p in progress) == 1 and {p["points"] for p in progress} == {1}


def test_resume_without_a_pending_pause_is_refused(rig):
    mark = rig.watch.mark()
    assert rig.command({"cmd": "start", "matrix": "quick"})["ok"] is True
    rig.status("waiting", start=mark)
    refused = rig.command({"cmd": "resume"})
    assert refused["ok"] is False and "cannot resume while the run is waiting" in refused["error"]
    # a pause that is not withdrawn is honoured after the confirmation
    assert rig.command({"cmd": "pause"})["ok"] is True
    assert rig.command({"cmd": "confirm", "step": "manual:0000"})["ok"] is True
    rig.status("paused", start=mark)
    assert rig.command({"cmd": "abort"})["ok"] is True
    rig.status("idle", start=mark, timeout=30)


def test_a_pause_while_waiting_is_said_to_take_effect_once_the_setting_is_confirmed(rig):
    """The run waiting for the operator's manual setting cannot pause before it is confirmed: the
    reply and the waiting status say so (not 'at its next safe point', seconds away, while the run
    may wait for minutes), and the run pauses right after the confirmation, before any block."""
    mark = rig.watch.mark()
    assert rig.command({"cmd": "start", "matrix": "quick"})["ok"] is True
    waiting = rig.status("waiting", start=mark)
    assert "pause" not in waiting["message"]
    m = rig.watch.mark()
    reply = rig.command({"cmd": "pause", "by": "ada"})
    assert reply["ok"] is True and "once manual:0000 is confirmed" in reply.get("detail", ""), reply
    said = rig.status(lambda s: "pause requested" in s["message"], start=m, timeout=5)
    assert said["state"] == "waiting" and said["since"] == waiting["since"] and said["step"] == "manual:0000", said
    assert said["message"].startswith(waiting["message"]), (said, waiting)
    assert said["message"].endswith("; pause requested by ada: the run pauses once manual:0000 is confirmed"), said
    time.sleep(1.0)  # nothing else: the run waits for the operator, not for a safe point
    assert [s.json()["state"] for s in rig.watch.on("status", m)] == ["waiting"]
    m = rig.watch.mark()
    assert rig.command({"cmd": "confirm", "step": "manual:0000"})["ok"] is True
    paused = rig.status("paused", start=m, timeout=15)
    assert "paused at a safe point" in paused["message"] and "asked by ada" in paused["message"], paused
    assert [s.json()["state"] for s in rig.watch.on("status", m)] == ["running", "paused"]
    assert all(p.json()["frequency"] == 0 for p in rig.watch.on("progress", m))  # held before the first block
    m = rig.watch.mark()
    assert rig.command({"cmd": "pause"})["ok"] is False  # held already: refused, as before
    assert rig.command({"cmd": "abort"})["ok"] is True
    rig.status("idle", start=m, timeout=30)

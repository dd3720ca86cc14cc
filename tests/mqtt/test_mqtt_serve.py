"""End to end: the real `orbitrig serve --sim` under a real, authenticated
mosquitto, driven by independent clients (mosquitto_pub / mosquitto_sub)."""

from __future__ import annotations

import asyncio
import json
import re
import signal
import time
from pathlib import Path

import h5py
import pytest

from orbitrig.cli.scenarios import default_scenario
from orbitrig.store.identity import header_identity
from support.units import UREG
from support.mqtt_helpers import ACCOUNTS, Broker, RigClient, Service, retained, sim_service_args
from support.mqtt_helpers import service_password_file
from support.polling import until

RIG = "sim-rig"
PROGRESS_KEYS = {
    "run_id",
    "point",
    "points",
    "frequency",
    "frequencies",
    "revolutions",
    "eta_s",
    "point_label",
    "block_revolutions",
    "fraction",
}
#: an operating point's label (orbitrig.run.plan.OperatingPoint.label)
LABEL = re.compile(r"^w\d+rpm_pr[\d.]+MPa_b[\d.]+_es[\d.]+_ed[\d.]+$")
STATUS_KEYS = {"state", "run_id", "since", "message"}


def run_status(workdir: Path, run_id: str) -> str:
    """The status stored in run.h5 of the latest run `run_id` (storage contract)."""
    with h5py.File(_run_dir(workdir, run_id) / "run.h5", "r") as f:
        return str(f.attrs["status"])


def _run_dir(workdir: Path, run_id: str) -> Path:
    """The folder of run `run_id` that has ended (its run.h5 written): its run.json's identity, one
    run's alone (a millisecond's creation time), not the newest file of the runs that mention it."""
    (run,) = [p.parent for p in (workdir / "runs").glob("*/run.h5") if _identity(p.parent) == run_id]
    return run


def _identity(run_dir: Path) -> str:
    return header_identity(json.loads((run_dir / "run.json").read_text()))


def _run_id_in_log(run_dir: Path, run_id: str) -> bool:
    log = run_dir / "run.log"
    return log.exists() and run_id in log.read_text(errors="replace")


@pytest.fixture(scope="module")
def service(broker, tmp_path_factory):
    """The module's `serve --sim`, its scenario given as --sim-config: a copy of the default one
    (the same simulator: every run records the copy's file)."""
    work = tmp_path_factory.mktemp("serve")
    scenario = work / "scenario.toml"
    scenario.write_text(default_scenario().text)
    args = sim_service_args(broker.url, RIG, work, "--password-file", str(service_password_file(work)))
    svc = Service([*args, "--sim-config", str(scenario)], work)
    svc.work, svc.scenario = work, scenario
    yield svc
    code = svc.stop()
    assert code == 0, svc.text()[-3000:]
    recorded = {json.loads(h.read_text())["sim_scenario"]["name"] for h in (work / "runs").glob("*/run.json")}
    assert recorded == {str(scenario)}  # every run the service started ran it


@pytest.fixture
def rig(broker, service):
    rc = RigClient(broker, RIG, service)
    try:
        first = rc.ready(lambda s: True)
        assert first["state"] in ("idle", "faulted"), first
    except AssertionError:
        raise AssertionError("service not idle:\n" + service.text()[-3000:]) from None
    yield rc
    if (
        service.proc.poll() is None
        and rc.watch.on("status")
        and rc.watch.on("status")[-1].json()["state"] not in ("idle", "faulted")
    ):
        rc.command({"cmd": "abort"})
        rc.status("idle", timeout=30)
    rc.close()


def test_status_is_retained_and_follows_the_spec(broker, rig):
    msg = retained(broker, f"orbitrig/{RIG}/status")
    assert msg is not None and msg.retain and msg.qos == 1
    # the ready status of a service whose runs folder holds no run yet: no last run to say
    assert set(msg.json()) == STATUS_KEYS | {"last_run"} and msg.json()["last_run"] is None


BAD = [
    (b"start quick", None, "payload is not JSON"),
    (b'{"id": "b1"}', "b1", "missing field 'cmd'"),
    (b'{"cmd": "launch", "id": "b2"}', "b2", "unknown command 'launch'"),
    (b'{"cmd": "start", "id": "b3"}', "b3", "missing field 'matrix' for command 'start'"),
    (
        b'{"cmd": "start", "id": "b4", "matrix": "quick", "spin_rpm": 9000}',
        "b4",
        "unexpected field 'spin_rpm' for command 'start'",
    ),
    (b'{"cmd": "start", "id": "b5", "matrix": "../../etc/passwd"}', "b5", "not a path"),
    (
        b'{"cmd": "start", "id": "b6", "matrix": "nope"}',
        "b6",
        "no matrix 'nope' in the matrix folder (available: judged, long, quick)",
    ),
    (b'{"cmd": "confirm", "id": "b7", "step": 3}', "b7", "field 'step' must be a string, got number"),
    (b'{"cmd": "pause", "id": 8}', None, "field 'id' must be a string"),
    (b'{"cmd": "pause", "id": "b9"}', "b9", "no run is active: nothing to pause"),
]


def test_bad_payloads_get_reasons_and_change_nothing(rig):
    mark = rig.watch.mark()
    for payload, cid, reason in BAD:
        m = rig.watch.mark()
        rig.send(payload)
        reply = rig.reply(cid, start=m)
        assert reply["ok"] is False and reason in reply["error"], (payload, reply)
        assert set(reply) == {"id", "ok", "error"}
    time.sleep(0.3)
    assert rig.watch.on("status", mark) == []  # nothing changed
    assert len(rig.watch.on("reply", mark)) == len(BAD)  # exactly one reply each


def test_viewer_start_is_denied_by_the_broker(rig):
    mark = rig.watch.mark()
    rig.send({"cmd": "start", "matrix": "quick", "id": "from-viewer"}, user="viewer", version=5)
    assert "not authorized" in rig.last_pub.stderr.decode().lower()
    rig.send({"cmd": "start", "matrix": "quick", "id": "from-viewer-311"}, user="viewer")
    # the service answers a later operator command, but never saw the viewer's
    assert rig.reply(rig.send({"cmd": "status"}), start=mark)["ok"] is True
    time.sleep(0.3)
    assert [m.json()["id"] for m in rig.watch.on("reply", mark)] == ["t1-status"]
    assert {m.json()["state"] for m in rig.watch.on("status", mark)} <= {"idle", "faulted"}


def test_anonymous_client_cannot_command(broker, rig):
    done = broker.pub(f"orbitrig/{RIG}/cmd", '{"cmd":"abort","id":"anon"}', user=None)
    assert done.returncode != 0 and b"not authori" in done.stderr.lower()


def test_remote_run_confirm_pause_resume_stop(rig, service):
    mark = rig.watch.mark()
    assert rig.command({"cmd": "start", "matrix": "long", "by": "ada"}) == {"id": "t1-start", "ok": True}
    refused = rig.command({"cmd": "start", "matrix": "quick"})
    assert refused["ok"] is False and "a run is active" in refused["error"]
    waiting = rig.status("waiting", start=mark)
    run_id = waiting["run_id"]
    assert "confirm step 'manual:0000'" in waiting["message"]
    assert (waiting["matrix"], waiting["by"]) == ("long", "ada")  # what runs, and for whom
    wrong = rig.command({"cmd": "confirm", "step": "manual:0042"})
    assert wrong["ok"] is False and "manual:0000" in wrong["error"]
    label = waiting["point_label"]  # the point the manual setting is for
    assert LABEL.match(label), label
    m = rig.watch.mark()
    assert rig.command({"cmd": "confirm", "step": "manual:0000"})["ok"] is True
    running = rig.status("running", start=m)
    # what the run does now, not only the answer it was given
    assert running["message"] == f"confirmed manual:0000; measuring point 1 of 1: {label} (point 0000)"
    assert running["point_label"] == label

    prog = rig.watch.wait_for(
        lambda m: m.topic.endswith("/progress") and m.json()["revolutions"] > 0, 30, start=mark, what="progress"
    )
    assert prog.qos == 0 and set(prog.json()) == PROGRESS_KEYS and prog.json()["run_id"] == run_id
    assert prog.json()["points"] == 1 and prog.json()["frequencies"] == 16 and prog.json()["point_label"] == label

    assert rig.command({"cmd": "pause"})["ok"] is True
    paused = rig.status("paused", start=mark)
    assert paused["run_id"] == run_id
    again = rig.command({"cmd": "pause"})
    assert again["ok"] is False and "cannot pause while the run is paused" in again["error"]
    assert paused["point_label"] == label
    m = rig.watch.mark()
    assert rig.command({"cmd": "resume"})["ok"] is True
    resumed = rig.status("running", start=m)
    assert resumed["message"] == f"resumed; measuring point 1 of 1: {label} (point 0000)"
    m = rig.watch.mark()
    assert rig.command({"cmd": "stop"})["ok"] is True
    rig.status("stopping", start=m)
    idle = rig.status("idle", start=m, timeout=60)
    assert idle["run_id"] == run_id and "stopped" in idle["message"]
    assert (paused["matrix"], idle["matrix"], idle["by"]) == ("long", "long", "ada")  # every status of the run
    folder = Path(idle["folder"])  # the run's own, absolute: what `orbitrig sweep --resume` is given
    assert folder.is_absolute() and _run_id_in_log(folder, run_id) and waiting["folder"] == idle["folder"]
    assert run_status(service.work, run_id) == "stopped"
    assert not rig.watch.on("result", mark)  # stopped before the point was complete


def test_abort_wins_while_waiting_for_a_confirmation(rig, service):
    mark = rig.watch.mark()
    assert rig.command({"cmd": "start", "matrix": "quick"})["ok"] is True
    run_id = rig.status("waiting", start=mark)["run_id"]
    assert rig.command({"cmd": "abort"})["ok"] is True
    idle = rig.status("idle", start=mark, timeout=30)
    assert idle["run_id"] == run_id and "aborted" in idle["message"]
    assert run_status(service.work, run_id) == "aborted"


def test_stop_wins_while_waiting_for_a_confirmation(rig, service):
    mark = rig.watch.mark()
    assert rig.command({"cmd": "start", "matrix": "quick"})["ok"] is True
    run_id = rig.status("waiting", start=mark)["run_id"]
    assert rig.command({"cmd": "stop"})["ok"] is True
    idle = rig.status("idle", start=mark, timeout=30)
    assert idle["run_id"] == run_id and "stopped" in idle["message"]


def test_completed_run_publishes_one_result_per_point(rig, service):
    mark = rig.watch.mark()
    assert rig.command({"cmd": "start", "matrix": "quick"})["ok"] is True
    run_id = rig.status("waiting", start=mark)["run_id"]
    assert rig.command({"cmd": "confirm", "step": "manual:0000"})["ok"] is True
    idle = rig.status("idle", start=mark, timeout=60)
    assert "completed" in idle["message"], idle
    results = rig.watch.on("result", mark)
    assert len(results) == 1 and results[0].qos == 1
    res = results[0].json()
    assert res["run_id"] == run_id
    # progress and status name the point as its result does
    labels = {m.json()["point_label"] for m in rig.watch.on("progress", mark)}
    running = [m.json() for m in rig.watch.on("status", mark) if m.json()["state"] == "running"]
    assert labels == {res["label"]}
    said = [(s["message"], s.get("point_label")) for s in running]
    assert said == [
        (f"run {run_id} started", None),
        (f"measuring point 1 of 1: {res['label']} (point 0000)", res["label"]),  # the point starts: said at once
        (f"confirmed manual:0000; measuring point 1 of 1: {res['label']} (point 0000)", res["label"]),
        ("every point measured: both drives ramp to zero", None),  # the closing ramp: no point under way
    ], said
    assert "point_label" not in idle  # no point under way once the run has ended
    text = json.dumps(res)
    assert "Kxx" in text and "1000" in text  # identified coefficients and the point's settings
    assert run_status(service.work, run_id) == "completed"
    # the simulator's scenario (--sim-config's) is recorded as a --sim sweep records it
    header = json.loads((_run_dir(service.work, run_id) / "run.json").read_text())
    given = (str(service.scenario), default_scenario().text)
    assert (header["sim_scenario"]["name"], header["sim_scenario"]["text"]) == given
    with h5py.File(_run_dir(service.work, run_id) / "run.h5", "r") as f:
        assert (f.attrs["sim_scenario_name"], f.attrs["sim_scenario_config"]) == given
    # its figures went to a drawing process as the point completed (orbitrig report reuses what it drew)
    assert "report figures: 1 point(s) handed to the drawing process, 0 not" in service.text()


def test_result_carries_intervals_uncertainty_verdicts_and_refusals(rig, service):
    mark = rig.watch.mark()
    assert rig.command({"cmd": "start", "matrix": "judged"})["ok"] is True
    settings = rig.status("waiting", start=mark)["settings"]
    assert rig.command({"cmd": "confirm", "step": "manual:0000"})["ok"] is True
    idle = rig.status("idle", start=mark, timeout=60)
    assert "completed" in idle["message"]
    (msg,) = rig.watch.on("result", mark)
    res = msg.json()
    rows = {(r["lms"], r["model"], r["freq_dep"]): r for r in res["identification"]}
    # every unit a subscriber gets is machine-readable: the manual settings' and each fit's (SI)
    assert {UREG.parse_units(s["unit"]).dimensionality for s in settings.values()} >= {UREG.m.dimensionality}
    lives = [m.json() for m in rig.watch.on("live", mark)]
    assert lives and all(UREG.parse_units(u) is not None for live in lives for u in live["units"].values())
    for row in res["identification"]:
        for key, unit in row.get("units", {}).items():  # SI: the value is its base-unit magnitude
            value = row["coefficients"][key]
            assert UREG.Quantity(value, unit).to_base_units().magnitude == pytest.approx(value, rel=1e-12), (key, unit)
    fit = rows[("piezo", "kc7", "none")]
    for key, (lo, hi) in fit["confidence_95"].items():
        assert lo < fit["coefficients"][key] < hi
    assert fit["interval"] == "normal"  # orbit-table v3: the quantile of confidence_95 (u_* stored)
    assert fit["uncertainty"]["k"] == 2.0 and fit["uncertainty"]["systematic"]["Kxx"] > 0
    assert fit["uncertainty"]["expanded"]["Kxx"] > 2 * fit["std_errors"]["Kxx"]
    assert isinstance(fit["warnings"], list) and isinstance(fit["notes"], list) and fit["chi2"] > 0
    assert fit["lms_consistency"]["pair"] == "piezo - strain"
    dep = rows[("strain", "kc7", "power:1")]
    assert dep["adequacy"]["verdict"].startswith("frequency dependence supported: ")
    assert {(a["lms"], a["freq_dep"]) for a in res["adequacy"]} == {("piezo", "power:1"), ("strain", "power:1")}
    assert "too few orbit frequencies" in rows[("piezo", "kcd12", "poly:4")]["error"]
    assert [(r["lms"], r["model"]) for r in res["refused"]] == [("piezo", "kcd12"), ("strain", "kcd12")]
    assert isinstance(res["warnings"], list)
    # the warnings grouped per fit family: in each result (the run so far) and in the closing idle status,
    # the one idle status of the run (sent once its closing summary is read from the stored run)
    assert isinstance(res["warning_groups"], list)
    assert bool(res["warnings"]) == bool(res["warning_groups"])  # (the fits of one point may all pass)
    assert all(re.fullmatch(r".+, .+: .+ at 1 of 1 points \(0000\).*", g) for g in res["warning_groups"])
    assert idle["message"] == "run completed" + "".join(f"; warning: {g}" for g in res["warning_groups"])
    assert [m.json()["state"] for m in rig.watch.on("status", mark)].count("idle") == 1


# -- the broker and the service go away -----------------------------------------


class OwnRun:
    """A broker and a `serve --sim --confirm auto` of the test's own (the password
    from the environment), with the 'long' matrix running and acquiring."""

    def __init__(self, tmp_path: Path, *args: str):
        self.broker = Broker(tmp_path / "broker")
        self.broker.start()
        env = {"ORBITRIG_MQTT_PASSWORD": ACCOUNTS["orbitrig-service"]}
        self.svc = Service(
            sim_service_args(self.broker.url, RIG, tmp_path, "--confirm", "auto", *args), tmp_path, env=env
        )
        self.rc = RigClient(self.broker, RIG, self.svc)

    def __enter__(self) -> "OwnRun":
        try:
            self.rc.ready()
            assert self.rc.command({"cmd": "start", "matrix": "long"})["ok"] is True
            self.run_id = self.rc.status("running")["run_id"]
            self.rc.watch.wait_for(lambda m: m.topic.endswith("/progress") and m.json()["revolutions"] > 0, 30)
        except BaseException:
            self.__exit__()
            raise
        return self

    def __exit__(self, *exc) -> None:
        self.rc.close()
        self.svc.kill()
        self.broker.stop()


def test_a_second_signal_while_stopping_aborts(tmp_path):
    with OwnRun(tmp_path, "--speedup", "1") as own:  # a ramp of about two seconds: room for a busy host
        log = next(p for p in (tmp_path / "runs").glob("*/run.log") if own.run_id in p.read_text())
        own.svc.proc.send_signal(signal.SIGTERM)
        deadline = time.monotonic() + 20
        while "[stopping] the service shutting down" not in log.read_text():
            assert time.monotonic() < deadline, log.read_text()
            time.sleep(0.005)
        own.svc.kill(signal.SIGINT)
        assert own.svc.proc.returncode == 0, own.svc.text()[-3000:]
        assert run_status(tmp_path, own.run_id) == "aborted"
        assert "drives: emergency stop (OFF3)" in log.read_text()  # before or during the ramp


def test_broker_restart_mid_run_and_the_run_completes(tmp_path):
    with OwnRun(tmp_path) as own:
        own.rc.close()
        own.broker.stop()
        time.sleep(1.0)
        own.broker.start()
        own.rc = rc = RigClient(own.broker, RIG, own.svc)
        again = rc.status(lambda s: s["run_id"] == own.run_id, timeout=30)  # republished on reconnect
        assert again["state"] in ("running", "paused", "stopping", "idle")
        idle = rc.status("idle", timeout=90)
        assert idle["run_id"] == own.run_id and "completed" in idle["message"], idle
        assert run_status(tmp_path, own.run_id) == "completed"
        assert [m.json()["run_id"] for m in rc.watch.on("result")] == [own.run_id]
        assert "connection to 127.0.0.1" in own.svc.text() and "lost" in own.svc.text()


def test_sigkill_publishes_offline_last_will(tmp_path):
    with OwnRun(tmp_path) as own:
        mark = own.rc.watch.mark()
        own.svc.kill(signal.SIGKILL)
        offline = own.rc.status("offline", start=mark, timeout=10)
        # the will is registered at connection time, before this run started
        assert offline["run_id"] is None and "connection to the rig service lost" in offline["message"]
        late = retained(own.broker, f"orbitrig/{RIG}/status")
        assert late.retain and late.json()["state"] == "offline"


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT], ids=["SIGTERM", "SIGHUP", "SIGQUIT"])
def test_sigterm_mid_run_stops_with_a_ramp_and_says_offline(tmp_path, sig):
    with OwnRun(tmp_path) as own:
        mark = own.rc.watch.mark()
        own.svc.kill(sig)
        assert own.svc.proc.returncode == 0, own.svc.text()[-3000:]
        own.rc.status("offline", 10, mark)  # acknowledged by the broker; the watcher may see it later
        statuses = own.rc.watch.on("status", mark)
        states = [m.json()["state"] for m in statuses]
        assert states[-1] == "offline" and "stopping" in states and "idle" in states, states
        assert statuses[-1].json()["message"] == "service stopped"
        assert retained(own.broker, f"orbitrig/{RIG}/status").json()["state"] == "offline"
        assert run_status(tmp_path, own.run_id) == "stopped"
        log = next(p for p in (tmp_path / "runs").glob("*/run.log") if own.run_id in p.read_text())
        log = log.read_text()
        assert "stopped at once by the service shutting down" in log
        assert "drives: ramp stop (OFF1); standstill after" in log


def test_ctrl_z_does_not_suspend_the_service_mid_run(tmp_path):
    """Ctrl-Z (SIGTSTP) at the service's terminal mid-run is refused with a warning: the service still
    takes commands from the broker (before, it was suspended: no abort taken, and the drives of a
    real rig turned unwatched until their comm-loss watchdog tripped them). SIGTERM still stops the
    run with a ramp."""
    with OwnRun(tmp_path) as own:
        own.svc.proc.send_signal(signal.SIGTSTP)
        try:
            refused = "Ctrl-Z ignored: orbitrig serve does not suspend while it commands the drives"
            asyncio.run(until(lambda: refused in own.svc.text(), 10, "the service's warning of the refused Ctrl-Z"))
            assert own.rc.command({"cmd": "status"}, timeout=5)["ok"] is True  # after the Ctrl-Z, taken
        finally:
            own.svc.proc.send_signal(signal.SIGCONT)  # `fg`, had it been suspended
        own.svc.kill(signal.SIGTERM)
        assert own.svc.proc.returncode == 0, own.svc.text()[-3000:]
        assert run_status(tmp_path, own.run_id) == "stopped"
        log = next(p for p in (tmp_path / "runs").glob("*/run.log") if own.run_id in p.read_text()).read_text()
        assert "drives: ramp stop (OFF1); standstill after" in log, log

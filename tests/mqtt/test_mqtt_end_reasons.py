"""A run of `orbitrig serve --sim` that the service or an operator ended says truthfully who asked
and why, in run.log, run.h5's status_message and /logs/commands, and in the closing status:
a loss of supervision (the broker killed), a second shutdown signal, an operator's stop. The
real service in a subprocess under a real mosquitto."""

from __future__ import annotations

import signal
import time
from pathlib import Path

import h5py
import pytest

from orbitrig.service.supervision import LOST
from support.mqtt_helpers import ACCOUNTS, Broker, RigClient, Service, sim_service_args

pytestmark = pytest.mark.timeout(180)

RIG = "reasons-rig"


class Serve:
    """A broker and `serve --sim --confirm auto` of the test's own, the 'long' matrix started by ada."""

    def __init__(self, tmp_path: Path, *args: str, speedup: float = 20):
        self.tmp = tmp_path
        self.broker = Broker(tmp_path / "broker")
        self.broker.start()
        env = {"ORBITRIG_MQTT_PASSWORD": ACCOUNTS["orbitrig-service"]}
        args = sim_service_args(self.broker.url, RIG, tmp_path, "--confirm", "auto", *args, speedup=speedup)
        self.svc = Service(args, tmp_path, env=env)
        self.rc = RigClient(self.broker, RIG, self.svc)

    def start_run(self) -> None:
        self.rc.ready()
        assert self.rc.command({"cmd": "start", "matrix": "long", "by": "ada"})["ok"] is True
        self.run_id = self.rc.status("running")["run_id"]
        self.rc.watch.wait_for(lambda m: m.topic.endswith("/progress") and m.json()["revolutions"] > 0, 30)
        self.run_dir = next(p.parent for p in (self.tmp / "runs").glob("*/run.log") if self.run_id in p.read_text())

    def log(self) -> str:
        return (self.run_dir / "run.log").read_text()

    def wait_log(self, what: str, timeout: float = 60.0) -> str:
        deadline = time.monotonic() + timeout
        while what not in (text := self.log()):
            assert time.monotonic() < deadline, f"no {what!r} in run.log:\n{text[-3000:]}\n{self.svc.text()[-3000:]}"
            time.sleep(0.01)
        return text

    def stored(self) -> tuple[str, str, list[tuple[str, str, str]]]:
        """run.h5's status, status_message and /logs/commands (command, by, detail)."""
        with h5py.File(self.run_dir / "run.h5", "r") as f:
            rows = [(c["command"].decode(), c["by"].decode(), c["detail"].decode()) for c in f["logs/commands"][()]]
            return str(f.attrs["status"]), str(f.attrs["status_message"]), rows

    def close(self) -> None:
        self.rc.close()
        self.svc.kill()
        self.broker.stop()


@pytest.fixture
def serve(tmp_path):
    made: list[Serve] = []

    def make(*args: str, speedup: float = 20) -> Serve:
        made.append(Serve(tmp_path, *args, speedup=speedup))
        return made[-1]

    yield make
    for s in made:
        s.close()


def test_a_stop_after_the_loss_of_supervision_names_the_service(serve):
    s = serve("--supervision-timeout", "1", "--supervision-policy", "stop", speedup=5)
    s.start_run()
    s.rc.close()
    s.broker.proc.kill()  # kill -9: the broker is gone, the service cannot say goodbye
    s.broker.proc.wait()
    log = s.wait_log(f"run {s.run_id} ended:", timeout=90)
    why = f"stopped by {LOST}"
    assert f"command stop by {LOST}" in log
    assert f"ended: stopped: {why}" in log and "by the operator" not in log, log[-3000:]
    status, message, commands = s.stored()
    assert status == "stopped" and message.startswith(why), message
    assert ("stop", LOST, "") in commands and not [c for c in commands if c[0] == "stop" and c[1] != LOST], commands
    # the broker back: the closing status (retained, republished) says who stopped the run
    s.broker = Broker(s.tmp / "broker", port=s.broker.port)
    s.broker.start()
    s.rc = RigClient(s.broker, RIG, s.svc)
    idle = s.rc.status(lambda st: st["run_id"] == s.run_id and st["state"] == "idle", timeout=60)
    assert idle["message"].startswith(f"run stopped: {why}"), idle


def test_a_second_shutdown_signal_is_an_abort_by_the_service(serve):
    s = serve(speedup=1)  # a ramp of about two seconds: room for a busy host
    s.start_run()
    s.svc.proc.send_signal(signal.SIGTERM)
    s.wait_log("[stopping] the service shutting down")
    s.svc.kill(signal.SIGTERM)  # the second signal, during the closing ramp
    assert s.svc.proc.returncode == 0, s.svc.text()[-3000:]
    sender = "service (SIGTERM; a second signal while shutting down)"
    status, message, commands = s.stored()
    assert status == "aborted", message
    assert message.startswith(f"aborted by {sender}"), message
    assert "stopped at once by the service shutting down on SIGTERM" in message, message
    assert commands[-1] == ("abort", sender, ""), commands
    log = s.log()
    assert f"command abort by {sender}" in log and "by unnamed" not in log and "by the operator" not in log, log


def test_an_operators_stop_names_the_operator(serve):
    s = serve()
    s.start_run()
    mark = s.rc.watch.mark()
    assert s.rc.command({"cmd": "stop", "by": "grace"})["ok"] is True
    idle = s.rc.status("idle", timeout=60, start=mark)
    assert idle["message"].startswith("run stopped: stopped by grace"), idle
    status, message, commands = s.stored()
    assert status == "stopped" and message.startswith("stopped by grace"), message
    assert commands[-1] == ("stop", "grace", ""), commands
    assert "[stopping] stop requested by grace: finishing the current orbit frequency" in s.log()

"""The first signal to `orbitrig serve` with no run active is an abort no run carries out: both
drives get the emergency stop (OFF3) over the service's own link before it leaves, the log says
what was sent, and serve exits 1 when the drives could not be reached.

Real parts: `orbitrig serve` as a subprocess (no --sim: the simulator of --sim ends with it, so
its drives could not be read after serve's exit), `orbitrig sim` in a process of its own (drives
over Modbus TCP, turned from their keypads through its control API), mosquitto with the shipped
ACL and accounts."""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import time

import pytest

from drives import registers as R
from support.cli_helpers import orbitrig_started, reaped
from support.mqtt_helpers import ACCOUNTS, RigClient, Service, write_matrices
from support.rig_configs import lab_record_config
from support.sim_drive_helpers import sim_control as control

pytestmark = pytest.mark.timeout(240)


@pytest.fixture
def sim_process(tmp_path):
    """`orbitrig sim` in its own process: its announced endpoints."""
    with open(tmp_path / "sim.log", "wb") as log:
        sim = orbitrig_started("sim", "--modbus-port", "0", "--adc-port", "0", "--speedup", "20", stderr=log)
    with reaped(sim, signal.SIGTERM):
        line = sim.stdout.readline()
        assert line, (tmp_path / "sim.log").read_text()
        yield json.loads(line)


def serve(broker, tmp_path, rig_id: str, modbus_url: str) -> Service:
    config = lab_record_config(tmp_path / "lab", edits={"modbus_url": f'modbus_url = "{modbus_url}"'})
    args = ["--config", str(config), "--broker", broker.url, "--rig-id", rig_id, "--username", "orbitrig-service"]
    args += ["--matrices", str(write_matrices(tmp_path / "matrices")), "--out", str(tmp_path / "runs")]
    return Service(args, tmp_path, env={"ORBITRIG_MQTT_PASSWORD": ACCOUNTS["orbitrig-service"]})


def until(condition, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f"not within {timeout} s: {what}"
        time.sleep(0.1)


def sigterm(svc: Service) -> int:
    svc.proc.send_signal(signal.SIGTERM)
    try:
        return svc.proc.wait(60)
    except subprocess.TimeoutExpired:
        svc.kill()
        raise AssertionError("serve did not end within 60 s of SIGTERM:\n" + svc.text()[-3000:]) from None


def test_sigterm_with_no_run_stops_drives_left_turning(broker, tmp_path, sim_process):
    ep = sim_process
    svc = serve(broker, tmp_path, "sig-idle", ep["modbus"])
    rc = RigClient(broker, "sig-idle", svc)
    try:
        rc.status("idle", timeout=60)
        control(ep, cmd="local_control", spin=50.0, orbit=-30.0, hand_back=True)  # turned from the keypads, no run
        until(lambda: min(abs(control(ep, cmd="state")[k]) for k in ("spin", "orbit")) > 10.0, 30, "drives turning")
        t_signal = time.monotonic()
        status = sigterm(svc)
    finally:
        rc.close()
        svc.kill()
    assert status == 0, svc.text()[-3000:]
    drives = control(ep, cmd="drives")["drives"]
    for device in ("1", "2"):
        words = [cw for t, cw in drives[device]["control_words"] if t >= t_signal]
        assert R.CW_EMERGENCY_STOP in words, (device, [hex(w) for w in words], svc.text()[-3000:])
    until(lambda: control(ep, cmd="state")["spin"] == 0 and control(ep, cmd="state")["orbit"] == 0, 30, "standstill")
    text = svc.text()
    assert "abort (SIGTERM with no run active): emergency stop (OFF3) sent to both drives" in text, text[-3000:]
    assert outcome_lines(text) == 1, text[-3000:]  # one stop, logged once
    assert "abort (SIGTERM with no run active): no run holds the drives: emergency stop (OFF3) to both" in text


def outcome_lines(text: str) -> int:
    """The service's log lines that say how the drives' stop went (sent, or not)."""
    service = [ln.lower() for ln in text.splitlines() if "orbitrig.service.rig_service:" in ln]
    return sum("sent to both drives" in ln or "not sent" in ln for ln in service)


def test_sigterm_with_no_run_and_the_drives_unreachable_exits_1(broker, tmp_path):
    with socket.socket() as closed:  # a port nobody listens on
        closed.bind(("127.0.0.1", 0))
        url = f"tcp://127.0.0.1:{closed.getsockname()[1]}"
    svc = serve(broker, tmp_path, "sig-unreached", url)
    rc = RigClient(broker, "sig-unreached", svc)
    try:
        rc.status("idle", timeout=60)
        status = sigterm(svc)
    finally:
        rc.close()
        svc.kill()
    text = svc.text()
    assert status == 1, text[-3000:]
    assert "abort (SIGTERM with no run active): emergency stop NOT sent" in text, text[-3000:]
    assert "orbitrig serve: error: SIGTERM with no run active: emergency stop NOT sent" in text, text[-3000:]
    assert outcome_lines(text) == 1, text[-3000:]

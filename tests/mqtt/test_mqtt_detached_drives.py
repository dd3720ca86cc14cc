"""The service dies, the drives do not: `orbitrig serve` (no --sim) runs a
matrix on a simulator in ANOTHER process (`orbitrig sim`), is killed with
SIGKILL mid-run, the broker publishes its last will (`offline`), and both
drives ramp to zero on their own communication-loss watchdog (fault 7510),
read back over Modbus with pymodbus.

Cross-process CAN: python-can's `serial` interface over two ptys joined by
this test (the `virtual` bus lives inside one process)."""

from __future__ import annotations

import json
import os
import pty
import re
import select
import signal
import threading
import time
import tty

import pytest
from pymodbus.client import ModbusTcpClient

from support.cli_helpers import orbitrig_started, reaped
from support.mqtt_helpers import ACCOUNTS, REPO, Broker, RigClient, Service, write_matrices
from support.sim_drive_helpers import sim_control as control
from orbitrig.config import rig_from_text

FAULT_COMM_LOSS = 7510


class NullModem:
    """Two ptys joined back to back (a null-modem cable), relayed by a thread of
    this test process, which outlives the service under test."""

    def __init__(self):
        self._fds = []
        self.paths = []
        for _ in range(2):
            master, slave = pty.openpty()
            tty.setraw(slave)
            self._fds.append((master, slave))
            self.paths.append(os.ttyname(slave))
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._relay, daemon=True)
        self._thread.start()

    def _relay(self) -> None:
        (a, _), (b, _) = self._fds
        peer = {a: b, b: a}
        while not self._stop.is_set():
            ready, _, _ = select.select([a, b], [], [], 0.1)
            for fd in ready:
                try:
                    data = os.read(fd, 4096)
                except OSError:  # nobody has the other end open yet
                    continue
                try:
                    os.write(peer[fd], data)
                except OSError:
                    pass

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2)
        for pair in self._fds:
            for fd in pair:
                os.close(fd)


@pytest.fixture
def detached_sim(tmp_path):
    """`orbitrig sim` in its own process, its CAN node on one end of a null modem;
    yields its endpoints plus the rig's end of the CAN link."""
    cable = NullModem()
    try:
        with open(tmp_path / "sim.log", "wb") as log:
            sim = orbitrig_started(
                *("sim", "--modbus-port", "0", "--adc-port", "0", "--can-interface", "serial"),
                *("--can-channel", cable.paths[0], "--speedup", "20"),
                stderr=log,
            )
        with reaped(sim, signal.SIGTERM):
            line = sim.stdout.readline()
            assert line, (tmp_path / "sim.log").read_text()
            endpoints = json.loads(line)
            endpoints["can_rig_end"] = cable.paths[1]
            yield endpoints
    finally:
        cable.close()


def rig_config(endpoints: dict) -> str:
    text = (REPO / "config" / "rig.toml").read_text()
    for old, new in (  # a link a busy host holds (1 s requests, lost after 5 polls: 5.5 s); the watchdog 6 s
        ("timeout_s = 0.15", "timeout_s = 1.0"),
        ("link_loss_polls = 3", "link_loss_polls = 5"),
        ("comm_loss_timeout_s = 1.0", "comm_loss_timeout_s = 6.0"),
    ):
        assert old in text, old
        text = text.replace(old, new)
    for key, value in (
        ("modbus_url", endpoints["modbus"]),
        ("adc_url", endpoints["adc"]),
        ("can_channel", endpoints["can_rig_end"]),
        ("can_interface", "serial"),
    ):
        text, n = re.subn(rf'^{key} = "[^"]*"', f'{key} = "{value}"', text, flags=re.M)
        assert n == 1, key
    return text


def test_sigkill_offline_and_drives_stop_on_their_watchdog(detached_sim, tmp_path):
    ep = detached_sim
    text = rig_config(ep)
    rig_from_text(text)  # CAN over a serial adapter is a valid rig config
    (tmp_path / "rig.toml").write_text(text)

    b = Broker(tmp_path / "broker")
    b.start()
    svc = Service(
        [
            "--config",
            str(tmp_path / "rig.toml"),
            "--broker",
            b.url,
            "--rig-id",
            "detached",
            "--username",
            "orbitrig-service",
            "--matrices",
            str(write_matrices(tmp_path / "matrices")),
            "--out",
            str(tmp_path / "runs"),
        ],
        tmp_path,
        env={"ORBITRIG_MQTT_PASSWORD": ACCOUNTS["orbitrig-service"]},
    )
    rc = RigClient(b, "detached", svc)
    try:
        rc.ready()
        # the operator's hands: the matrix's manual settings on the rig
        control(
            ep,
            cmd="set_manual",
            orbit_radius=0.096 * 60e-6,
            static_eccentricity=0.0,
            recess_pressure=0.4826e6,
            pressure_ratio=0.4,
        )
        assert rc.command({"cmd": "start", "matrix": "long"})["ok"] is True
        assert "'manual:0000'" in rc.status("waiting")["message"]
        assert rc.command({"cmd": "confirm", "step": "manual:0000"})["ok"] is True
        deadline = time.monotonic() + 30
        while True:
            state = control(ep, cmd="state")
            if state["spin"] > 50 and abs(state["orbit"]) > 20:  # rad/s: both spindles turning
                break
            assert time.monotonic() < deadline, f"drives never ran: {state}\n{svc.text()[-2000:]}"
            time.sleep(0.1)

        mark = rc.watch.mark()
        svc.kill(signal.SIGKILL)
        t_kill = time.monotonic()
        offline = rc.status("offline", start=mark, timeout=10)
        assert offline["message"] == "connection to the rig service lost"

        # no Modbus traffic from here on until the drives have stopped (it would feed their watchdog)
        while True:
            state = control(ep, cmd="state")
            if state["spin"] == 0 and state["orbit"] == 0:
                break
            assert time.monotonic() - t_kill < 25, f"drives still turning: {state}"
            time.sleep(0.05)
        assert time.monotonic() - t_kill > 4.0  # not commanded: the 6 s watchdog (from the last poll) stopped them

        host, port = ep["modbus"].removeprefix("tcp://").split(":")
        client = ModbusTcpClient(host, port=int(port), timeout=2)
        assert client.connect()
        try:
            for device in (1, 2):
                regs = client.read_holding_registers(4, count=3, device_id=device).registers
                act, fault = regs[0], regs[2]  # ACT (int16), FAULT
                assert act == 0, (device, regs)
                assert fault == FAULT_COMM_LOSS, (device, regs)
        finally:
            client.close()
    finally:
        rc.close()
        svc.kill()
        b.stop()

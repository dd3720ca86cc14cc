"""A signal to `orbitrig serve --sim` while its simulator is still starting (before the service
exists): the start is cut short there, the simulator process ended, nothing else opened (no MQTT
session, no drive link: the simulator's drives had no client, nothing turns), the log says so, and
serve exits 0 at once. It went on starting: waited for the simulator, then brought the service up
(online, "service ready") after the signal, only to shut it down again.

Real parts: `orbitrig serve --sim` as a subprocess with its simulator process, mosquitto with the
shipped ACL and accounts. The signal is sent as soon as the simulator's process exists, well
before it announces its endpoints (importing and listening takes it a second or more)."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from support.mqtt_helpers import ACCOUNTS, RigClient, Service, sim_service_args

pytestmark = pytest.mark.timeout(120)

RIG = "sim-starting"


def simulator_child(pid: int) -> int | None:
    """The pid of the `python -m sim` child of process `pid`, if it has one now."""
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            cmdline = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        ppid = int(stat.rsplit(")", 1)[1].split()[1])
        if ppid == pid and b"-m" in cmdline and b"sim" in cmdline:
            return int(entry.name)
    return None


def gone(pid: int) -> bool:
    """Whether process `pid` has ended (gone, or a zombie nobody has reaped yet)."""
    try:
        return (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"
    except OSError:
        return True


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_a_signal_while_the_simulator_starts_ends_it_and_starts_nothing(broker, tmp_path, sig):
    rc = RigClient(broker, RIG)  # subscribed before the service could publish anything
    env = {"ORBITRIG_MQTT_PASSWORD": ACCOUNTS["orbitrig-service"]}
    svc = Service(sim_service_args(broker.url, RIG, tmp_path), tmp_path, env=env)
    try:
        deadline, child = time.monotonic() + 30, None
        while child is None:
            assert svc.proc.poll() is None and time.monotonic() < deadline, svc.text()[-3000:]
            child = simulator_child(svc.proc.pid)
            time.sleep(0.002)
        svc.proc.send_signal(sig)
        t0 = time.monotonic()
        try:
            code = svc.proc.wait(30)
        except subprocess.TimeoutExpired:
            raise AssertionError("serve did not end within 30 s:\n" + svc.text()[-3000:]) from None
        took = time.monotonic() - t0
        time.sleep(0.5)  # anything the service published would be here by now
        statuses = [m.json() for m in rc.watch.on("status")]
    finally:
        svc.kill()
        rc.close()
    said = svc.text()
    assert code == 0, said[-3000:]
    assert gone(child), f"the simulator process {child} still runs after serve's exit"
    assert statuses == [], f"the service came up after the signal: {statuses}"
    name = "Ctrl-C" if sig == signal.SIGINT else "SIGTERM"  # as orbitrig.cli.signals names them
    assert f"{name} before the service was up: not started" in said, said[-3000:]
    assert took < 10.0, f"serve took {took:.1f} s to end"
    assert not os.path.exists(tmp_path / "runs") or not any((tmp_path / "runs").iterdir())

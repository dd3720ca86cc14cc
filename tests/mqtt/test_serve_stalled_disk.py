"""`orbitrig serve` whose run's disk never returns: a shutdown signal stops both drives first, the
run then says (status, over MQTT) that it waits for its storage; a second signal once a write has
not returned for DISK_STALL_S, or the end of
the service's whole wait for the run, ends the process (exit 1) with what was not written, in its
log and its offline status; every file written before is kept.

Real parts: mosquitto with the shipped ACL and accounts, `orbitrig serve --sim` as a process (the
simulator's drives over Modbus TCP), real signals. Injected (a disk that never returns cannot be
produced by the real parts): the block writes hang once the test creates a flag file; for the
first-signal case the service's allowance for recording a run's end (RECORD_END_S, 120 s) is 2 s.
"""

from __future__ import annotations

import signal
import time
from pathlib import Path

import h5py
import pytest

from orbitrig.run.closing import DISK_STALL_S
from support.mqtt_helpers import ACCOUNTS, Broker, RigClient, Service, retained, run_dirs, sim_service_args
from support.stalled_disk import stalling_env

pytestmark = pytest.mark.timeout(240)

RIG = "stall"


def _serve_stalling(tmp_path: Path, broker: Broker, **env: str) -> tuple[Service, RigClient, Path]:
    stalling, flag = stalling_env(tmp_path, **env)
    env = {"ORBITRIG_MQTT_PASSWORD": ACCOUNTS["orbitrig-service"], **stalling}
    svc = Service(sim_service_args(broker.url, RIG, tmp_path, "--confirm", "auto"), tmp_path, env=env)
    return svc, RigClient(broker, RIG, svc), flag


def _stall_mid_run(rc: RigClient, flag: Path, runs: Path) -> str:
    """The 'long' run started; the disk stalls once its first two blocks are written (a block's
    write waits for the next ramp), one more block is measured."""
    rc.ready()
    assert rc.command({"cmd": "start", "matrix": "long"})["ok"] is True
    run_id = rc.status("running")["run_id"]

    def at(frequency: int):
        return lambda m: m.topic.endswith("/progress") and m.json()["frequency"] >= frequency

    rc.watch.wait_for(at(3), 60)
    deadline = time.monotonic() + 60
    while len(list(runs.glob("*/points/0000/*.h5"))) < 2:
        assert time.monotonic() < deadline, "two blocks not written in 60 s"
        time.sleep(0.01)
    flag.touch()
    rc.watch.wait_for(at(5), 60)  # its block's write hangs
    return run_id


def _waiting_for_storage(rc: RigClient, mark: int) -> dict:
    status = rc.status(lambda s: "waiting for the storage in flight" in (s.get("message") or ""), 60, mark)
    assert status["state"] == "stopping", status
    assert status["message"].startswith("drives: ramp stop (OFF1); standstill after"), status
    return status


def _check_left(tmp_path: Path, svc: Service, why: str, broker: Broker) -> None:
    text = svc.text()
    words = f"left without waiting for the disk ({why}), after the drives' closing stop"
    assert f"orbitrig serve: error: {words}" in text, text[-3000:]
    assert "not written: store 0000/" in text and "the run's end (its status, run.h5)" in text, text[-3000:]
    offline = retained(broker, f"orbitrig/{RIG}/status")
    assert offline is not None and offline.json()["state"] == "offline", offline
    assert words in offline.json()["message"], offline.json()
    (run,) = run_dirs(tmp_path / "runs")
    blocks = sorted((run / "points" / "0000").glob("*.h5"))
    assert len(blocks) >= 2, blocks  # written before the stall: kept, whole
    for block in blocks:
        with h5py.File(block, "r") as f:
            assert len(f.keys()) > 0
    assert "drives: ramp stop (OFF1); standstill after" in (run / "run.log").read_text()


def test_a_second_signal_leaves_a_run_whose_disk_never_returns_once_its_drives_are_stopped(tmp_path):
    broker = Broker(tmp_path / "broker")
    broker.start()
    svc, rc, flag = _serve_stalling(tmp_path, broker)
    try:
        _stall_mid_run(rc, flag, tmp_path / "runs")
        mark = rc.watch.mark()
        svc.proc.send_signal(signal.SIGTERM)
        _waiting_for_storage(rc, mark)
        time.sleep(DISK_STALL_S)  # a write stalled that long: the run waits for a disk that stalls
        assert svc.proc.poll() is None  # still waiting: the first signal's wait is the service's whole one
        t = time.monotonic()
        svc.proc.send_signal(signal.SIGTERM)
        assert svc.proc.wait(30) == 1, svc.text()[-3000:]
        assert time.monotonic() - t < 6.0  # 2 s of grace, the offline status, the exit
        _check_left(tmp_path, svc, "SIGTERM; a second signal", broker)
    finally:
        rc.close()
        svc.kill()
        broker.stop()


def test_one_signal_leaves_a_run_whose_disk_never_returns_after_the_services_whole_wait(tmp_path):
    broker = Broker(tmp_path / "broker")
    broker.start()
    svc, rc, flag = _serve_stalling(tmp_path, broker, ORBITRIG_TEST_RECORD_END_S="2")
    try:
        _stall_mid_run(rc, flag, tmp_path / "runs")
        mark = rc.watch.mark()
        svc.proc.send_signal(signal.SIGTERM)
        _waiting_for_storage(rc, mark)
        assert svc.proc.wait(90) == 1, svc.text()[-3000:]
        text = svc.text()
        assert "did not end within" in text  # the service's own wait, then its cut
        assert "its drives' closing stop was done" in text and "stop is not confirmed" not in text, text[-3000:]
        _check_left(tmp_path, svc, "SIGTERM: the run did not end within its wait", broker)
    finally:
        rc.close()
        svc.kill()
        broker.stop()

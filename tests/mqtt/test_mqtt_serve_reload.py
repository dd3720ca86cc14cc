"""`orbitrig serve` loads the rig configuration and its active calibration record again at
each start: a record made active while the service runs is the next run's; a configuration
that no longer loads refuses the start with its error."""

from __future__ import annotations

import json

from support.mqtt_helpers import ACCOUNTS, RigClient, Service, run_dirs, sim_service_args
from support.rig_configs import LAB_RECORD, lab_record_config, loads_record

RIG = "reload-rig"


def _provenance(work) -> list[dict]:
    runs = run_dirs(work / "runs")
    return [json.loads((run / "run.json").read_text())["provenance"] for run in runs]


def _run_quick(rc: RigClient) -> None:
    mark = rc.watch.mark()
    assert rc.command({"cmd": "start", "matrix": "quick"})["ok"] is True
    idle = rc.status("idle", start=mark, timeout=90)
    assert "completed" in idle["message"], idle


def test_each_start_loads_the_rig_configuration_again(broker, tmp_path):
    config = lab_record_config(tmp_path / "lab")
    first = next(ln for ln in config.read_text().splitlines() if ln.startswith("calibration_record"))
    args = sim_service_args(broker.url, RIG, tmp_path, "--confirm", "auto", "--config", str(config))
    svc = Service(args, tmp_path, env={"ORBITRIG_MQTT_PASSWORD": ACCOUNTS["orbitrig-service"]})
    try:
        rc = RigClient(broker, RIG, svc)
        try:
            rc.ready()
            _run_quick(rc)
            (config.parent / "calibration" / f"{LAB_RECORD}.toml").write_text(loads_record(0.98))
            config.write_text(config.read_text().replace(first, f'calibration_record = "{LAB_RECORD}"'))
            _run_quick(rc)
            config.write_text(config.read_text().replace(LAB_RECORD, "2026-12-31T000000Z-loads"))
            refused = rc.command({"cmd": "start", "matrix": "quick"})
        finally:
            rc.close()
    finally:
        assert svc.stop() == 0, svc.text()[-3000:]
    assert refused["ok"] is False and "the rig configuration does not load" in refused["error"], refused
    assert str(config) in refused["error"] and "no calibration record '2026-12-31T000000Z-loads'" in refused["error"]
    before, after = _provenance(tmp_path)
    assert f'"{before["calibration_record"]}"' in first and after["calibration_record"] == LAB_RECORD
    assert before["calibration_record_sha256"] != after["calibration_record_sha256"]
    assert f"calibration record {LAB_RECORD} (was {before['calibration_record']})" in svc.text()
    assert len(_provenance(tmp_path)) == 2  # the refused start made no run


def test_serve_sim_runs_on_the_node_its_rig_toml_reads_and_refuses_another_later(broker, tmp_path):
    """rig.toml reads CAN node 5: `serve --sim` starts the simulator as node 5 and a run completes on its
    heartbeat 0x705 (as node 1 the run failed after can_heartbeat_timeout_s); rig.toml reading node 1
    since, the next start is refused naming both (the simulator is still node 5), no run made."""
    config = lab_record_config(tmp_path / "lab")
    assert "can_node_id = 1\n" in config.read_text()
    config.write_text(config.read_text().replace("can_node_id = 1\n", "can_node_id = 5\n"))
    args = sim_service_args(broker.url, RIG, tmp_path, "--confirm", "auto", "--config", str(config))
    svc = Service(args, tmp_path, env={"ORBITRIG_MQTT_PASSWORD": ACCOUNTS["orbitrig-service"]})
    try:
        rc = RigClient(broker, RIG, svc)
        try:
            rc.ready()
            _run_quick(rc)
            config.write_text(config.read_text().replace("can_node_id = 5\n", "can_node_id = 1\n"))
            refused = rc.command({"cmd": "start", "matrix": "quick"})
        finally:
            rc.close()
    finally:
        assert svc.stop() == 0, svc.text()[-3000:]
    assert refused["ok"] is False, refused
    assert f"{config}: [transports] can_node_id 1: the simulator's CAN node is node 5" in refused["error"], refused
    assert len(_provenance(tmp_path)) == 1  # the refused start made no run

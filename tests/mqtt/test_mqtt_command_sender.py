"""Who changed the run: the optional "by" of every command (docs/protocols/mqtt.md), recorded with
its time in run.log and run.h5 (/logs/commands), the sender of `start` as the run's operator.
The real `orbitrig serve --sim` under the authenticated mosquitto of tests/mqtt."""

from __future__ import annotations

import h5py
import pytest

from support.mqtt_helpers import RigClient, sim_service
from orbitrig.service.protocol import CommandError, parse_command

RIG = "sender-rig"


def test_by_is_parsed_checked_and_never_blocks_a_stop():
    assert parse_command('{"cmd": "pause", "id": "a", "by": "bob"}').by == "bob"
    assert parse_command('{"cmd": "start", "id": "a", "matrix": "quick"}').by is None
    with pytest.raises(CommandError, match="64"):
        parse_command('{"cmd": "pause", "id": "a", "by": "' + "x" * 65 + '"}')
    stop = parse_command('{"cmd": "stop", "id": "a", "by": "carol", "stray": 1}')
    assert stop.cmd == "stop" and stop.by == "carol" and stop.ignored


def test_every_command_that_changed_the_run_is_logged_with_its_sender(broker, tmp_path):
    svc = sim_service(broker.url, RIG, tmp_path)
    rig = RigClient(broker, RIG, svc)
    try:
        rig.ready(lambda s: True)
        mark = rig.watch.mark()
        assert rig.command({"cmd": "start", "matrix": "long", "by": "alice"})["ok"] is True
        run_id = rig.status("waiting", start=mark)["run_id"]
        assert rig.command({"cmd": "confirm", "step": "manual:0000", "by": "bob"})["ok"] is True
        rig.status("running", start=mark)
        assert rig.command({"cmd": "pause", "by": "bob"})["ok"] is True
        rig.status("paused", start=mark)
        assert rig.command({"cmd": "resume"})["ok"] is True  # no "by": recorded as unnamed
        assert rig.command({"cmd": "stop", "by": "carol"})["ok"] is True
        rig.status(lambda s: s["state"] == "idle" and s["run_id"] == run_id, start=mark, timeout=60)
    finally:
        rig.close()
        assert svc.stop() == 0, svc.text()[-3000:]
    (run,) = [p.parent for p in (tmp_path / "runs").glob("*/run.h5")]
    want = [("start", "alice"), ("confirm", "bob"), ("pause", "bob"), ("resume", "unnamed"), ("stop", "carol")]
    with h5py.File(run / "run.h5") as f:
        rows = f["logs/commands"][()]
        assert [(r["command"].decode(), r["by"].decode()) for r in rows] == want
        at = [r["at"].decode() for r in rows]
        assert at == sorted(at) and all(t.endswith("Z") for t in at)
        assert f.attrs["operator"] == "alice" and f.attrs["status"] == "stopped"
        assert f.attrs["started"] <= at[0] and f.attrs["ended"] >= at[-1]
    log = (run / "run.log").read_text()
    for command, by in want:
        assert f"command {command} by {by}" in log

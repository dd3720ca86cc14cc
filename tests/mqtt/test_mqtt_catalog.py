"""`orbitrig serve --catalog URL`: each completed point lands in the campaign catalog; a
catalog that cannot be written is logged and the run completes all the same; a URL of no
database the catalog supports is refused at the start (exit 2), not found point by point."""

from __future__ import annotations

import time

import pytest

from support.cli_helpers import orbitrig
from support.mqtt_helpers import ACCOUNTS, RigClient, Service, sim_service_args
from orbitrig.catalog.store import Catalog
from orbitrig.store.reader import read_run

RIG = "cat-rig"


def _serve(broker, work, catalog_url):
    args = sim_service_args(broker.url, RIG, work, "--confirm", "auto", "--catalog", catalog_url)
    return Service(args, work, env={"ORBITRIG_MQTT_PASSWORD": ACCOUNTS["orbitrig-service"]})


def _run_quick(broker, svc) -> None:
    rc = RigClient(broker, RIG, svc)
    try:
        rc.status("idle", timeout=30)
        mark = rc.watch.mark()
        assert rc.command({"cmd": "start", "matrix": "quick"})["ok"] is True
        idle = rc.status("idle", start=mark, timeout=90)
        assert "completed" in idle["message"], idle
    finally:
        rc.close()


@pytest.mark.parametrize("writable", [True, False])
def test_completed_points_land_in_the_catalog(broker, tmp_path, writable):
    url = f"sqlite:///{tmp_path / ('catalog.sqlite' if writable else 'missing/dir/catalog.sqlite')}"
    svc = _serve(broker, tmp_path, url)
    try:
        _run_quick(broker, svc)
        deadline = time.monotonic() + 30
        while writable and time.monotonic() < deadline and "added (run completed)" not in svc.text():
            time.sleep(0.2)  # the run's end, added when its task has finished
    finally:
        assert svc.stop() == 0, svc.text()[-3000:]
    if not writable:
        assert "not added" in svc.text()  # logged; the run completed all the same
        return
    rows = Catalog(url).rows()
    run_dir = next((tmp_path / "runs").iterdir())
    assert {(r["point"], r["lms"], r["model"]) for r in rows} == {(0, "piezo", "kc7"), (0, "strain", "kc7")}
    assert all(r["run_path"] == str(run_dir.resolve()) and r["Kxx_U"] > 0 for r in rows)
    ended = read_run(run_dir).provenance["ended"]
    assert ended and {(r["run_status"], r["ended"]) for r in rows} == {("completed", ended)}  # not left 'running'


@pytest.mark.parametrize(
    "url, says",
    [
        ("mysql://alice@db.lab/fits", "--catalog mysql://alice@db.lab/fits: database 'mysql' is not supported"),
        ("catalog.sqlite", "--catalog catalog.sqlite: not a database URL"),
    ],
)
def test_a_catalog_url_of_no_supported_database_exits_2_at_the_start(tmp_path, url, says):
    """Checked before the broker is reached: no broker serves this port."""
    args = ("serve", "--sim", "--broker", "mqtt://127.0.0.1:1", "--out", str(tmp_path / "runs"), "--catalog", url)
    p = orbitrig(*args, timeout=60)
    assert p.returncode == 2, p.stderr
    assert f"orbitrig serve: {says}" in p.stderr and "Traceback" not in p.stderr
    assert not (tmp_path / "runs").exists()

"""`orbitrig serve --catalog URL`: each completed point lands in the campaign catalog; a
catalog that cannot be written is logged and the run completes all the same; a URL of no
database the catalog supports is refused at the start (exit 2), not found point by point.

A catalog that does not answer (its table locked by another client: a VACUUM FULL, a migration
left open) holds the feed's own thread only: the service reconnects to its broker and carries out
an abort as ever, the points are added once the lock is gone, and a signal ends the service
naming the runs it did not add (real parts: a PostgreSQL server and a client of its own holding
the lock, mosquitto, the simulator)."""

from __future__ import annotations

import asyncio
import contextlib
import signal
import time

import psycopg
import pytest

from support.cli_helpers import orbitrig
from support.mqtt_helpers import ACCOUNTS, CutProxy, RigClient, Service, run_dirs, sim_service_args, wait
from support.polling import until
from support.report_synthetic import write_synthetic_run
from orbitrig.catalog.store import Catalog
from orbitrig.service.catalog_feed import FINISH_S
from orbitrig.store.reader import read_run
from test_mqtt_abort_always_sent import emergency_stopped, publish_abort, serving

RIG = "cat-rig"
#: completed points handed to a feed whose catalog does not answer: more than the event loop's
#: worker threads ever are (concurrent.futures: at most 32)
POINTS = 40


def _serve(broker, work, catalog_url):
    args = sim_service_args(broker.url, RIG, work, "--confirm", "auto", "--catalog", catalog_url)
    return Service(args, work, env={"ORBITRIG_MQTT_PASSWORD": ACCOUNTS["orbitrig-service"]})


def _run_quick(broker, svc) -> None:
    rc = RigClient(broker, RIG, svc)
    try:
        rc.ready()
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
    (run_dir,) = run_dirs(tmp_path / "runs")
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
    assert f"orbitrig serve: error: {says}" in p.stderr and "Traceback" not in p.stderr
    assert not (tmp_path / "runs").exists()


@contextlib.contextmanager
def locked_catalog(url: str):
    """The catalog at ``url`` made, its table then locked by a client of its own (the connection,
    whose rollback lets go of it): nothing can be added until then."""
    Catalog(url)
    with psycopg.connect(url) as held:
        held.execute("LOCK TABLE fits IN ACCESS EXCLUSIVE MODE")
        yield held


async def test_a_catalog_that_does_not_answer_holds_back_no_abort_after_the_broker_returns(
    broker, tmp_path, postgres_server
):
    url, run_dir = postgres_server, write_synthetic_run(tmp_path / "earlier" / "run1", incomplete=0)
    proxy = CutProxy(broker.port)
    try:
        with locked_catalog(url) as held:
            async with serving(broker, tmp_path, "stalled-cat", url=proxy.url, catalog_url=url) as (svc, sim_rig, rc):
                for _ in range(POINTS):  # a campaign's points completed while the catalog is locked
                    svc._catalog.point_completed(run_dir, 0)
                before = svc.link.connections
                proxy.cut()
                await until(lambda: not svc.link.online.is_set(), 30, "the service sees its link drop")
                proxy.restore()
                await until(lambda: svc.link.connections > before and svc.abort_link.up, 30, "both links back")
                sim_rig.local_control(spin=50.0, orbit=-30.0, hand_back=True)
                await until(lambda: min(abs(w) for w in sim_rig.speeds) > 10.0, 30, "both drives turning")
                t_abort = time.monotonic()
                mark = await wait(publish_abort, rc, "after-return")
                emergency_stopped(await wait(rc.reply, "after-return", 15, mark), sim_rig, t_abort)
                held.rollback()  # the lock let go: what waited is added
                assert await asyncio.to_thread(svc._catalog.finish, 60) == []
                assert svc._catalog.failed == 0
        assert str(run_dir.resolve()) in {r["run_path"] for r in Catalog(url).rows()}
    finally:
        proxy.close()


def test_a_signal_ends_the_service_whose_catalog_does_not_answer_naming_the_run_not_added(
    broker, tmp_path, postgres_server
):
    with locked_catalog(postgres_server):
        svc = _serve(broker, tmp_path, postgres_server)
        try:
            _run_quick(broker, svc)
            (run_dir,) = run_dirs(tmp_path / "runs")
            t0 = time.monotonic()
            svc.proc.send_signal(signal.SIGTERM)
            code = svc.proc.wait(FINISH_S + 30)
            assert code == 0 and time.monotonic() - t0 < FINISH_S + 30, svc.text()[-3000:]
        finally:
            svc.kill()
    assert f"did not answer within {FINISH_S:.0f} s: not added: {run_dir}" in svc.text(), svc.text()[-3000:]

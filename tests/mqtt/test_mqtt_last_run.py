"""A restarted service says how the last run ended: the real `orbitrig serve --sim` under a real,
authenticated mosquitto, stopped and started again on the same runs folder; its `service ready`
status carries `last_run`, read from the store (run.json's id, the journal's last status line)."""

from __future__ import annotations

import asyncio
import json
import os
import re
import signal
import time
from pathlib import Path

import pytest

from orbitrig.service.last_run import read_last_run_within
from orbitrig.store.errors import RunDirError

from support.mqtt_helpers import RigClient, retained, sim_service

RIG = "last-run-rig"
#: the house timestamp (rigunits.utc_iso)
STAMP = re.compile(r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z$")


def stored_status(folder: Path) -> dict:
    """The journal's last status line: what the store recorded of the run's end."""
    lines = [json.loads(t) for t in (folder / "journal.jsonl").read_text().splitlines() if t.strip()]
    return [r for r in lines if r["k"] == "status"][-1]


def ready(broker, svc) -> tuple[RigClient, dict]:
    rc = RigClient(broker, RIG, svc)
    return rc, rc.ready(lambda s: s["message"] == "service ready")


def test_a_restarted_service_says_how_the_last_run_ended(broker, tmp_path):
    svc = sim_service(broker.url, RIG, tmp_path)
    rc = None
    try:
        rc, first = ready(broker, svc)
        assert (first["state"], first["run_id"], first["last_run"]) == ("idle", None, None)  # no run stored yet
        mark = rc.watch.mark()
        assert rc.command({"cmd": "start", "matrix": "quick", "by": "ada"})["ok"] is True
        run_id = rc.status("waiting", start=mark)["run_id"]
        assert rc.command({"cmd": "abort", "by": "ada"})["ok"] is True
        idle = rc.status("idle", start=mark, timeout=30)
        assert idle["run_id"] == run_id and idle["message"].startswith("run aborted")
        rc.close()
        rc = None
        assert svc.stop() == 0, svc.text()[-3000:]

        svc = sim_service(broker.url, RIG, tmp_path)  # the same runs folder
        rc, again = ready(broker, svc)
        folder = Path(idle["folder"])
        stored = stored_status(folder)
        assert (again["state"], again["run_id"]) == ("idle", None)  # no run of this service yet
        assert again["last_run"] == {
            "run_id": run_id,
            "outcome": "aborted",
            "message": stored["message"],
            "folder": idle["folder"],
            "ended_at": stored["at"],
        }
        assert "ada" in stored["message"] and STAMP.match(stored["at"])
        late = retained(broker, f"orbitrig/{RIG}/status")  # a subscriber that comes later
        assert late is not None and late.json()["last_run"]["run_id"] == run_id
    finally:
        if rc is not None:
            rc.close()
        svc.stop()


def test_a_run_the_store_still_says_running_is_said_so_with_no_end(broker, tmp_path):
    """A service killed during a run leaves its stored status `running`: said as stored, no end time."""
    svc = sim_service(broker.url, RIG, tmp_path)
    rc = None
    try:
        rc, _ = ready(broker, svc)
        mark = rc.watch.mark()
        assert rc.command({"cmd": "start", "matrix": "quick"})["ok"] is True
        waiting = rc.status("waiting", start=mark)
        rc.close()
        rc = None
        svc.kill(signal.SIGKILL)

        svc = sim_service(broker.url, RIG, tmp_path)
        rc, again = ready(broker, svc)
        assert stored_status(Path(waiting["folder"]))["status"] == "running"
        last = again["last_run"]
        assert (last["run_id"], last["outcome"], last["folder"], last["ended_at"]) == (
            waiting["run_id"],
            "running",
            waiting["folder"],
            None,
        )
    finally:
        if rc is not None:
            rc.close()
        svc.stop()


def test_a_runs_folder_that_does_not_answer_holds_the_start_for_a_bounded_time(tmp_path):
    """A journal that never returns its bytes (a FIFO with no writer, as a share that hangs):
    the read is given up after its bound, and the thread left reading ends when the bytes come."""
    run = tmp_path / "runs" / "20261206T010000.000Z-demo"
    run.mkdir(parents=True)
    (run / "run.json").write_text("{}")
    os.mkfifo(run / "journal.jsonl")
    t0 = time.monotonic()
    with pytest.raises(TimeoutError):
        asyncio.run(read_last_run_within(tmp_path / "runs", 0.5))
    assert 0.5 <= time.monotonic() - t0 < 3
    with open(run / "journal.jsonl", "w"):  # the reader blocked in open() gets an empty journal and ends
        pass


def test_of_two_runs_ended_within_one_tick_of_the_file_clock_the_later_ended_is_the_last_run(tmp_path):
    """Two journals of the same modification time (a runs folder on a share that keeps whole
    seconds: two runs ended within the second): the run whose end was recorded later is the last
    run, whichever folder the listing gives first (it took the first: the earlier run, in one of
    these two orders)."""
    from orbitrig import config as cfg
    from orbitrig.service.last_run import read_last_run
    from orbitrig.store.status import RunStatus
    from orbitrig.store.writer import RunStore

    from support.store_checks import small_matrix

    rig, mat = cfg.load_rig(), cfg.matrix_from_text(small_matrix("tick", 8), "tick.toml")
    for later in ("20261206T010000.000Z-demo", "20261206T010000.400Z-demo"):
        runs = tmp_path / later
        stores = {
            name: RunStore.create(
                runs / name, rig_text=rig.text, matrix_text=mat.run_text, matrix_name=mat.name, sim=True
            )
            for name in ("20261206T010000.000Z-demo", "20261206T010000.400Z-demo")
        }
        (earlier,) = set(stores) - {later}
        stores[earlier].set_status(RunStatus.STOPPED, "stopped by ada")
        time.sleep(0.01)  # the later end is recorded 10 ms later, within the same second
        stores[later].set_status(RunStatus.ABORTED, "aborted by bob")
        tick = (runs / later / "journal.jsonl").stat().st_mtime_ns // 10**9 * 10**9
        for name in stores:
            os.utime(runs / name / "journal.jsonl", ns=(tick, tick))
        last = read_last_run(runs)
        assert last is not None and last.folder == (runs / later).resolve(), (later, last)
        assert (last.outcome, last.message) == (RunStatus.ABORTED, "aborted by bob")


def test_a_damaged_journal_among_tied_ones_is_left_out_naming_its_file_and_line(tmp_path, caplog):
    """Three journals of the same modification time, the one whose end was recorded last damaged
    (an event's time written as a 400-digit integer on its line 3): it is left out with a warning
    naming the file and the line, and the last run is the later of the other two (the read failed)."""
    from orbitrig import config as cfg
    from orbitrig.service.last_run import read_last_run
    from orbitrig.store.status import RunStatus
    from orbitrig.store.writer import RunStore

    from support.store_checks import small_matrix

    rig, mat = cfg.load_rig(), cfg.matrix_from_text(small_matrix("tick", 8), "tick.toml")
    runs, names = tmp_path / "runs", ("a-demo", "b-demo", "c-demo")
    for name, (status, message) in zip(
        names, [(RunStatus.STOPPED, "stopped by ada"), (RunStatus.ABORTED, "aborted by bob"), (RunStatus.COMPLETED, "")]
    ):
        store = RunStore.create(
            runs / name, rig_text=rig.text, matrix_text=mat.run_text, matrix_name=mat.name, sim=True
        )
        store.set_status(status, message)
        time.sleep(0.01)  # each end recorded after the one before
    damaged = runs / "c-demo" / "journal.jsonl"
    lines = damaged.read_text().splitlines(keepends=True)
    bad = '{"k": "event", "t": ' + "9" * 400 + ', "state": "running", "message": "m"}\n'
    damaged.write_text("".join(lines[:2] + [bad] + lines[2:]))
    tick = damaged.stat().st_mtime_ns // 10**9 * 10**9
    for name in names:
        os.utime(runs / name / "journal.jsonl", ns=(tick, tick))
    with caplog.at_level("WARNING", logger="orbitrig.service.last_run"):
        last = read_last_run(runs)
    assert last is not None and last.folder == (runs / "b-demo").resolve()
    assert (last.outcome, last.message) == (RunStatus.ABORTED, "aborted by bob")
    (said,) = [r.getMessage() for r in caplog.records if r.name == "orbitrig.service.last_run"]
    assert f"{damaged}: line 3: " in said and "left out" in said
    os.utime(runs / "c-demo" / "journal.jsonl", ns=(tick + 10**9, tick + 10**9))  # the damaged one alone newest
    with pytest.raises(RunDirError, match=r"c-demo/journal.jsonl: line 3: "):
        read_last_run(runs)

"""journal.jsonl deleted while the run is being written is not created again silently: the new
journal starts with a `continued` line saying what was lost, restates the run's status, and the
warning is an event (run.h5's /logs/events), a run.log line and a warning of every reader of the
run, said once per deletion, whichever writer (the store's lines, the commands' thread) finds it.
A resume of a run whose journal is missing starts the new one the same way.

Real parts: the sweep's own RunStore writing real files and run.h5 (h5py)."""

from __future__ import annotations

import json

import h5py

from orbitrig.store.reader import read_run
from orbitrig.store.status import RunStatus
from orbitrig.store.writer import RunStore

from support.store_commits import commit_points

DELETED = "journal.jsonl was deleted while the run was being written (found missing at "


def _records(path) -> list[dict]:
    return [json.loads(x) for x in path.read_text().splitlines()]


def test_a_journal_deleted_during_the_run_is_continued_and_said(tmp_path):
    out = tmp_path / "run"
    store = commit_points(out, 2)
    (out / "journal.jsonl").unlink()
    store.command("pause", "ada")  # the commands' thread finds it gone
    store.run_log.flush()
    first = _records(out / "journal.jsonl")
    assert [r["k"] for r in first] == ["continued", "status", "event", "command"], first
    assert DELETED in first[0]["detail"] and "are lost; a new journal.jsonl continues it" in first[0]["detail"]
    assert (first[1]["status"], first[1]["message"]) == ("running", "")  # the status as it stands
    assert first[2]["state"] == "running" and first[2]["message"] == f"warning: {first[0]['detail']}"
    assert first[3]["command"] == "pause" and first[3]["by"] == "ada"
    (out / "journal.jsonl").unlink()
    store.set_status(RunStatus.COMPLETED, "all points completed")  # the store's own lines find it gone
    store.run_log.flush()
    second = _records(out / "journal.jsonl")
    assert [r["k"] for r in second][:3] == ["continued", "status", "event"] and second[1]["status"] == "running"
    log = (out / "run.log").read_text()
    assert log.count(DELETED) == 2, log  # once per deletion
    with h5py.File(out / "run.h5", "r") as f:
        assert f.attrs["status"] == "completed"
        events = [e["message"].decode() for e in f["logs/events"][()]]
    assert [m for m in events if DELETED in m] == [f"warning: {second[0]['detail']}"], events
    warnings = read_run(out).warnings  # every command reading the run says it
    assert warnings == [f"warning: {second[0]['detail']}"], warnings


def test_a_resume_of_a_run_without_journal_starts_a_continued_one(tmp_path):
    out = tmp_path / "run"
    commit_points(out, 2).set_status(RunStatus.STOPPED, "test")
    (out / "journal.jsonl").unlink()
    store = RunStore.open_existing(out)
    store.hold()
    try:
        store.prepare_resume()
    finally:
        store.release()
    first = _records(out / "journal.jsonl")[0]
    assert first["k"] == "continued" and "journal.jsonl was missing when the run was resumed" in first["detail"]
    assert read_run(out).warnings == [f"warning: {first['detail']}"]  # no longer missing, still said

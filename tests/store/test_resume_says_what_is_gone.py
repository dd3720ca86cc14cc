"""What a resume finds gone is said where a lab sees it.

- A resume that measures removes the run.h5 written before it (stale): said as it starts (run.log,
  terminal, the run's events), and a resumed run that then ends without run.h5 (the disk full at
  its end) says in its end message (status, run.log, terminal) that the earlier run.h5 is gone.
- A run whose journal.jsonl is missing (its status and logs lost) is said by the resume, by its
  consolidation (run.h5's status message) and by every command that reads the run.

Real parts: the sweep's own RunStore and record_end on a real tmpfs filled up, the `orbitrig`
command line (a subprocess for the resume, typer's runner for export)."""

from __future__ import annotations

import os
import shutil

import h5py
import pytest
from typer.testing import CliRunner

from orbitrig.cli import app
from orbitrig.run.run_dir import record_end
from orbitrig.run.states import FAILED, STOPPED
from orbitrig.store.reader import read_run
from orbitrig.store.writer import REMOVED_BEFORE, REMOVED_RUN_FILE, RunStore

from support.cli_helpers import orbitrig
from support.report_synthetic import write_synthetic_run
from support.store_checks import fill

pytestmark = pytest.mark.timeout(240)
MISSING = "journal.jsonl is missing: the run's recorded status, commands, events and CAN and drive logs are lost"


def _resumed(run) -> RunStore:
    store = RunStore.open_existing(run)
    store.hold()
    return store


@pytest.mark.parametrize("status", [STOPPED, FAILED])
def test_a_resume_that_ends_without_run_h5_says_the_earlier_one_was_removed(synthetic, tiny_disk, status):
    run = tiny_disk / "run"
    shutil.copytree(synthetic, run)  # stopped: points 0 and 1 complete, 2 not; run.h5 written
    assert (run / "run.h5").is_file()
    store = _resumed(run)
    try:
        assert store.prepare_resume() == [0, 1]
        assert not (run / "run.h5").exists() and REMOVED_RUN_FILE in store.set_aside, store.set_aside
        filler = fill(tiny_disk)
        os.truncate(filler, filler.stat().st_size - 200_000)  # room for the logs, not for run.h5
        failures: list[str] = []
        ended, message = record_end(store, store.run_id, status, "the test ends it", lambda w, e: failures.append(w))
    finally:
        store.release()
    store.run_log.flush()
    assert not (run / "run.h5").exists()
    assert ended == status and REMOVED_BEFORE in message, message  # the terminal's closing line
    assert REMOVED_BEFORE in read_run(run).status_message  # the run's recorded status (journal)
    log = (run / "run.log").read_text()
    assert f"resume: {REMOVED_RUN_FILE}" in log
    assert f"ended: {status}: " in log.splitlines()[-1] and REMOVED_BEFORE in log.splitlines()[-1], log


def test_a_resume_with_its_run_h5_never_written_says_nothing_removed(synthetic, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(synthetic, run)
    (run / "run.h5").unlink()
    store = _resumed(run)
    try:
        store.prepare_resume()
    finally:
        store.release()
    assert REMOVED_RUN_FILE not in store.set_aside and store.gone() == ""


def test_readers_and_a_measuring_resume_say_the_journal_is_missing(synthetic, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(synthetic, run)
    (run / "journal.jsonl").unlink()
    said = f"warning: {run / 'journal.jsonl'} is missing"
    assert [w.split(":", 2)[:2] for w in read_run(run).warnings] == [["warning", f" {run}/journal.jsonl is missing"]]
    r = CliRunner().invoke(app, ["export", str(run), "--out", str(tmp_path / "x")])
    assert r.exit_code == 0 and f"{said}: the run's recorded status" in r.stderr, r.output
    store = _resumed(run)
    try:
        store.prepare_resume()
    finally:
        store.release()
    store.run_log.flush()
    assert any(m.startswith(said) for m in store.set_aside), store.set_aside  # the resume's events
    assert f"resume: {said}" in (run / "run.log").read_text()


def test_a_consolidating_resume_says_the_journal_is_missing(tmp_path):
    run = write_synthetic_run(tmp_path / "run", incomplete=0)  # completed, run.h5 written
    (run / "run.h5").unlink()
    (run / "journal.jsonl").unlink()
    r = orbitrig("sweep", "--sim", "--resume", "--out", str(run), timeout=180, columns=None)
    assert r.returncode == 0, r.stderr
    assert f"warning: {run}/{MISSING}" in r.stderr, r.stderr
    with h5py.File(run / "run.h5", "r") as f:
        assert f.attrs["status"] == "completed" and MISSING in f.attrs["status_message"]
    assert f"resume: warning: {run}/{MISSING}" in (run / "run.log").read_text()

"""A resume that fails while it prepares the run folder (coefficients.csv cannot be written:
here a folder in its place, a fault a real file system produces as root too) leaves the run
with the status it ended with: the resume never began. It wrote "running (resumed)" first, then
failed before the run engine had a store to record an end with: the folder said running, no end."""

from __future__ import annotations

import pytest

from orbitrig.store.errors import StorageError
from orbitrig.store.journal import read_journal
from orbitrig.store.status import RunStatus
from orbitrig.store.writer import RunStore


def test_a_resume_that_cannot_write_coefficients_csv_keeps_the_runs_ended_status(tmp_path):
    out = tmp_path / "run"
    store = RunStore.create(out, rig_text="", matrix_text="", matrix_name="m", sim=True)
    store.set_status(RunStatus.STOPPED, "stopped by ada")
    store.run_log.flush()
    csv = store.csv_path
    csv.unlink()
    csv.mkdir()
    (csv / "in the way").write_text("x")
    again = RunStore.open_existing(out)
    with pytest.raises(StorageError, match="coefficients.csv"):
        again.prepare_resume()
    j = read_journal(again.layout.journal)
    assert (j.status, j.status_message) == (RunStatus.STOPPED, "stopped by ada")


def test_a_run_whose_coefficients_csv_cannot_be_created_says_it_failed(tmp_path):
    """The same at a new run: run.json and the journal's "running" were written, then the CSV
    failed before the engine had a store to record an end with: the folder said running for ever."""
    out = tmp_path / "run"
    (out / "coefficients.csv" / "in the way").mkdir(parents=True)
    with pytest.raises(StorageError, match="coefficients.csv"):
        RunStore.create(out, rig_text="", matrix_text="", matrix_name="m", sim=True)
    j = read_journal(out / "journal.jsonl")
    assert j.status == RunStatus.FAILED and j.status_message.startswith("the run could not be created: ")
    assert "coefficients.csv" in j.status_message

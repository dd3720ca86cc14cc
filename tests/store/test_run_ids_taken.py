"""A run's id (``<rig id>@<created>``, the catalog's key) is taken in the folder of run
directories: two runs of one rig started there in the same millisecond get two ids."""

from __future__ import annotations

import datetime as dt
import subprocess
from pathlib import Path

import pytest

from orbitrig.store.errors import StorageError
from orbitrig.store.identity import TAKEN, claim_created
from orbitrig.store.writer import RunStore
from rigunits import utc_stamp

WHEN = dt.datetime(2026, 12, 7, 3, 30, 5, 123456, tzinfo=dt.timezone.utc)


def _take(runs, name):
    (runs / TAKEN).mkdir(exist_ok=True)
    (runs / TAKEN / name).touch()


def test_a_millisecond_taken_moves_the_id_to_the_next_free_one(tmp_path):
    _take(tmp_path, "SAC-DS-1@20261207T033005.123Z")
    _take(tmp_path, "SAC-DS-1@20261207T033005.124Z")
    _take(tmp_path, "other-rig@20261207T033005.125Z")  # another rig's id: no bar to this one's
    assert claim_created(tmp_path, "SAC-DS-1", WHEN) == "2026-12-07T03:30:05.125Z"
    assert claim_created(tmp_path, "SAC-DS-1", WHEN) == "2026-12-07T03:30:05.126Z"  # now taken too
    assert claim_created(tmp_path, "other-rig", WHEN) == "2026-12-07T03:30:05.123Z"
    assert (tmp_path / TAKEN / "SAC-DS-1@20261207T033005.126Z").is_file()


def test_a_rig_id_not_fit_for_a_file_name_is_taken_all_the_same(tmp_path):
    assert claim_created(tmp_path, "lab/rig 2", WHEN) == "2026-12-07T03:30:05.123Z"
    assert claim_created(tmp_path, "lab/rig 2", WHEN) == "2026-12-07T03:30:05.124Z"
    assert claim_created(tmp_path, "", WHEN) == "2026-12-07T03:30:05.123Z"  # recorded as 'rig'
    assert sorted(p.name for p in (tmp_path / TAKEN).iterdir()) == [
        "lab_rig_2@20261207T033005.123Z",
        "lab_rig_2@20261207T033005.124Z",
        "rig@20261207T033005.123Z",
    ]


def test_two_runs_of_one_rig_never_share_an_id_in_one_folder(tmp_path):
    """Every millisecond of the next 2 s is taken (by runs another process started): the runs
    created now are dated after them, each at its own millisecond."""
    now = dt.datetime.now(dt.timezone.utc)
    window = {utc_stamp(now + dt.timedelta(milliseconds=ms)) for ms in range(2000)}
    for stamp in window:
        _take(tmp_path, f"rigA@{stamp}")
    kw = {"rig_text": "", "matrix_text": "", "matrix_name": "m", "sim": True, "provenance": {"rig_id": "rigA"}}
    ids = [RunStore.create(tmp_path / name, **kw).run_id for name in ("a", "b")]
    first, second = (i.split("@", 1)[1] for i in ids)
    assert ids[0] != ids[1] and ids[0].startswith("rigA@")
    last = max(window)
    for created in (first, second):
        stamp = utc_stamp(dt.datetime.fromisoformat(created.replace("Z", "+00:00")))
        assert stamp not in window and stamp > last


def test_a_read_only_folder_of_runs_leaves_the_id_untaken_and_says_so(tmp_path, caplog):
    """The run directory given (writable) inside a folder mounted read-only: the run is created
    all the same, dated now, with a warning that its id was not checked there."""
    from support.small_disk import mounted_tmpfs

    with mounted_tmpfs(tmp_path / "runs", "1m") as runs, mounted_tmpfs(runs / "run", "4m") as run:
        subprocess.run(["mount", "-o", "remount,ro", str(runs)], check=True)
        with caplog.at_level("WARNING", logger="orbitrig.store.identity"):
            store = RunStore.create(run, rig_text="", matrix_text="", matrix_name="m", sim=True)
        assert store.run_id.startswith("rig@") and not (runs / TAKEN).exists()
        assert f"not taken in {runs / TAKEN} (Read-only file system)" in caplog.text
        assert claim_created(runs, "rigA", WHEN) == "2026-12-07T03:30:05.123Z"


def test_a_file_where_the_ids_are_taken_is_refused_naming_it(tmp_path):
    (tmp_path / TAKEN).write_text("")
    with pytest.raises(StorageError, match=r"\.run-ids: cannot take the run id: FileExistsError"):
        claim_created(tmp_path, "rigA", WHEN)


def test_a_run_directory_given_as_dot_takes_its_id_beside_its_siblings(tmp_path, monkeypatch):
    """`--out .` from inside runs/b: the id is taken in runs/.run-ids, where runs/a's was (not in
    b itself, where no other run would be compared, nor above runs)."""
    kw = {"rig_text": "", "matrix_text": "", "matrix_name": "m", "sim": True, "provenance": {"rig_id": "rigA"}}
    runs = tmp_path / "runs"
    (runs / "b").mkdir(parents=True)
    first = RunStore.create(runs / "a", **kw).run_id
    monkeypatch.chdir(runs / "b")
    second = RunStore.create(Path("."), **kw).run_id
    assert first != second
    assert not (runs / "b" / TAKEN).exists() and not (tmp_path / TAKEN).exists()
    stamps = sorted(
        utc_stamp(dt.datetime.fromisoformat(i.split("@")[1].replace("Z", "+00:00"))) for i in (first, second)
    )
    assert sorted(p.name for p in (runs / TAKEN).iterdir()) == [f"rigA@{s}" for s in stamps]

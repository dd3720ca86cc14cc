"""Storage errors survive the trip from a worker process (orbitrig report's figure workers)
with every field: a full disk in a worker is the same one-line error in the parent."""

import pickle
from concurrent.futures import ProcessPoolExecutor

import pytest

from orbitrig.store.errors import RunDirError, StorageError, StorageFullError


def _raise_full(path: str) -> None:
    raise StorageFullError(path, "needs 5.0 MB free, 1.0 MB left", advice="free space", needed=5, free=1)


def test_each_error_pickles_with_its_fields():
    full = StorageFullError("/r/run.h5", "cannot write", advice="export again", needed=10, free=2)
    back = pickle.loads(pickle.dumps(full))
    assert type(back) is StorageFullError and str(back) == str(full)
    assert (back.path, back.problem, back.advice, back.needed, back.free) == (
        "/r/run.h5",
        "cannot write",
        "export again",
        10,
        2,
    )
    plain = pickle.loads(pickle.dumps(StorageError("/r/x", "cannot rename")))
    assert (type(plain), plain.path, plain.reason) == (StorageError, "/r/x", "cannot rename")
    bad = pickle.loads(pickle.dumps(RunDirError("/r/run.json", "not JSON")))
    assert (type(bad), bad.file, bad.reason, str(bad)) == (
        RunDirError,
        "/r/run.json",
        "not JSON",
        "/r/run.json: not JSON",
    )


def test_a_full_disk_in_a_worker_process_arrives_as_itself():
    with ProcessPoolExecutor(1) as pool, pytest.raises(StorageFullError) as err:
        pool.submit(_raise_full, "/r/figures/a.png").result()
    assert (err.value.needed, err.value.free, err.value.advice) == (5, 1, "free space")
    assert str(err.value) == "/r/figures/a.png: needs 5.0 MB free, 1.0 MB left: free space"

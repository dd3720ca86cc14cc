"""A run file (or a point's results.h5) damaged inside is refused with a message naming the file
and the HDF5 object that is wrong, so a colleague who was sent run.h5 can say what is missing:
it said only `object 'fx' doesn't exist` (which point? which load system?) or a bare JSON
decoding error, naming no fit."""

from __future__ import annotations

import shutil

import h5py
import pytest

import orbitrig
from orbitrig.store.errors import RunDirError
from orbitrig.store.layout import RunLayout
from orbitrig.store.reader import read_point, read_run
from support.cli_helpers import orbitrig as orbitrig_cli

FIT = "points/0001/identification/strain__kcd11__none__ols"
DEEP = "[" * 100_000 + "]" * 100_000  # the JSON decoder recurses per level: a RecursionError traceback before


@pytest.fixture
def lone_run_h5(synthetic, tmp_path):
    """A folder holding only a copy of the run's run.h5 (as sent to a colleague)."""
    (tmp_path / "copy").mkdir()
    shutil.copy(synthetic / "run.h5", tmp_path / "copy" / "run.h5")
    return tmp_path / "copy"


def _damage(path, edit) -> None:
    with h5py.File(path, "a") as f:
        edit(f)


@pytest.mark.parametrize(
    "edit, names",
    [
        (lambda f: f.__delitem__("points/0001/table/strain/fx"), ["/points/0001/table/strain", "'fx'"]),
        (lambda f: f[FIT].attrs.__setitem__("json", "{not json"), [f"/{FIT}", "json"]),
        (lambda f: f.__delitem__("points/0000/frequencies/00_fwd/coherence"), None),  # optional: still read
        (lambda f: f["points/0000/truth"].attrs.__setitem__("json", "[1,"), ["/points/0000/truth", "json"]),
        (lambda f: f[FIT].attrs.__setitem__("json", DEEP), [f"/{FIT}", "'json'", "nested too deeply"]),
        # a point's setting of the wrong type or missing: it said only "could not convert string to float"
        (lambda f: f["points/0001"].attrs.__setitem__("spin", "fast"), ["/points/0001: setting 'spin'", "'fast'"]),
        (lambda f: f["points/0000"].attrs.__delitem__("spin"), ["/points/0000: setting 'spin' missing"]),
    ],
)
def test_run_h5_damage_names_file_and_object(lone_run_h5, edit, names):
    _damage(lone_run_h5 / "run.h5", edit)
    if names is None:
        assert read_run(lone_run_h5).points[0].frequencies
        return
    with pytest.raises(RunDirError) as caught:
        orbitrig.open_run(lone_run_h5)
    message = str(caught.value)
    assert message.startswith(f"{lone_run_h5 / 'run.h5'}: malformed run file: ")
    for part in names:
        assert part in message, message


def test_results_piece_damage_names_the_object(synthetic, tmp_path):
    """A point's results.h5 read as a complete point's (its digest checked elsewhere)."""
    run = tmp_path / "run"
    shutil.copytree(synthetic, run)
    results = run / "points" / "0001" / "results.h5"
    _damage(results, lambda f: f["identification/piezo__kc7__none__ols"].attrs.__setitem__("json", "{"))
    with pytest.raises(RunDirError) as caught:
        read_point(RunLayout(run), 1, complete=True, blocks=False)
    message = str(caught.value)
    assert message.startswith(f"{results}: malformed results of a complete point: ")
    assert "/identification/piezo__kc7__none__ols" in message and "json" in message


def test_a_command_reading_such_a_run_h5_exits_2_naming_it(lone_run_h5):
    _damage(lone_run_h5 / "run.h5", lambda f: f[FIT].attrs.__setitem__("json", DEEP))
    p = orbitrig_cli("reduce", str(lone_run_h5), "--model", "kc8")
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    assert p.stderr == (
        f"orbitrig reduce: error: {lone_run_h5 / 'run.h5'}: malformed run file: /{FIT}: "
        "attribute 'json' is not JSON this reader takes (nested too deeply)\n"
    )

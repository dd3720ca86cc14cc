"""orbitrig.open_run takes a run file itself, under any name: run.h5 as a colleague was sent it
(`an1-2026-12-05.h5`) or the h5 export, read with everything the run directory gives."""

from __future__ import annotations

import shutil

import h5py
import numpy as np
import pytest

import orbitrig
from orbitrig.store.errors import RunDirError
from support.cli_helpers import orbitrig as orbitrig_cli


@pytest.fixture(scope="module")
def sent(sim_run, tmp_path_factory):
    """The run's run.h5 copied under another name into a folder of other files."""
    folder = tmp_path_factory.mktemp("inbox")
    shutil.copy(sim_run / "run.h5", folder / "rig3-2026-12-05.h5")
    (folder / "notes.txt").write_text("the run of Friday\n")
    return folder / "rig3-2026-12-05.h5"


def test_a_run_file_under_any_name_reads_as_its_directory(sim_run, sent):
    by_dir, by_file = orbitrig.open_run(sim_run), orbitrig.open_run(sent)
    assert repr(by_file).startswith(f"RunData({str(sent)!r}, status=completed")
    assert by_file.points.equals(by_dir.points)
    assert by_file.coefficients.equals(by_dir.coefficients)
    assert by_file.table(0, "strain").equals(by_dir.table(0, "strain"))
    with h5py.File(sent, "r") as f:  # the numbers as h5py reads them from that file
        ident = f["points/0000/identification/piezo__kcd11__none__ols"]
        np.testing.assert_array_equal(
            by_file.fit(0, "piezo", "kcd11").coefficients["value"].to_numpy(), ident["coefficients"][()]
        )
    assert by_file.waveforms(0).identical(by_dir.waveforms(0))
    with pytest.raises(KeyError, match=f"{sent}: no operating point 9"):
        by_file.table(9)


def test_a_file_that_is_no_run_file_is_refused_naming_it(sent):
    notes = sent.parent / "notes.txt"
    with pytest.raises(RunDirError, match=f"{notes}: not a readable HDF5 file"):
        orbitrig.open_run(notes)


def test_reduce_still_wants_the_directory_it_writes_into(sent):
    """`orbitrig reduce` writes its CSV into the run's directory: a file is refused as before,
    not taken and then failing to write `FILE/reduce_*.csv`."""
    p = orbitrig_cli("reduce", str(sent), "--model", "kc8")
    assert p.returncode == 2, p.stderr
    assert (
        p.stderr
        == f"orbitrig reduce: error: {sent}: not a directory (expected a run directory written by `orbitrig sweep --out DIR`)\n"
    )
    assert sorted(x.name for x in sent.parent.iterdir()) == ["notes.txt", sent.name]


def test_a_path_that_does_not_exist_is_named_as_either_kind(tmp_path):
    """open_run and `design --noise-from` take a directory or a file: a mistyped one is not said
    to be a missing directory (the README's `--noise-from demo.h5` before demo.h5 was made)."""
    missing = tmp_path / "demo.h5"
    with pytest.raises(RunDirError, match=f"^{missing}: no such run directory or run file$"):
        orbitrig.open_run(missing)
    p = orbitrig_cli("design", "--model", "kc8", "--spin", "1000", "--noise-from", str(missing))
    assert p.returncode == 2, p.stderr
    assert p.stderr == f"orbitrig design: error: {missing}: no such run directory or run file\n"

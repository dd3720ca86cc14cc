"""Asking the API for the table or a fit of a point the run never completed says so: it said only
that the point had no orbit table ('tables: none') or no fit ('fits: none'), as if the run had
measured none there. The truth of such a point of a --sim run, and the waveforms of a point with
no block, are the same KeyError naming the point (they were None and an empty Dataset, silently);
a missing fit's KeyError lists the fits as fit() takes them, not by their internal keys."""

from __future__ import annotations

import ast

import pytest

import orbitrig
from support.report_synthetic import write_synthetic_run


@pytest.fixture(scope="module")
def cut_short(tmp_path_factory):
    """Two complete points and point 2 whose blocks are stored but which was never completed."""
    return orbitrig.open_run(write_synthetic_run(tmp_path_factory.mktemp("cut") / "run", finished=False))


def test_the_table_and_fit_of_an_incomplete_point_say_it_is_not_complete(cut_short):
    assert not cut_short.points.loc[2, "complete"] and len(cut_short.waveforms(2).block) > 0  # blocks stored
    with pytest.raises(KeyError, match=r"tables: none\); it is not complete: never completed \(no commit record\)"):
        cut_short.table(2, "piezo")
    with pytest.raises(KeyError, match=r"takes them: none\); it is not complete: never completed \(no commit record\)"):
        cut_short.fit(2, "piezo", "kcd11")


def test_a_complete_point_missing_a_fit_says_nothing_of_completeness(cut_short):
    with pytest.raises(KeyError) as caught:
        cut_short.fit(0, "piezo", "kcd12")
    said = str(caught.value)
    assert "not complete" not in said and "no fit ('piezo', 'kcd12', 'none', 'ols')" in said
    assert "as fit(point, lms, model, freq_dep, method) takes them: ('piezo', 'kc7', 'none', 'ols')" in said
    assert "('strain', 'kcd11', 'power:1', 'ols')" in said and "__" not in said
    listed = said.split("takes them: ")[1].split(")")[0] + ")"
    assert cut_short.fit(0, *ast.literal_eval(listed)).error == ""  # as the caller types it


def test_the_truth_of_an_incomplete_point_of_a_sim_run_says_it_is_not_complete(cut_short):
    assert cut_short.run.sim and cut_short.truth(0)["K0"].shape == (2, 2)
    with pytest.raises(KeyError, match=r"point 2 has no truth stored \(a --sim run\); it is not complete: never"):
        cut_short.truth(2)


def test_the_waveforms_of_a_point_with_no_block_name_it(tmp_path):
    run = write_synthetic_run(tmp_path / "run", finished=False)
    for block in (run / "points" / "0002").glob("*.h5"):
        block.unlink()  # begun, cut before its first block
    data = orbitrig.open_run(run)
    assert 2 in data.points.index and len(data.waveforms(0).block) > 0
    with pytest.raises(KeyError, match=r"point 2 has no block stored \(no waveforms\); it is not complete: never"):
        data.waveforms(2)

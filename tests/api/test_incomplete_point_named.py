"""Asking the API for the table or a fit of a point the run never completed says so: it said only
that the point had no orbit table ('tables: none') or no fit ('fits: none'), as if the run had
measured none there."""

from __future__ import annotations

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
    with pytest.raises(KeyError, match=r"fits: none\); it is not complete: never completed \(no commit record\)"):
        cut_short.fit(2, "piezo", "kcd11")


def test_a_complete_point_missing_a_fit_says_nothing_of_completeness(cut_short):
    with pytest.raises(KeyError) as caught:
        cut_short.fit(0, "piezo", "kcd12")
    assert "not complete" not in str(caught.value) and "fits: piezo__" in str(caught.value)

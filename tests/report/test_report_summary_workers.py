"""summary.png draws the same error bars whether the points were drawn in worker processes
(the default, 2) or here: its bands were looked up by id() of each result, and a point drawn in a
worker comes back pickled, its results new objects, so the summary fell back to the statistical
covariance (error bars 30 times too short on a calibrated rig) and its legend said so."""

from __future__ import annotations

import shutil

import matplotlib.image as mpimg
import numpy as np
import pytest

from orbitrig.analysis.report import ReportOptions, make_report
from reduction.systematic import UncertaintyBasis
from support.report_synthetic import write_synthetic_run
from test_report_stated import STATED

#: the points' own figures the quickest kind: the summary is drawn from the points' results whichever are drawn
OPTIONS = ReportOptions(figures=frozenset({"coherence"}))


@pytest.fixture(scope="module")
def two_copies(tmp_path_factory):
    """One calibrated run of two points, copied to a second folder of the same name."""
    first = write_synthetic_run(tmp_path_factory.mktemp("one") / "run", incomplete=0, calibration=STATED)
    second = tmp_path_factory.mktemp("two") / "run"
    shutil.copytree(first, second)
    return first, second


def test_summary_is_the_same_drawn_in_workers_or_here(two_copies):
    here = make_report(two_copies[0], options=OPTIONS, workers=1)
    pooled = make_report(two_copies[1], options=OPTIONS, workers=2)
    for pr in pooled.points:  # the bands of every result, found again after the trip through pickle
        bases = {pr.band(r).basis for rs in pr.results.values() for r in rs}
        assert bases == {UncertaintyBasis.COMBINED}
    a, b = mpimg.imread(here.summary), mpimg.imread(pooled.summary)
    assert a.shape == b.shape and np.array_equal(a, b)

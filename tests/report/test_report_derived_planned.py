"""The page's derived quantities on a run of the real sweep on the simulator name each column
by its planned orbit frequency, as the API's and the exports' derived rows (index orbit_hz:
5.0, ..., 20.0 Hz), hold the numbers those rows hold, and show the speeds measured on the timing
disk (the orbit table's orbit_hz: 4.9997 Hz for 5.0) as measured."""

from __future__ import annotations

import re

import numpy as np
import pytest

import orbitrig
from orbitrig.analysis.report import ReportOptions, make_report
from orbitrig.analysis.rounding import number, orbit_frequency, with_uncertainty
from orbitrig.analysis.quality import derived_k
from rigunits import HZ

FITS = (("kcd11", "none"), ("kcd11", "power:1"))  # WFR constant over Omega, and one that is not


@pytest.fixture(scope="module")
def report(sweep_run, tmp_path_factory):
    """The report of the session's simulator run (one cheap figure kind) into a folder of its own."""
    out = tmp_path_factory.mktemp("planned")
    return make_report(sweep_run, out=out, options=ReportOptions(figures=frozenset({"coherence"})))


@pytest.mark.parametrize("model, freq_dep", FITS)
def test_derived_quantities_are_those_of_the_exports_at_the_planned_frequencies(sweep_run, report, model, freq_dep):
    exported = orbitrig.open_run(sweep_run).fit(0, "piezo", model, freq_dep).derived
    planned = exported.index.to_numpy()
    assert planned[[0, -1]].tolist() == [5.0, 20.0]
    (pr,) = report.points
    r, d = next((r, d) for r, d in pr.derived["piezo"] if (r.model, r.freq_dep) == (model, freq_dep))
    assert d.orbit[[0, -1]] == pytest.approx(HZ * planned[[0, -1]], rel=1e-15)  # not the measured 4.9997 Hz
    np.testing.assert_allclose(d.wfr[[0, -1]], exported["wfr"].to_numpy()[[0, -1]], rtol=1e-6)
    np.testing.assert_allclose(d.wfr_std[[0, -1]], exported["wfr_std"].to_numpy()[[0, -1]], rtol=1e-6)
    k = derived_k(r)
    row = re.search(
        rf'<td class="l">{re.escape(model)}{"" if freq_dep == "none" else " " + freq_dep} \(\d+ coef\.\)</td>'
        r"<td>([^<]*)</td><td>([^<]*)</td>",
        report.html.read_text(encoding="utf-8"),
    )
    assert row is not None
    assert list(row.groups()) == [
        with_uncertainty(v, k * u) for v, u in zip(exported["wfr"].iloc[[0, -1]], exported["wfr_std"].iloc[[0, -1]])
    ]


def test_columns_name_the_planned_frequency_and_show_the_measured_speeds(sweep_run, report):
    run = orbitrig.open_run(sweep_run)
    table = run.table(0, "piezo")
    page = report.html.read_text(encoding="utf-8")
    heads = re.findall(r"<th>WFR at (.*?)</th>", page)
    assert len(heads) == 4  # two columns, both load measuring systems
    for planned, head in zip((5.0, 20.0), heads):
        blocks = [f.name for f in report.points[0].point.frequencies if f.orbit_hz == planned]
        rows = table[table["block"].isin(blocks)]
        assert len(rows) == 2 and not np.any(rows["orbit_hz"] == planned)  # measured: never exactly the plan
        by_whirl = sorted(zip(-rows["direction"], rows["orbit_hz"]))
        measured = ", ".join(f"{number(hz, digits=6)} Hz {'forward' if d < 0 else 'backward'}" for d, hz in by_whirl)
        assert head == f'{orbit_frequency(planned)}<br><span class="muted">(measured {measured})</span>'

"""bearing_elements given a file that is no ROSS export (a run's run.json, a CSV) names the file
and what it wants: it raised a bare KeyError 'bearings' or a JSON decoding error. ROSS is the `ross`
extra, which tools/run-tests installs: without it this fails, not skips."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from orbitrig.cli import app


def test_a_file_that_is_no_ross_export_is_named(synthetic_run, tmp_path):
    from orbitrig.analysis.ross_elements import bearing_elements

    header = synthetic_run / "run.json"
    with pytest.raises(ValueError, match=rf"^{header}: not an orbitrig ROSS export \(format 'orbitrig-run/"):
        bearing_elements(header, [0, 6])
    other = tmp_path / "other.json"
    other.write_text('{"points": []}')
    with pytest.raises(ValueError, match=rf"^{other}: not an orbitrig ROSS export \(no list 'bearings'\)"):
        bearing_elements(other, [0, 6])
    table = tmp_path / "point_0000_piezo.csv"
    table.write_text("spin_rpm,orbit_hz\n1000,5\n")
    with pytest.raises(ValueError, match=rf"^{table}: not JSON \("):
        bearing_elements(table, [0, 6])
    res = CliRunner().invoke(app, ["export", str(synthetic_run), "--format", "ross", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    assert bearing_elements(tmp_path / "ross_bearings.json", [0, 6], point=0)  # the export itself: read

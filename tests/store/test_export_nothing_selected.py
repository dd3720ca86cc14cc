"""`orbitrig export RUN --point N` when no point asked for can be exported: nothing is written
or removed (an earlier export stays byte for byte), the point is named and the exit status
is 1, as `report --point` leaves its page; a negative N is bad usage (exit 2), for `report` too
(it said "point -001 skipped", exit 1), and so is a --fit with a format other than ross (it was
ignored)."""

from __future__ import annotations

import csv
import io
import json

import pytest
from typer.testing import CliRunner

from orbitrig.cli import app
from orbitrig.store.export import export_run

FORMATS = ("csv", "mat", "tdms", "ross")


def _export(run, out, *args):
    return CliRunner().invoke(app, ["export", str(run), "--out", str(out), *args])


def _snapshot(folder) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


@pytest.fixture(scope="module")
def exported(synthetic, tmp_path_factory):
    """Every format exported once (both complete points) into one folder."""
    out = tmp_path_factory.mktemp("earlier")
    for fmt in FORMATS:
        res = _export(synthetic, out, "--format", fmt)
        assert res.exit_code == 0, res.output
    return out


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_mistyped_point_leaves_the_earlier_export_as_it_was(synthetic, exported, fmt):
    before = _snapshot(exported)
    bearings = json.loads(before["ross_bearings.json"])["bearings"]
    rows = list(csv.DictReader(io.StringIO(before["coefficients.csv"].decode())))
    assert len(bearings) == 2 and {r["point"] for r in rows} == {"0", "1"}  # the earlier export has data
    res = _export(synthetic, exported, "--format", fmt, "--point", "7")
    assert res.exit_code == 1
    assert "error: point 0007 skipped: no such point in the run" in res.stderr
    assert f"nothing exported: {exported} left as it was" in res.stdout
    assert _snapshot(exported) == before  # no file written, replaced or removed


def test_a_negative_point_is_bad_usage_naming_the_option(synthetic, exported):
    before = _snapshot(exported)
    for fmt in FORMATS:
        res = _export(synthetic, exported, "--format", fmt, "--point", "-1")
        assert res.exit_code == 2, (fmt, res.output)
        assert "--point -1" in res.stderr and "-001" not in res.stderr
    assert _snapshot(exported) == before
    res = CliRunner().invoke(app, ["report", str(synthetic), "--point", "-1"])
    assert res.exit_code == 2 and "error: --point -1: a point index is 0 or more" in res.stderr
    assert "-001" not in res.output and not (synthetic / "plots" / "point_-001").exists()


@pytest.mark.parametrize("fmt", ["csv", "mat", "tdms", "h5"])
def test_a_fit_with_another_format_than_ross_is_bad_usage(synthetic, exported, fmt):
    before = _snapshot(exported)
    res = _export(synthetic, exported, "--format", fmt, "--fit", "strain:kc8:none:ols")
    assert res.exit_code == 2, res.output
    assert f"--fit 'strain:kc8:none:ols' applies to --format ross only (--format {fmt} exports" in res.stderr
    assert _snapshot(exported) == before


def test_export_run_writes_nothing_and_makes_no_folder_for_no_point(synthetic, tmp_path):
    done = export_run(synthetic, "csv", tmp_path / "new", points=[7])
    assert done.files == [] and done.selection.points == []
    assert done.selection.skipped == ["point 0007 skipped: no such point in the run"]
    assert not (tmp_path / "new").exists()
    done = export_run(synthetic, "csv", tmp_path / "new", points=[1, 7])  # one of two: exported, one named
    assert [p.index for p in done.selection.points] == [1] and len(done.selection.skipped) == 1
    assert (tmp_path / "new" / "point_0001_piezo.csv").is_file()


def test_a_format_is_one_of_the_export_formats(synthetic, tmp_path):
    from orbitrig.store.export import ExportFormat

    bad = _export(synthetic, tmp_path / "bad", "--format", "xlsx")
    assert bad.exit_code == 2 and "--format 'xlsx': one of csv, mat, tdms, h5, ross" in bad.output
    with pytest.raises(ValueError, match="unknown format 'ross': one of csv, mat, tdms, h5"):
        export_run(synthetic, ExportFormat.ROSS, tmp_path / "ross")
    assert not (tmp_path / "bad").exists() and not (tmp_path / "ross").exists()

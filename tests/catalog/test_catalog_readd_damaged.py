"""A re-add makes the catalog say what the run folder says now: a point catalogued once and
damaged since loses its rows (and is named as damaged, exit 1, as on a first add), on SQLite
and on a real PostgreSQL server; a run whose every point is damaged since keeps no row."""

from __future__ import annotations

import shutil

from typer.testing import CliRunner

from orbitrig.cli import app

N_FITS = 8  # per point: four models on each load measuring system


def _damage(run, point: str) -> None:
    results = run / "points" / point / "results.h5"
    results.write_bytes(results.read_bytes()[:100])


def test_a_point_damaged_since_the_first_add_loses_its_rows(catalog_run, catalog, tmp_path):
    run = tmp_path / "runs" / "run1"
    shutil.copytree(catalog_run, run)
    first = CliRunner().invoke(app, ["catalog", "add", str(run), "--db", catalog.url])
    assert first.exit_code == 0, first.output
    assert {r["point"] for r in catalog.rows()} == {0, 1}
    _damage(run, "0001")
    again = CliRunner().invoke(app, ["catalog", "add", str(run), "--db", catalog.url])
    assert again.exit_code == 1, again.output
    assert f"error: {run}: point 0001 skipped: results.h5 is damaged" in again.stderr
    rows = catalog.rows()
    assert {r["point"] for r in rows} == {0} and len(rows) == N_FITS
    _damage(run, "0000")
    last = CliRunner().invoke(app, ["catalog", "add", str(run), "--db", catalog.url])
    assert last.exit_code == 1 and f"error: {run}: nothing added:" in last.stderr, last.output
    assert catalog.rows() == []

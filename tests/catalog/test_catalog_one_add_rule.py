"""The service's feed and `catalog add` follow one rule (orbitrig.catalog.run_add), on SQLite
and on a real PostgreSQL server: a point damaged since it was added loses its rows, whichever
adds the run again; a run whose run.json cannot be read keeps its rows of an earlier add, and
both say how many rows of which run stay."""

from __future__ import annotations

import asyncio
import logging
import shutil

from typer.testing import CliRunner

from orbitrig.cli import app
from orbitrig.service.catalog_feed import CatalogFeed

N_FITS = 8  # per point: four models on each load measuring system


def _damage(run, point: str) -> None:
    results = run / "points" / point / "results.h5"
    results.write_bytes(results.read_bytes()[:100])


def _feed(url: str, run, point: int | None) -> CatalogFeed:
    feed = CatalogFeed(url)

    async def go() -> None:
        if point is None:
            feed.run_ended(run)
        else:
            feed.point_completed(run, point)
        assert await asyncio.to_thread(feed.finish, 30) == []

    asyncio.run(go())
    return feed


def test_the_feed_deletes_the_rows_of_a_point_damaged_since(catalog_run, catalog, tmp_path, caplog):
    run = tmp_path / "runs" / "run1"
    shutil.copytree(catalog_run, run)
    assert CliRunner().invoke(app, ["catalog", "add", str(run), "--db", catalog.url]).exit_code == 0
    assert {r["point"] for r in catalog.rows()} == {0, 1}
    _damage(run, "0001")
    with caplog.at_level(logging.WARNING, logger="orbitrig.service.catalog"):
        _feed(catalog.url, run, 1)  # the point reported again, damaged now
    rows = catalog.rows()
    assert {r["point"] for r in rows} == {0} and len(rows) == N_FITS
    assert "damaged point(s) 0001: their rows deleted" in caplog.text
    _damage(run, "0000")
    _feed(catalog.url, run, None)  # the run's end: every point damaged since loses its rows
    assert catalog.rows() == []


def test_the_feed_adds_only_the_point_it_is_told_of(catalog_run, catalog):
    _feed(catalog.url, catalog_run, 0)
    assert {r["point"] for r in catalog.rows()} == {0}


def test_a_run_json_unreadable_since_keeps_its_rows_and_says_so(catalog_run, catalog, tmp_path, caplog):
    run = tmp_path / "runs" / "run1"
    shutil.copytree(catalog_run, run)
    assert CliRunner().invoke(app, ["catalog", "add", str(run), "--db", catalog.url]).exit_code == 0
    run_id = catalog.rows()[0]["run_id"]
    (run / "run.json").write_text("{not json")
    again = CliRunner().invoke(app, ["catalog", "add", str(run), "--db", catalog.url])
    assert again.exit_code == 2, again.output
    kept = f"the catalog keeps its {2 * N_FITS} rows of run {run_id} from an earlier add (not removed"
    assert f"error: {run}: not added: {run / 'run.json'}: not a readable run header" in again.stderr
    assert kept in again.stderr
    assert len(catalog.rows()) == 2 * N_FITS
    with caplog.at_level(logging.WARNING, logger="orbitrig.service.catalog"):
        feed = _feed(catalog.url, run, None)
    assert feed.failed == 1 and kept in caplog.text and "not added" in caplog.text
    assert len(catalog.rows()) == 2 * N_FITS


def test_an_unreadable_run_is_named_when_the_catalog_cannot_be_asked(catalog_run, tmp_path):
    run = tmp_path / "runs" / "run1"
    shutil.copytree(catalog_run, run)
    (run / "run.json").write_text("{not json")
    down = f"postgresql://postgres@/postgres?host={tmp_path / 'no-server'}&port=1"
    res = CliRunner().invoke(app, ["catalog", "add", str(run), "--db", down])
    assert res.exit_code == 2, res.output
    assert f"error: {run}: not added: {run / 'run.json'}: not a readable run header" in res.stderr
    assert "what the catalog keeps of it is not known (catalog postgresql://" in res.stderr


def test_the_feed_reads_only_the_point_it_adds_and_writes_the_rows_catalog_add_writes(catalog_run, catalog):
    """Each completed point's add reads that point alone (it read and hashed the whole run for
    every point: n^2 over a run in the feed's thread); its rows are those of `catalog add`."""
    from support.store_commits import counting_hashes

    for k in (1, 0):
        with counting_hashes() as hashed:
            _feed(catalog.url, catalog_run, k)
        point_dir = catalog_run / "points" / f"{k:04d}"
        assert len(hashed.paths) > 2 and {p.parent for p in hashed.paths} == {point_dir}, (k, hashed.paths)
    fed = catalog.rows()
    assert {r["point"] for r in fed} == {0, 1} and len(fed) == 2 * N_FITS
    with catalog.engine.begin() as conn:
        conn.exec_driver_sql("DELETE FROM fits")
    assert CliRunner().invoke(app, ["catalog", "add", str(catalog_run), "--db", catalog.url]).exit_code == 0
    assert catalog.rows() == fed

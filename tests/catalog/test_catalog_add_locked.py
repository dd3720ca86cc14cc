"""`catalog add` of several RUNs into a catalog it cannot write (SQLite: another writer holds the
lock) names each RUN with the database's error and tries the others, exit 1; it stopped at the
first with a message naming no RUN, and never told what became of the rest."""

from __future__ import annotations

import shutil
import sqlite3

from typer.testing import CliRunner

from orbitrig.catalog.store import Catalog
from orbitrig.cli import app


def test_each_run_the_locked_catalog_refuses_is_named(catalog_run, tmp_path):
    runs = tmp_path / "runs"
    shutil.copytree(catalog_run, runs / "a")
    shutil.copytree(catalog_run, runs / "b")
    (runs / "b" / "run.json").write_text("{not json")
    path = tmp_path / "c.sqlite"
    Catalog(f"sqlite:///{path}").close()  # made, then locked by another writer
    other = sqlite3.connect(path, isolation_level=None)
    other.execute("BEGIN IMMEDIATE")
    try:
        res = CliRunner().invoke(app, ["catalog", "add", str(runs / "a"), str(runs / "b"), "--db", f"sqlite:///{path}"])
    finally:
        other.execute("ROLLBACK")
        other.close()
    assert res.exit_code == 2, res.output  # no RUN added, one refused
    assert (
        f"error: {runs / 'a'}: not added: catalog sqlite:///{path}: cannot add rows (database is locked)" in res.stderr
    ), res.stderr
    assert f"error: {runs / 'b'}: not added: {runs / 'b' / 'run.json'}: not a readable run header" in res.stderr
    assert "Traceback" not in res.output

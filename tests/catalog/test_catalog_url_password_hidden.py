"""A catalog URL's password never reaches a message or the service's log: neither the user
part's (`postgresql://user:PW@host/db`) nor a `password=` query parameter
(`postgresql://user@/db?host=DIR&password=PW`, which libpq and SQLAlchemy accept). The
database is a real PostgreSQL client (psycopg) failing to reach a server on a socket
directory where none listens."""

from __future__ import annotations

import logging

import pytest
from typer.testing import CliRunner

from orbitrig.cli import app
from orbitrig.service.catalog_feed import CatalogFeed
from support.ports import free_port

SECRET = "s3cret-Pw"


def _urls(sock_dir) -> list[str]:
    port = free_port()
    return [
        f"postgresql://postgres@/postgres?host={sock_dir}&port={port}&password={SECRET}",
        f"postgresql://postgres:{SECRET}@/postgres?host={sock_dir}&port={port}",
    ]


@pytest.mark.parametrize("command", [["catalog", "list"], ["catalog", "export"], ["compare"]])
def test_a_failing_database_is_named_without_its_password(command, tmp_path):
    for url in _urls(tmp_path):
        res = CliRunner().invoke(app, [*command, "--db", url])
        assert res.exit_code == 1, res.output
        assert "error: catalog postgresql://postgres@/postgres?host=" in res.stderr, res.stderr
        assert "port=" in res.stderr and str(tmp_path) in res.stderr  # the server it tried is named
        assert SECRET not in res.output


def test_catalog_add_names_the_database_without_its_password(catalog_run, tmp_path):
    for url in _urls(tmp_path):
        res = CliRunner().invoke(app, ["catalog", "add", str(catalog_run), "--db", url])
        assert res.exit_code == 1 and "cannot open" in res.stderr, res.output
        assert SECRET not in res.output


def test_the_service_feed_logs_the_database_without_its_password(catalog_run, tmp_path, caplog):
    caplog.set_level(logging.WARNING, logger="orbitrig.service.catalog")
    for url in _urls(tmp_path):
        feed = CatalogFeed(url)
        feed.point_completed(catalog_run, 0)
        assert feed.finish(60.0) == []
        assert feed.failed == 1 and feed.added == 0
    logged = [r.getMessage() for r in caplog.records if r.name == "orbitrig.service.catalog"]
    assert len(logged) == 2 and all("point 0 of" in m and "not added" in m for m in logged), logged
    assert all(f"host={tmp_path}" in m for m in logged), logged
    assert not any(SECRET in m for m in logged), logged

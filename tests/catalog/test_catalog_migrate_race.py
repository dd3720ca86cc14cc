"""Processes opening one catalog at the same moment, each bringing it up to this version's
tables on open (orbitrig.catalog.migrate): a catalog of an earlier version (no bearing
columns, no `fits_units`) or an empty database. Every process succeeds, the rows stay, each
new column and unit is there; in SQLite and on a real PostgreSQL server. The processes are
forked and released together by a barrier, many times over, so their changes overlap."""

from __future__ import annotations

import multiprocessing
import time

import pytest
from sqlalchemy import func, inspect, select

from orbitrig.catalog.errors import CatalogError
from orbitrig.catalog.rows import run_rows
from orbitrig.catalog.schema import KEY, UNIT_OF, fits, fits_units
from orbitrig.catalog.store import Catalog
from orbitrig.store.reader import read_run
from support.catalog_earlier import write_earlier_catalog

#: processes opening the catalog at once, and how many times each race is run
OPENERS = 3
ROUNDS = 12


def _open(url: str, barrier, errors) -> None:
    """A process of the race: open the catalog when every opener is ready."""
    barrier.wait(timeout=60)
    try:
        Catalog(url).close()
    except CatalogError as err:  # reported to the parent (any other error: the exit code)
        errors.put(f"{type(err).__name__}: {err}")


def _race(url: str) -> list[str]:
    """Open the catalog at ``url`` in OPENERS forked processes at once; their errors."""
    ctx = multiprocessing.get_context("fork")
    barrier, errors = ctx.Barrier(OPENERS), ctx.Queue()
    procs = [ctx.Process(target=_open, args=(url, barrier, errors)) for _ in range(OPENERS)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(timeout=120)
    found = []
    while not errors.empty():
        found.append(errors.get())
    return found + [f"exit code {p.exitcode}" for p in procs if p.exitcode != 0]


def _check(url: str, rows: list[dict]) -> None:
    """The catalog at ``url`` has this version's tables, every unit and ``rows`` (read only)."""
    cat = Catalog(url, create=False)
    try:
        with cat.engine.connect() as conn:
            assert conn.execute(select(func.count()).select_from(fits)).scalar() == len(rows)
            units = dict(conn.execute(select(fits_units.c.column_name, fits_units.c.unit)).all())
        assert units == UNIT_OF and _values(cat.rows()) == _values(rows)
        assert sorted(c["name"] for c in inspect(cat.engine).get_columns("fits")) == sorted(fits.c.keys())
    finally:
        cat.close()


def _values(rows: list[dict]) -> set[tuple]:
    return {tuple(r[c] for c in (*KEY, "Kxx", "Cyy_U")) for r in rows}


@pytest.fixture(params=["sqlite", "postgresql"])
def catalog_url(request, tmp_path):
    if request.param == "sqlite":
        return f"sqlite:///{tmp_path / 'c.sqlite'}"
    return request.getfixturevalue("postgres_server")


def test_processes_opening_a_catalog_at_once_all_succeed(catalog_url, catalog_run):
    rows = run_rows(read_run(catalog_run))
    failures, started = [], time.monotonic()
    try:
        for attempt in range(ROUNDS):
            for kind, given in (("earlier", rows), ("empty", None)):
                write_earlier_catalog(catalog_url, given)
                failures += [f"round {attempt}, {kind} catalog: {e}" for e in _race(catalog_url)]
                _check(catalog_url, given or [])
    finally:
        Catalog(catalog_url).close()  # the session's server left with this version's tables
    print(f"{ROUNDS} x 2 races of {OPENERS} openers in {time.monotonic() - started:.1f} s", *failures, sep="\n")
    assert failures == []

"""The catalog database (SQLAlchemy Core): open by URL, add rows idempotently, query.

The default URL is an SQLite file ``catalog.sqlite`` next to the runs; a lab points
every rig service and user at one server (``postgresql+psycopg://user@host/db``; a bare
``postgresql://`` URL is given the psycopg 3 driver). Adding a row whose key
(orbitrig.catalog.schema.KEY) is already there replaces it (an upsert: two writers adding
the same rows at once both succeed), in one transaction per call.
"""

from __future__ import annotations

import logging
from enum import StrEnum
from pathlib import Path
from typing import Any, Iterable

from sqlalchemy import create_engine, delete, func, select
from sqlalchemy.engine import Engine, make_url
from sqlalchemy.exc import ArgumentError, SQLAlchemyError

from orbitrig.catalog.errors import CatalogError, CatalogMissingError, CatalogUsageError
from orbitrig.catalog.errors import shown_url as _shown
from orbitrig.catalog.migrate import upgrade
from orbitrig.catalog.schema import KEY, ROW_COLUMNS, fits
from orbitrig.catalog.where import parse_where

#: the default catalog file, in the directory holding the runs
DEFAULT_FILE = "catalog.sqlite"


class _NoEchoOfRaisedError(logging.Filter):
    """Drops psycopg's 'error ignored terminating <psycopg.Pipeline ...>: pipeline aborted' (and
    its 'error ignored in rollback ...'): logged while the error it raises propagates, which the
    catalog reports as a CatalogError naming the database; without logging set up (the CLI) the
    echo was a second line on standard error naming a Python object."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not str(record.msg).startswith("error ignored ")


logging.getLogger("psycopg").addFilter(_NoEchoOfRaisedError())


class Dialect(StrEnum):
    """The databases the catalog supports, by SQLAlchemy's dialect (backend) name."""

    SQLITE = "sqlite"
    POSTGRESQL = "postgresql"


def check_url(url: str, option: str) -> None:
    """CatalogUsageError naming ``option`` when ``url`` is no database URL or one of a database
    the catalog does not support; nothing is connected to (``serve --catalog`` at its start)."""
    try:
        _dialect(url, option)
    except ArgumentError as err:
        raise _not_a_url(option, url, err) from None


def _not_a_url(option: str, url: str, err: Exception) -> CatalogUsageError:
    """The error of a catalog URL given with ``option`` that is no database URL."""
    return CatalogUsageError(f"{option} {_shown(url)}: not a database URL ({err})")


def _dialect(url: str, option: str = "--db") -> Dialect:
    """The dialect of ``url``; CatalogUsageError naming the URL and its database when the
    catalog does not support it (ArgumentError when ``url`` is no database URL)."""
    name = make_url(_driver_url(url)).get_backend_name()
    try:
        return Dialect(name)
    except ValueError:
        supported = " or ".join(d.value for d in Dialect)
        raise CatalogUsageError(
            f"{option} {_shown(url)}: database {name!r} is not supported (use {supported})"
        ) from None


def default_url(runs_dir: Path) -> str:
    """The SQLite catalog next to the runs in ``runs_dir``."""
    return f"sqlite:///{(Path(runs_dir) / DEFAULT_FILE).resolve()}"


def _driver_url(url: str) -> str:
    for bare in ("postgresql://", "postgres://"):
        if url.startswith(bare):
            return "postgresql+psycopg://" + url[len(bare) :]
    return url


class Catalog:
    """One catalog database. Raises CatalogError (URL named) when it cannot be used;
    ``create`` False: an SQLite file that does not exist is such an error (reading a
    catalog never creates one)."""

    def __init__(self, url: str, create: bool = True):
        self.url = url
        try:
            self.dialect = _dialect(url)
            if not create:
                _sqlite_file_exists(url, self.dialect)
            self.engine: Engine = create_engine(_driver_url(url), future=True)
            upgrade(self.engine)  # a new catalog made, one of an earlier version brought up: its rows kept
        except ArgumentError as err:
            raise _not_a_url("--db", url, err) from None
        except (SQLAlchemyError, ImportError) as err:
            raise CatalogError(f"catalog {_shown(url)}: cannot open ({_reason(err)})") from None

    def close(self) -> None:
        self.engine.dispose()

    def add(self, rows: Iterable[dict[str, Any]], run_id: str = "", points: Iterable[int] = ()) -> int:
        """Insert ``rows``, replacing those with the same key; the number of rows written. With
        ``run_id``, first delete (same transaction) every row of run ``run_id`` at ``points``: a
        re-add then leaves of those points only ``rows`` (a point damaged since: none)."""
        by_key = {tuple(row.get(k) for k in KEY): {c: row.get(c) for c in ROW_COLUMNS} for row in rows}
        rows = [by_key[key] for key in sorted(by_key)]  # one order for every writer: no deadlock between two
        stale = sorted(set(points)) if run_id else []
        if not rows and not stale:
            return 0
        try:
            upsert = _upsert(self.dialect)
            with self.engine.begin() as conn:
                if stale:
                    conn.execute(delete(fits).where(fits.c.run_id == run_id, fits.c.point.in_(stale)))
                for start in range(0, len(rows), _BATCH):
                    conn.execute(upsert, rows[start : start + _BATCH])
        except SQLAlchemyError as err:
            raise CatalogError(f"catalog {_shown(self.url)}: cannot add rows ({_reason(err)})") from None
        return len(rows)

    def held_at(self, run_path: str) -> dict[str, int]:
        """How many rows the catalog holds of each run last added from ``run_path`` (a resolved
        run directory), by run_id."""
        query = (
            select(fits.c.run_id, func.count())
            .where(fits.c.run_path == run_path)
            .group_by(fits.c.run_id)
            .order_by(fits.c.run_id)
        )
        try:
            with self.engine.connect() as conn:
                return {run_id: int(n) for run_id, n in conn.execute(query)}
        except SQLAlchemyError as err:
            raise CatalogError(f"catalog {_shown(self.url)}: cannot read ({_reason(err)})") from None

    def rows(self, where: str = "") -> list[dict[str, Any]]:
        """The rows matching the --where filter (docs/catalog.md), by run, point and fit."""
        query = select(*(fits.c[c] for c in ROW_COLUMNS))
        condition = parse_where(where)
        if condition is not None:
            query = query.where(condition)
        query = query.order_by(*(fits.c[k] for k in ("created", *KEY)))
        try:
            with self.engine.connect() as conn:
                return [dict(r._mapping) for r in conn.execute(query)]
        except SQLAlchemyError as err:
            raise CatalogError(f"catalog {_shown(self.url)}: cannot read ({_reason(err)})") from None


#: rows per statement batch (each row binds len(ROW_COLUMNS) parameters; PostgreSQL takes 65535)
_BATCH = 500


def _upsert(dialect: Dialect) -> Any:
    """INSERT ... ON CONFLICT (KEY) DO UPDATE of every other column, for ``dialect``."""
    stmt: Any  # the dialect's own Insert; both have on_conflict_do_update and excluded
    if dialect is Dialect.POSTGRESQL:
        from sqlalchemy.dialects.postgresql import insert as postgresql_insert

        stmt = postgresql_insert(fits)
    else:
        from sqlalchemy.dialects.sqlite import insert as sqlite_insert

        stmt = sqlite_insert(fits)
    return stmt.on_conflict_do_update(
        index_elements=[fits.c[k] for k in KEY],
        set_={c: stmt.excluded[c] for c in ROW_COLUMNS if c not in KEY},
    )


def _sqlite_file_exists(url: str, dialect: Dialect) -> None:
    """Raise CatalogError naming the file when ``url`` is an SQLite file that does not exist."""
    name = make_url(url).database or ""
    if dialect is Dialect.SQLITE and name not in ("", ":memory:") and not name.startswith("file:"):
        if not Path(name).is_file():
            raise CatalogMissingError(f"catalog {name}: no such file (`orbitrig catalog add RUN` creates it)")


def _reason(err: Exception) -> str:
    orig = getattr(err, "orig", None)
    return str(orig or err).strip().splitlines()[0]

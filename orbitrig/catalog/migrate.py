"""A catalog brought up to the tables of this version when it is opened: the tables made
when missing, each column ``fits`` lacks added (``ALTER TABLE fits ADD COLUMN``, NULL in the
rows already there; no row is touched otherwise; `catalog add RUN` again fills the new
columns of that run's rows), and ``fits_units`` made to list the unit of every column of
this version.

A catalog already up to date is only read. Otherwise the change is one transaction under
the database's write lock (PostgreSQL: a transaction-level advisory lock; SQLite: ``BEGIN
IMMEDIATE``) that looks again before it writes: processes opening one catalog at once
all succeed, the first one changing it.

A catalog a newer version has written (``fits_units`` names a column this version does not
know) keeps that version's units: this version only adds the units of its own columns
missing there, and never deletes a unit (docs/catalog.md).
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import inspect, select
from sqlalchemy.engine import Connection, Engine

from orbitrig.catalog.schema import UNIT_OF, fits, fits_units, metadata

#: the PostgreSQL advisory lock key held while a catalog is changed (any 64-bit number; "orbitcat")
_LOCK_KEY = 0x6F72626974636174


def upgrade(engine: Engine) -> None:
    """Bring the catalog at ``engine`` up to this version (module docstring); writes nothing
    when it is up to date."""
    with engine.connect() as conn:
        if not _needed(conn):
            return
    with engine.begin() as conn:
        _lock(conn)
        if _needed(conn):  # another process may have changed it while this one waited
            metadata.create_all(conn)
            _add_columns(conn)
            _write_units(conn)


def missing_columns(conn: Connection) -> list[str]:
    """The columns of ``fits`` the database's table does not have (none without the table)."""
    inspector = inspect(conn)
    if not inspector.has_table(fits.name):
        return []
    have = {c["name"] for c in inspector.get_columns(fits.name)}
    return [c.name for c in fits.columns if c.name not in have]


def units_to_write(stored: dict[str, str]) -> dict[str, str]:
    """The units ``fits_units`` lacks, ``stored`` being what it holds: every unit of UNIT_OF
    that is missing or differs; only the missing ones when ``stored`` names a column this
    version does not know (a newer version wrote it: its units stand)."""
    newer = not set(stored) <= set(UNIT_OF)
    return {c: u for c, u in UNIT_OF.items() if c not in stored or (not newer and stored[c] != u)}


def _needed(conn: Connection) -> bool:
    inspector = inspect(conn)
    if not all(inspector.has_table(t.name) for t in metadata.sorted_tables):
        return True
    return bool(missing_columns(conn) or units_to_write(_stored_units(conn)))


def _lock(conn: Connection) -> None:
    """Hold the catalog's write lock until ``conn``'s transaction ends."""
    if conn.dialect.name == "postgresql":
        conn.exec_driver_sql(f"SELECT pg_advisory_xact_lock({_LOCK_KEY})")
    else:  # SQLite: the database's write lock now (waiting up to the driver's busy timeout, 5 s)
        conn.exec_driver_sql("BEGIN IMMEDIATE")


def _add_columns(conn: Connection) -> None:
    preparer = conn.dialect.identifier_preparer
    for name in missing_columns(conn):
        sql_type = fits.c[name].type.compile(dialect=conn.dialect)
        conn.exec_driver_sql(f"ALTER TABLE {preparer.quote(fits.name)} ADD COLUMN {preparer.quote(name)} {sql_type}")


def _stored_units(conn: Connection) -> dict[str, str]:
    return dict(conn.execute(select(fits_units.c.column_name, fits_units.c.unit)).all())


def _write_units(conn: Connection) -> None:
    units = units_to_write(_stored_units(conn))
    if not units:
        return
    stmt: Any  # the dialect's own Insert; both have on_conflict_do_update and excluded
    if conn.dialect.name == "postgresql":
        from sqlalchemy.dialects.postgresql import insert as postgresql_insert

        stmt = postgresql_insert(fits_units)
    else:
        from sqlalchemy.dialects.sqlite import insert as sqlite_insert

        stmt = sqlite_insert(fits_units)
    upsert = stmt.on_conflict_do_update(index_elements=[fits_units.c.column_name], set_={"unit": stmt.excluded.unit})
    conn.execute(upsert, [{"column_name": c, "unit": u} for c, u in units.items()])

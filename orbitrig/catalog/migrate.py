"""An existing catalog brought up to the tables of this version: each column ``fits`` lacks
is added (``ALTER TABLE fits ADD COLUMN``, NULL in the rows already there; no row is
touched otherwise; `catalog add RUN` again fills the new columns of that run's rows), and
``fits_units`` is made to list every column's unit.
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import inspect, select
from sqlalchemy.engine import Engine
from sqlalchemy.exc import OperationalError, ProgrammingError

from orbitrig.catalog.schema import UNIT_OF, fits, fits_units


def missing_columns(engine: Engine) -> list[str]:
    """The columns of ``fits`` the database's table does not have (none without the table)."""
    inspector = inspect(engine)
    if not inspector.has_table(fits.name):
        return []
    have = {c["name"] for c in inspector.get_columns(fits.name)}
    return [c.name for c in fits.columns if c.name not in have]


def add_missing_columns(engine: Engine) -> list[str]:
    """Add the columns the table lacks; the names added. Two processes doing it at once
    both succeed (the second finds the column there)."""
    missing = missing_columns(engine)
    preparer = engine.dialect.identifier_preparer
    for name in missing:
        column = fits.c[name]
        sql_type = column.type.compile(dialect=engine.dialect)
        statement = f"ALTER TABLE {preparer.quote(fits.name)} ADD COLUMN {preparer.quote(name)} {sql_type}"
        try:
            with engine.begin() as conn:
                conn.exec_driver_sql(statement)
        except (OperationalError, ProgrammingError):
            if name not in missing_columns(engine):
                continue  # another writer added it meanwhile
            raise
    return missing


def write_units(engine: Engine) -> None:
    """Make ``fits_units`` hold UNIT_OF (written only when it differs: reading a catalog of
    this version writes nothing)."""
    with engine.connect() as conn:
        stored = dict(conn.execute(select(fits_units.c.column_name, fits_units.c.unit)).all())
    if stored == UNIT_OF:
        return
    stmt: Any  # the dialect's own Insert; both have on_conflict_do_update and excluded
    if engine.dialect.name == "postgresql":
        from sqlalchemy.dialects.postgresql import insert as postgresql_insert

        stmt = postgresql_insert(fits_units)
    else:
        from sqlalchemy.dialects.sqlite import insert as sqlite_insert

        stmt = sqlite_insert(fits_units)
    upsert = stmt.on_conflict_do_update(index_elements=[fits_units.c.column_name], set_={"unit": stmt.excluded.unit})
    with engine.begin() as conn:  # an upsert: two processes opening the catalog at once both succeed
        conn.execute(upsert, [{"column_name": c, "unit": u} for c, u in UNIT_OF.items()])

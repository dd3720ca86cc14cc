"""An existing catalog brought up to the table ``fits`` of this version: each column it lacks
is added (``ALTER TABLE fits ADD COLUMN``, NULL in the rows already there; no row is
touched otherwise). `catalog add RUN` again fills the new columns of that run's rows.
"""

from __future__ import annotations

from sqlalchemy import inspect
from sqlalchemy.engine import Engine
from sqlalchemy.exc import OperationalError, ProgrammingError

from orbitrig.catalog.schema import fits


def missing_columns(engine: Engine) -> list[str]:
    """The columns of ``fits`` the database's table does not have (all when it has no table)."""
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

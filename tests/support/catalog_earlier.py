"""A catalog as an earlier orbitrig left it: `fits` without the bearing columns and no
`fits_units` table, holding some rows (orbitrig.catalog.migrate brings it up on open)."""

from __future__ import annotations

from typing import Any

from sqlalchemy import Column, MetaData, Table, UniqueConstraint, create_engine

from orbitrig.catalog.bearing import BEARING_COLUMNS
from orbitrig.catalog.schema import KEY, fits
from orbitrig.catalog.store import _driver_url

#: the columns `fits` gained with the bearing
NEW = BEARING_COLUMNS


def earlier_table(metadata: MetaData) -> Table:
    """`fits` as the catalog had it before the bearing columns."""
    columns = [Column(c.name, c.type, primary_key=c.primary_key) for c in fits.columns if c.name not in NEW]
    return Table("fits", metadata, *columns, UniqueConstraint(*KEY, name="fits_key"))


def write_earlier_catalog(url: str, rows: list[dict[str, Any]] | None) -> int:
    """Replace the catalog at ``url`` by an earlier one holding ``rows`` (their new columns
    dropped; None: by no table at all, an empty database); the number of rows written."""
    engine = create_engine(_driver_url(url))
    try:
        with engine.begin() as conn:
            conn.exec_driver_sql("DROP TABLE IF EXISTS fits_units")
            conn.exec_driver_sql("DROP TABLE IF EXISTS fits")
        if rows is None:
            return 0
        earlier = earlier_table(MetaData())
        earlier.create(engine)
        with engine.begin() as conn:
            conn.execute(earlier.insert(), [{k: v for k, v in r.items() if k not in NEW} for r in rows])
    finally:
        engine.dispose()
    return len(rows)

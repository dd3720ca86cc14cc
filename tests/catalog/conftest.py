from __future__ import annotations

from pathlib import Path

import pytest

from support.pg_server import postgres_server  # noqa: F401 - fixture
from orbitrig.catalog.store import Catalog
from support.report_synthetic import write_synthetic_run

PROVENANCE = {
    "operator": "alice",
    "software_version": "orbitrig test",
    "rig_id": "rigA",
    "calibration_record": "2026-01-01.toml",
    "calibration_record_sha256": "ab" * 32,
    "host": "bench",
    "started": "2026-11-26T10:00:00+00:00",
}


@pytest.fixture(scope="session")
def catalog_run(tmp_path_factory) -> Path:
    """Two complete points (static eccentricity 0 and 0.15), four fits per load system, provenance."""
    return write_synthetic_run(
        tmp_path_factory.mktemp("catalog") / "runs" / "run1", incomplete=0, provenance=PROVENANCE
    )


@pytest.fixture(params=["sqlite", "postgresql"])
def catalog(request, tmp_path):
    """An empty catalog in an SQLite file, then on a real PostgreSQL server."""
    if request.param == "sqlite":
        url = f"sqlite:///{tmp_path / 'c.sqlite'}"
    else:
        url = request.getfixturevalue("postgres_server")
    cat = Catalog(url)
    with cat.engine.begin() as conn:  # the server lives for the session: start each test empty
        conn.exec_driver_sql("DELETE FROM fits")
    yield cat
    cat.close()

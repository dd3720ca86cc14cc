"""Catalog rows of a made-up campaign: repeated runs over static eccentricity, each
coefficient drawn around a known law with its stated U (k = 2)."""

from __future__ import annotations

import numpy as np

from orbitrig.catalog.rows import COEFFICIENTS
from orbitrig.catalog.schema import ROW_COLUMNS

ECCENTRICITIES = (0.0, 0.1, 0.2, 0.3, 0.4)
U_REL = 0.02  # expanded uncertainty relative to the value


def law(name: str, eps: float) -> float:
    """The 'true' coefficient (SI) at static eccentricity eps."""
    base = {"K": 3.2e7, "C": 5.0e4, "D": 20.0}[name[0]]
    cross = -1.0 if name[1:] == "yx" else (0.12 if name[1] != name[2] else 1.0)
    return base * cross * (1.0 + 1.5 * eps**2)


def campaign_rows(n_runs: int = 3, rng=None, scatter: float = 1.0) -> list[dict]:
    """Rows of n_runs runs at every eccentricity; values scattered by `scatter` x U/2."""
    rng = rng or np.random.default_rng(7)
    rows = []
    for run in range(n_runs):
        for point, eps in enumerate(ECCENTRICITIES):
            row = dict.fromkeys(ROW_COLUMNS)
            row.update(
                run_id=f"rigA@2026-11-2{run}T10:00:00+00:00",
                created=f"2026-11-2{run}T10:00:00+00:00",
                point=point,
                lms="piezo",
                model="kcd11",
                freq_dep="none",
                method="ols",
                ok=True,
                spin=104.72,
                spin_rpm=1000.0,
                recess_pressure=482600.0,
                pressure_ratio=0.25,
                static_eccentricity=eps,
                dynamic_eccentricity=0.04,
                run_path=f"/runs/{run}",
            )
            for name in COEFFICIENTS:
                true, u = law(name, eps), abs(law(name, eps)) * U_REL
                row[name], row[f"{name}_U"] = true + scatter * u / 2 * rng.standard_normal(), u
            rows.append(row)
    return rows

"""The catalog takes u = U / k with each coefficient's own k (coefficients_json "k_values": the
sweep's combined U at its effective dof), a row stored before them its one k."""

from __future__ import annotations

import json

from orbitrig.catalog.compare import _values_and_u, coverage
from orbitrig.catalog.compare_plot import bars_text


def _row(stored: dict, **cells) -> dict:
    return {"coefficients_json": json.dumps(stored), **cells}


def test_u_is_u_over_the_coefficients_own_k():
    row = _row({"k": 3.31, "k_values": {"Kxx": 3.31, "Kxy": 2.0}}, Kxx=1e7, Kxx_U=3.31e5, Kxy=2e6, Kxy_U=2e5)
    assert coverage(row, "Kxx") == 3.31 and coverage(row, "Kxy") == 2.0
    (pair,), statistical = _values_and_u([row], "Kxy")
    assert not statistical and pair == (2e6, 1e5)  # U / its own k, not U / the largest (3.31)
    assert bars_text([row]) == "bars: expanded uncertainty U (each fit's k: 2, 3.31)"
    old = _row({"k": 2.87}, Kxx=1e7, Kxx_U=2.87e5)
    assert coverage(old, "Kxx") == 2.87 and bars_text([old]) == "bars: expanded uncertainty U (k = 2.87)"

"""`not_determined` is one rule in `orbitrig identify` and in the sweep (orbit-table v3: the
expanded uncertainty exceeds the magnitude; orbitrig's k is reduction.statistics.coverage_factor,
2 with the stated u_*): a coefficient estimated at 1.98 standard errors is not determined in
both, one at 2.05 standard errors in neither (a 1.96 half-width would call both determined)."""

from __future__ import annotations

import numpy as np

from support.reduction_synthetic import frequencies, orbit_table, truth
from orbitrig.config import ModelSpec
from orbitrig.load_systems import LoadSystem
from orbitrig.run.point_analysis import analyse_point
from reduction.identify import identify
from reduction.statistics import coverage_factor
from reduction.table import OrbitTable


def _table(true: dict, s: float = 5.0) -> OrbitTable:
    """The noise-free table of `true` with stated force uncertainties u_fx = u_fy = `s` (N; the
    covariance is known, so an ols estimate is the truth and its std the design's)."""
    clean = orbit_table(true, frequencies(8))
    u = np.tile([0.0, 0.0, s, s], (clean.n, 1))
    return OrbitTable(clean.spin, clean.orbit, clean.x, clean.y, clean.fx, clean.fy, None, np.full(clean.n, 50), u)


def test_between_1_96_and_2_standard_errors_is_not_determined_in_identify_and_sweep() -> None:
    true = truth("kc8", {"K": (0,), "C": (0,)})
    std = identify(_table(true), model="kc8").std_errors
    true[("K", 0)] = true[("K", 0)].copy()
    true[("K", 0)][0, 1] = 1.98 * std["Kxy"]  # 1.96 sigma < |value| < 2 sigma: U = 2 sigma exceeds it
    true[("K", 0)][1, 0] = -2.05 * std["Kyx"]  # beyond 2 sigma: determined
    table = _table(true)
    ident = identify(table, model="kc8")
    assert ident.interval == "normal" and coverage_factor(ident.interval, ident.dof) == 2.0
    ratio = {k: abs(ident.coefficients[k]) / ident.std_errors[k] for k in ("Kxy", "Kyx")}
    assert 1.97 < ratio["Kxy"] < 1.99 and 2.04 < ratio["Kyx"] < 2.06, ratio
    assert "Kxy" in ident.not_determined and "Kyx" not in ident.not_determined
    assert ident.not_determined == ["Kxy"]

    spec = ModelSpec(model="kc8")
    lms = LoadSystem("piezo")
    idents = {(lms, spec.key): {"spec": spec, "json": ident.to_dict()}}
    analyse_point(table.spin, {lms: table}, {(lms, spec.key): ident}, idents, None, np.unique(np.abs(table.orbit)))
    d = idents[(lms, spec.key)]["json"]
    assert d["expanded_uncertainty"]["k"] == 2.0 and d["expanded_uncertainty"]["basis"] == "statistical"
    assert d["not_determined"] == ident.not_determined == ["Kxy"]

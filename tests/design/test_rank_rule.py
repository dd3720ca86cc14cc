"""One rule of whether a list of orbit frequencies identifies a model
(reduction.rank.determined_rank): identify, the predicted covariance of a design, the
prediction of a list and a list's Fisher information refuse alike. Hand-made cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from reduction.design import design_orbits, predicted_covariance
from reduction.errors import IdentifiabilityError
from reduction.frequency_list import DesignProblem, predict
from reduction.identify import identify
from reduction.impedance import forces, impedance
from reduction.information import predicted_errors
from reduction.models import model_spec
from reduction.rank import RANK_RTOL, design_rank, determined_rank
from reduction.table import OrbitTable

SPIN = 1000 * 2 * math.pi / 60
RADIUS = 6e-6
U = np.array([100e-9, 100e-9, 20.0, 20.0])  # per revolution x, y (m), fx, fy (N)
# kcd11 at the nominal bearing (N/m, N s/m, kg)
THETA = np.array([3.8e7, 6e6, -6e6, 4e7, 1e5, 2e3, 2e3, 1.1e5, 4.0, 0.05, 4.2])
KD = ["Kxx + 0.0003648*Dxx", "Kxy + Kyx + 0.0003648*Dxy", "Kyy + 0.0003648*Dyy"]


def test_determined_rank_counts_singular_values_above_1e_7_of_the_largest():
    assert RANK_RTOL == 1e-7
    assert determined_rank([2.0, 1.0, 2e-7]) == 2  # at the cut: null
    assert determined_rank([2.0, 1.0, 2.0000001e-7]) == 3
    assert determined_rank([1.0, 1e-9], rtol=0.0) == 2  # any nonzero one (the reference's rank)
    assert determined_rank(np.zeros(3)) == 0 and determined_rank([]) == 0


def test_a_list_of_condition_number_1e9_is_refused_by_design_and_by_identify_alike():
    """Two ratios 1e-9 apart: kcd11's K and Omega^2 D are both in the real part of Z, so at
    (nearly) one |Omega| only K + Omega^2 D is seen. Condition number ~1e9 - between identify's
    1e7 and the 1e-12 singular-value cut the design once used, so `orbitrig design` showed
    finite errors for data identify refuses. Now the prediction, the covariance, the
    information and identify all refuse, naming the same undetermined combinations."""
    spec = model_spec("kcd11")
    ratios = [0.5, 0.5 + 1e-9]
    orbit, x, y = design_orbits(np.asarray(ratios) * SPIN / (2 * np.pi), "both", RADIUS)
    cond = design_rank(spec, orbit, x, y, 0.0).condition_number
    assert 3e8 < cond < 3e9

    fx, fy = forces(impedance(spec, THETA, orbit), x, y)
    with pytest.raises(IdentifiabilityError) as refused:
        identify(OrbitTable(SPIN, orbit, x, y, fx, fy), "kcd11")
    assert refused.value.combinations == KD

    u = U / math.sqrt(50)
    with pytest.raises(IdentifiabilityError) as design:
        predicted_covariance(spec, orbit, x, y, u, THETA, "the list")
    assert design.value.combinations == KD
    assert str(design.value).startswith(
        "the list cannot identify kcd11 none: Kxx, Kxy, Kyx, Kyy, Dxx, Dxy, Dyy undetermined (the forces do not "
        "change when the coefficients move along Kxx + 0.0003648*Dxx; "
    )

    pred = predict(DesignProblem(spec, THETA, SPIN, RADIUS, U, 50), ratios)
    assert pred.std_errors is None and pred.worst == math.inf
    assert pred.refusal is not None
    assert pred.refusal.startswith("the list (ratios 0.5, 0.500000001) cannot identify kcd11 none: Kxx, Kxy")

    # the allocation's and the sequential design's test: the list's Fisher information
    Aw = _weighted_rows(spec, orbit, x, y, u)
    se = predicted_errors(Aw.T @ Aw)
    undetermined = [n for n, e in zip(spec.names, se) if not np.isfinite(e)]
    assert undetermined == ["Kxx", "Kxy", "Kyx", "Kyy", "Dxx", "Dxy", "Dyy"]


def test_a_list_just_inside_the_rule_keeps_its_figures():
    """1e-6 apart (condition number ~1e6 < 1e7): identified by identify, and the design's
    covariance is the inverse of the list's information (the figures of a well-conditioned
    list are what they were)."""
    spec = model_spec("kcd11")
    ratios = [0.5, 0.5 + 1e-6]
    orbit, x, y = design_orbits(np.asarray(ratios) * SPIN / (2 * np.pi), "both", RADIUS)
    assert design_rank(spec, orbit, x, y).deficiency == 0
    fx, fy = forces(impedance(spec, THETA, orbit), x, y)
    assert identify(OrbitTable(SPIN, orbit, x, y, fx, fy), "kcd11").coefficients["Kxx"] == pytest.approx(
        3.8e7, rel=1e-3
    )
    u = U / math.sqrt(50)
    cov = predicted_covariance(spec, orbit, x, y, u, THETA)
    pred = predict(DesignProblem(spec, THETA, SPIN, RADIUS, U, 50), ratios)
    assert pred.refusal is None and pred.std_errors == pytest.approx(np.sqrt(np.diag(cov)), rel=1e-12)


def _weighted_rows(spec, orbit, x, y, u):
    from reduction.impedance import real_rows, regressors
    from reduction.noise import equation_variances

    A = real_rows(regressors(spec, orbit, x, y))
    var = equation_variances(np.broadcast_to(u, (orbit.size, 4)), impedance(spec, THETA, orbit))
    return A / np.sqrt(var)[:, None]

"""reduction.frequency_list: the grid, the exchange search, the target, rig-time figures."""

from __future__ import annotations

import math

import numpy as np
import pytest

from orbitrig.cli.design_inputs import NOMINAL
from reduction.design import design_orbits, predicted_covariance
from reduction.errors import ReductionError
from reduction.frequency_list import (
    DesignProblem,
    acquisition_time,
    allowed_ratios,
    best_list,
    coefficient_scales,
    predict,
    propose,
    revolutions_for,
    time_to_target,
)
from reduction.models import model_spec

SPIN = 1000 * 2 * math.pi / 60
PAPER = [round(0.2 + k / 9, 6) for k in range(10)]


def problem(model="kcd11", revolutions=50, **kw) -> DesignProblem:
    spec = model_spec(model)
    theta = np.array([NOMINAL.get(n, 0.0) for n in spec.names])
    return DesignProblem(spec, theta, SPIN, 6e-6, np.array([100e-9, 100e-9, 20.0, 20.0]), revolutions, **kw)


def test_grid_keeps_away_from_synchronous_whirl():
    grid = allowed_ratios(0.1, 1.5)
    assert grid[0] == pytest.approx(0.1) and grid[-1] == pytest.approx(1.5)
    assert np.all(np.abs(grid - 1) >= 0.1 - 1e-9) and 0.9 in np.round(grid, 6) and 0.95 not in np.round(grid, 6)
    with pytest.raises(ReductionError):
        allowed_ratios(0.95, 1.05)


def test_prediction_is_the_cramer_rao_bound_at_u_over_sqrt_n():
    p = problem()
    pred = predict(p, PAPER)
    orbit, x, y = design_orbits(np.array(PAPER) * SPIN / (2 * math.pi), "both", 6e-6)
    cov = predicted_covariance(p.spec, orbit, x, y, p.u_revolution / math.sqrt(50), theta=p.theta)
    assert pred.std_errors == pytest.approx(np.sqrt(np.diag(cov)), rel=1e-12)
    scales = coefficient_scales(p.spec, p.theta, SPIN)
    assert scales[p.spec.names.index("Kxy")] == pytest.approx(math.sqrt((3.8e7**2 + 4.0e7**2) / 2))
    assert pred.worst == pytest.approx(np.max(pred.std_errors / scales))
    four = predict(problem(revolutions=200), PAPER)
    assert four.std_errors == pytest.approx(pred.std_errors / 2, rel=1e-9)
    assert predict(p, [0.5]).worst == math.inf  # 8 equations for 11 coefficients


def test_exchange_lowers_the_worst_error_and_stays_on_the_grid():
    p = problem()
    grid = allowed_ratios(0.2, 1.2)
    best, evaluated = best_list(p, grid, 10)
    assert best.worst < 0.9 * predict(p, PAPER).worst
    assert set(np.round(best.ratios, 6)) <= set(np.round(grid, 6)) and len(set(best.ratios)) == 10
    assert evaluated > 10
    # no single move improves the result (a local optimum of the exchange)
    for i in range(10):
        for g in grid:
            if g in best.ratios:
                continue
            trial = list(best.ratios)
            trial[i] = g
            assert predict(p, trial).worst >= best.worst * (1 - 1e-9)


def test_target_in_the_least_rig_time():
    p = problem("kc8")
    grid = allowed_ratios(0.2, 1.2)
    paper = predict(p, PAPER)
    prop = propose(p, grid, target=paper.worst, block_overhead=2.05)
    n = revolutions_for(prop.best, 50, paper.worst)
    assert predict(problem("kc8", n), prop.best.ratios).worst <= paper.worst * (1 + 1e-9)
    t_prop = time_to_target(p, prop.best, paper.worst, block_overhead=2.05)
    assert t_prop < time_to_target(p, paper, paper.worst, block_overhead=2.05)
    assert t_prop == pytest.approx(acquisition_time(prop.best.ratios, SPIN, n) + 4 * len(prop.best.ratios) / 2 * 2.05)


def test_reference_scales_and_measured_noise_per_ratio():
    p = problem()
    paper = predict(p, PAPER)
    relative_to_paper = predict(problem(scales=paper.std_errors), PAPER)
    assert relative_to_paper.relative == pytest.approx(np.ones(11))
    measured = problem(noise_ratios=np.array([0.2, 1.2]))
    measured = DesignProblem(
        p.spec,
        p.theta,
        SPIN,
        6e-6,
        np.array([[1e-7, 1e-7, 10, 10], [3e-7, 3e-7, 30, 30]]),
        noise_ratios=np.array([0.2, 1.2]),
    )
    assert measured.noise_at([0.1, 0.7, 2.0]) == pytest.approx(
        np.array([[1e-7, 1e-7, 10, 10], [2e-7, 2e-7, 20, 20], [3e-7, 3e-7, 30, 30]])
    )


def test_acquisition_time():
    assert acquisition_time([0.5, 1.0], SPIN, 10) == pytest.approx(
        2 * 11 * (2 * math.pi / (0.5 * SPIN) + 2 * math.pi / SPIN)
    )
    assert acquisition_time([0.5], SPIN, [20], "forward") == pytest.approx(21 * 2 * math.pi / (0.5 * SPIN))

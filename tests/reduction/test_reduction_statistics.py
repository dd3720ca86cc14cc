"""The v2 statistics of one fit: covariance and intervals, chi2 with u_*, warnings,
the frequency-dependence verdict and the predicted (Cramer-Rao) covariance of a design."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from support.reduction_synthetic import frequencies, keys_of, orbit_table, truth
from reduction.adequacy import frequency_dependence
from reduction.design import design_orbits, predicted_covariance
from reduction.errors import IdentifiabilityError, ReductionError
from reduction.identify import identify
from reduction.models import model_spec
from reduction.table import OrbitTable

TRUE = truth("kc8", {"K": (0,), "C": (0,)})


def _noisy(true=TRUE, n_freq=8, rel=0.01, seed=0, with_u=True, u_scale=1.0):
    rng = np.random.default_rng(seed)
    clean = orbit_table(true, frequencies(n_freq))
    s = rel * np.sqrt(np.mean(np.abs(clean.fx) ** 2))
    noise = s / np.sqrt(2) * (rng.standard_normal((2, clean.n)) + 1j * rng.standard_normal((2, clean.n)))
    u = np.tile([0.0, 0.0, s * u_scale, s * u_scale], (clean.n, 1)) if with_u else None
    return OrbitTable(
        clean.spin,
        clean.orbit,
        clean.x,
        clean.y,
        clean.fx + noise[0],
        clean.fy + noise[1],
        None,
        np.full(clean.n, 50) if with_u else None,
        u,
    )


def test_covariance_intervals_and_dof():
    r = identify(_noisy(with_u=False), "kc8")
    assert r.dof == 4 * 16 - 8 and r.free == model_spec("kc8").names and r.chi2 is None
    std = np.sqrt(np.diag(r.covariance))
    assert [r.std_errors[k] for k in r.free] == pytest.approx(std, rel=1e-12)
    t = stats.t.ppf(0.975, r.dof)
    lo, hi = r.confidence_95["Kxx"]
    assert (hi - lo) / 2 == pytest.approx(t * r.std_errors["Kxx"], rel=1e-12)
    assert "chi2" not in r.to_dict()


def test_stated_uncertainties_give_the_covariance_and_an_honest_chi2():
    r = identify(_noisy(), "kc8")
    assert r.known_noise and r.chi2 == pytest.approx(r.dof, abs=4 * np.sqrt(2 * r.dof))
    assert 0.001 < r.p_value < 0.999 and r.warnings == []
    d = r.to_dict()
    assert d["chi2"] == r.chi2 and d["p_value"] == r.p_value
    # understated u_* (a third of the noise): chi2 far too large, a warning says so
    bad = identify(_noisy(u_scale=1 / 3), "kc8")
    assert bad.p_value < 1e-3 and any(w.startswith("bad fit: chi2") for w in bad.warnings)
    # the covariance comes from u_*: three times smaller u_*, three times smaller std errors
    assert bad.std_errors["Kxx"] == pytest.approx(r.std_errors["Kxx"] / 3, rel=1e-6)


def test_aic_and_bic_prefer_the_true_model():
    true = truth("kc8", {"K": (0, 1), "C": (0, 1)})
    table = _noisy(true, n_freq=10, rel=0.002)
    const, dep = identify(table, "kc8"), identify(table, "kc8", "power:1")
    assert dep.aic < const.aic and dep.bic < const.bic
    a = frequency_dependence(const, dep)
    assert a.supported and a.test == "likelihood ratio" and a.p_value < 1e-6
    # p underflows here (chi2 difference ~1e5 on 8 dof): told below the floor, never "p = 0"
    assert a.verdict == "frequency dependence supported: yes (p < 1e-300)" and a.p_value == 0.0


def test_frequency_dependence_not_supported_on_constant_data():
    table = _noisy(with_u=False, seed=3)
    a = frequency_dependence(identify(table, "kc8"), identify(table, "kc8", "poly:2"))
    assert a.test == "F" and a.dof == (16, 4 * 16 - 24)
    assert a.verdict == f"frequency dependence supported: no (p = {a.p_value:.3g})" and a.p_value > 0.05
    with pytest.raises(ReductionError, match="not nested"):
        frequency_dependence(identify(table, "kc8", "poly:2"), identify(table, "kc8"))


def test_predicted_covariance_of_a_design_scales_with_noise_and_radius():
    spec = model_spec("kc8")
    orbit, x, y = design_orbits(frequencies(6), "both", 5e-6)
    assert orbit.size == 12 and np.all(np.imag(np.conj(x[::2]) * y[::2]) < 0)  # forward first
    c1 = predicted_covariance(spec, orbit, x, y, [0, 0, 1.0, 1.0])
    c2 = predicted_covariance(spec, orbit, 2 * x, 2 * y, [0, 0, 1.0, 1.0])
    np.testing.assert_allclose(c2, c1 / 4, rtol=1e-10)  # twice the radius: half the std
    # hand check: with forward and backward circles at every frequency the Kxx column (-x in the
    # fx equations) is orthogonal to the others, so var(Kxx) = (u^2 / 2) / (R^2 * rows)
    n = orbit.size
    assert np.sqrt(c1[0, 0]) == pytest.approx(np.sqrt(0.5 / (25e-12 * n)), rel=1e-9)
    with pytest.raises(IdentifiabilityError, match="the design cannot identify kc8 power:1: Kxx_1, ") as refused:
        fwd = design_orbits(frequencies(6), "forward", 5e-6)  # forward only: identify's refusal, named
        predicted_covariance(model_spec("kc8", "power:1"), *fwd, [0, 0, 1.0, 1.0])
    assert refused.value.combinations == ["Kxx_1 - Cxy", "Kxy_1 + Cxx", "Kyx_1 - Cyy", "Kyy_1 + Cyx"]
    with pytest.raises(ReductionError, match="need at least 2 orbit frequencies"):  # 4 equations, 8 unknowns
        predicted_covariance(spec, *design_orbits(frequencies(1), "forward", 5e-6), [0, 0, 1.0, 1.0])
    with pytest.raises(ReductionError, match="theta"):
        predicted_covariance(spec, orbit, x, y, [1e-9, 1e-9, 1.0, 1.0])
    theta = np.array([keys_of(TRUE)[k] for k in spec.names])
    c3 = predicted_covariance(spec, orbit, x, y, [1e-8, 1e-8, 1.0, 1.0], theta)
    assert np.all(np.diag(c3) > np.diag(c1))  # displacement noise adds


def test_a_p_that_underflowed_is_told_below_the_floor_never_as_zero():
    """chi2 = 6030 on 32 dof has p far below the smallest double: 'p < 1e-300', not 'p = 0' (which
    would call the result impossible); the verdict of the adequacy test says it the same way."""
    import dataclasses

    from reduction.adequacy import Adequacy
    from reduction.statistics import chi2_p_value, chi2_tail, chi2_warning, p_text

    p = chi2_p_value(6030.0, 32)
    assert p == 0.0
    assert chi2_tail(6030.0, 32, p) == "p < 1e-300"
    assert "(p < 1e-300)" in chi2_warning(6030.0, 32, p)
    assert chi2_tail(60.0, 32, chi2_p_value(60.0, 32)) == f"p = {stats.chi2.sf(60.0, 32):.2g}"
    assert p_text(float("nan")) == "p = -" and p_text(4.47e-149, 3) == "p = 4.47e-149"
    a = Adequacy(True, 0.0, 9000.0, "likelihood ratio", (7, 0), 0.05, (1.0, 0.5), (1.0, 0.5))
    assert a.verdict == "frequency dependence supported: yes (p < 1e-300)"
    assert dataclasses.replace(a, p_value=0.012).verdict == "frequency dependence supported: yes (p = 0.012)"

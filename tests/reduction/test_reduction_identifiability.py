"""Refusals: too few frequencies and rank-deficient regressions, with named combinations."""

from __future__ import annotations

import numpy as np
import pytest

from support.reduction_synthetic import frequencies, orbit_table, truth
from reduction.errors import IdentifiabilityError
from reduction.rank import numerical_rank
from reduction.identify import identify
from reduction.impedance import regression
from reduction.models import model_spec, parse_freq_dep


def _table(model, freq_dep, n, shapes=("forward", "backward")):
    return orbit_table(truth(model, parse_freq_dep(freq_dep).orders), frequencies(n), shapes)


def test_too_few_frequencies():
    table = _table("kcd11", "none", 1)  # fwd + bwd at one frequency: 8 equations, 11 unknowns
    with pytest.raises(IdentifiabilityError) as info:
        identify(table, "kcd11")
    msg = str(info.value)
    assert "too few orbit frequencies" in msg and "at least 3" in msg and "has 2" in msg
    assert len(info.value.combinations) == 3
    assert "more distinct orbit frequencies" in msg


def test_a_table_without_any_orbit_is_refused_naming_that_not_the_orbit_shape():
    """All displacements zero: rank 0. The hint read 'non-circular (elliptical) orbits separate
    11 of these directions', which no ellipse of zero size would."""
    t = _table("kcd11", "none", 4)
    zero = np.zeros(t.n, dtype=complex)
    with pytest.raises(IdentifiabilityError) as info:
        identify(t.with_phasors(zero, zero, t.fx, t.fy), "kcd11")
    msg = str(info.value)
    assert "numerical rank 0 of 11" in msg and "every row's displacement is zero" in msg
    assert "elliptical" not in msg


def test_forward_whirl_only_cannot_separate_omega_k1_from_c():
    table = _table("kc8", "power:1", 8, ("forward",))
    with pytest.raises(IdentifiabilityError) as info:
        identify(table, "kc8", "power:1")
    combos = info.value.combinations
    assert "Kxx_1 - Cxy" in combos and "Kxy_1 + Cxx" in combos and len(combos) == 4
    msg = str(info.value)
    assert "only Kxx_1 + Cxy is determined" in msg
    assert "forward plus backward whirl" in msg
    # ... and forward plus backward whirl does separate them
    both = _table("kc8", "power:1", 8)
    assert identify(both, "kc8", "power:1").n_coefficients == 16


def test_backward_whirl_only_is_named_too():
    table = _table("kc7", "power:1", 8, ("backward",))
    with pytest.raises(IdentifiabilityError, match="every orbit in the table is a backward circular whirl"):
        identify(table, "kc7", "power:1")


def test_generic_orbits_cannot_separate_omega_squared_stiffness_from_inertia():
    # kc8 power:2 with an added D would collide; the rank test on generic orbits names it
    spec = model_spec("kcd11", "poly:2")
    assert "Kxx_2" not in spec.names and spec.absorbed == (2,)  # v2: not fitted, D carries it


@pytest.mark.parametrize("freq_dep", ["power:1", "poly:1", "poly:2"])
@pytest.mark.parametrize("minor", [4.9e-6, 3e-6])  # 2 % (the simulator's default) and 40 % ellipticity
def test_forward_only_tables_of_one_fixed_ellipse_are_refused(freq_dep, minor):
    table = _table("kc8", freq_dep, 12, ((5e-6, minor, 0.3),))
    with pytest.raises(IdentifiabilityError) as info:
        identify(table, "kc8", freq_dep)
    msg = str(info.value)
    assert "one common shape" in msg and "backward-whirl" in msg
    assert any(c.startswith("Kxx_1") and "Cxy" in c for c in info.value.combinations)
    # the same ellipse whirled both ways identifies the model
    both = _table("kc8", freq_dep, 12, ((5e-6, minor, 0.3), (5e-6, -minor, 0.3)))
    assert identify(both, "kc8", freq_dep).warnings == []


def test_forward_only_power_2_with_inertia_is_identifiable():
    # K orders {0}, C orders + 1 {1, 3}, D orders + 2 {2, 4}: disjoint once K_2 is absorbed
    true = truth("kcd11", {"K": (0,), "C": (0, 2), "D": (0, 2)})
    result = identify(orbit_table(true, frequencies(8), ("forward",)), "kcd11", "power:2")
    assert result.n_coefficients == 18 and "Kxx_2" not in result.coefficients
    assert result.coefficients["Cxx_2"] == pytest.approx(true[("C", 2)][0, 0], rel=1e-9)


def test_ill_conditioned_identifiable_fit_is_fitted_with_a_warning():
    true = truth("kc8", {"K": (0, 1), "C": (0, 1)})
    fwd = orbit_table(true, frequencies(8), ("forward",))
    bwd = orbit_table(true, frequencies(8), ("backward",), radius=5e-9)  # 1000 times smaller
    table = type(fwd)(
        fwd.spin,
        np.r_[fwd.orbit, bwd.orbit],
        np.r_[fwd.x, bwd.x],
        np.r_[fwd.y, bwd.y],
        np.r_[fwd.fx, bwd.fx],
        np.r_[fwd.fy, bwd.fy],
    )
    result = identify(table, "kc8", "power:1")
    assert len(result.warnings) == 1 and result.warnings[0].startswith("ill-conditioned")
    assert "poorly determined: " in result.warnings[0] and "Kxx_1" in result.warnings[0]
    # similar sizes both ways: no warning
    assert identify(_table("kc8", "power:1", 8), "kc8", "power:1").warnings == []


def test_power_auto_skips_exponents_that_forward_whirl_cannot_identify():
    true = truth("kcd11", {"K": (0, 3), "C": (0, 3), "D": (0, 3)})
    result = identify(orbit_table(true, frequencies(8), ("forward",)), "kcd11", "power:auto")
    assert sorted(result.skipped) == [1] and result.exponent == 3
    assert "Kxx_1 - Cxy" in result.skipped[1]


def test_power_auto_with_nothing_identifiable():
    true = truth("kcd11", {"K": (0, 1), "C": (0, 1), "D": (0, 1)})
    table = orbit_table(true, [5.0, 5.0, 5.0, 7.0, 7.0, 7.0])  # 2 distinct frequencies, 12 rows
    with pytest.raises(IdentifiabilityError, match="no exponent M in 1..4") as info:
        identify(table, "kcd11", "power:auto")
    assert any(c.startswith("power:1: Kxx_1") for c in info.value.combinations)


def test_repeated_frequency_is_not_enough():
    true = truth("kc8", {"K": (0,), "C": (0,)})
    table = orbit_table(true, [10.0, 10.0, 10.0], ("forward",))  # 12 equations, but one frequency
    with pytest.raises(IdentifiabilityError, match="rank-deficient"):
        identify(table, "kc8")


def test_rank_uses_column_scaling():
    # columns of wildly different units (N/m vs kg * Omega^2): full rank after scaling
    spec = model_spec("kcd12", "none")
    table = _table("kcd12", "none", 4)
    A, _ = regression(spec, table.orbit, table.x, table.y, table.fx, table.fy)
    rank = numerical_rank(A)
    assert rank.deficiency == 0 and rank.condition_number < 100 < np.linalg.cond(A) / 100


def test_noisy_forward_circles_are_refused_like_exact_ones():
    true = truth("kc8", {"K": (0, 1), "C": (0, 1)})
    clean = orbit_table(true, frequencies(10), ("forward",))
    rng = np.random.default_rng(4)
    noise = 0.5e-2 * 5e-6 * (rng.standard_normal((2, clean.n)) + 1j * rng.standard_normal((2, clean.n)))
    noisy = type(clean)(clean.spin, clean.orbit, clean.x + noise[0], clean.y + noise[1], clean.fx, clean.fy)
    with pytest.raises(IdentifiabilityError, match="one common shape") as info:
        identify(noisy, "kc8", "power:1")
    assert "Kxx_1 - Cxy" in info.value.combinations
    # the same noise on forward plus backward circles identifies fine
    both = orbit_table(true, frequencies(10))
    noisy_both = type(both)(
        both.spin,
        both.orbit,
        both.x + np.tile(noise[0], 2)[: both.n],
        both.y + np.tile(noise[1], 2)[: both.n],
        both.fx,
        both.fy,
    )
    assert identify(noisy_both, "kc8", "power:1").n_coefficients == 16


def test_check_plan_says_before_a_run_which_models_the_plan_cannot_identify():
    from reduction.identifiability import check_plan

    hz = frequencies(10)
    check_plan("kcd11", "power:2", hz, "forward")  # identifiable forward-only once K_2 is absorbed
    check_plan("kc8", "power:1", hz, "both")
    check_plan("kc8", "power:auto", hz, "forward")  # M = 2 works forward-only
    with pytest.raises(IdentifiabilityError) as info:
        check_plan("kc8", "power:1", hz, "forward")
    assert "Kxx_1 - Cxy" in info.value.combinations
    with pytest.raises(IdentifiabilityError, match="too few orbit frequencies"):
        check_plan("kcd12", "poly:2", hz[:3], "both")

"""Refusals: too few frequencies and rank-deficient regressions, with named combinations."""

from __future__ import annotations

import numpy as np
import pytest

from reduction_synthetic import frequencies, orbit_table, truth
from reduction.errors import IdentifiabilityError
from reduction.identifiability import numerical_rank
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


def test_stiffness_omega_squared_is_an_inertia_term_for_every_orbit():
    # the paper's 33-coefficient model: K_2 Omega^2 and -Omega^2 D cannot be told apart
    table = _table("kcd11", "poly:2", 20, ((5e-6, 2e-6, 0.3), "forward", "backward"))
    with pytest.raises(IdentifiabilityError) as info:
        identify(table, "kcd11", "poly:2")
    assert info.value.combinations == ["Kxx_2 + Dxx", "Kxy_2 + Kyx_2 + Dxy", "Kyy_2 + Dyy"]
    msg = str(info.value)
    assert "rank 30 of 33" in msg and "no orbit data can separate" in msg
    assert "only Kxx_2 - Dxx is determined" in msg


def test_kcd_with_power_2_is_always_refused():
    with pytest.raises(IdentifiabilityError, match="Kxy_2 \\+ Dxy"):
        identify(_table("kcd12", "power:2", 10), "kcd12", "power:2")


def test_power_auto_skips_exponents_that_forward_whirl_cannot_identify():
    true = truth("kcd11", {"K": (0, 3), "C": (0, 3), "D": (0, 3)})
    result = identify(orbit_table(true, frequencies(8), ("forward",)), "kcd11", "power:auto")
    assert sorted(result.skipped) == [1, 2] and result.exponent == 3
    assert "Kxx_1 - Cxy" in result.skipped[1]


def test_power_auto_with_nothing_identifiable():
    true = truth("kcd11", {"K": (0, 1), "C": (0, 1), "D": (0, 1)})
    table = orbit_table(true, [5.0, 5.0, 5.0, 7.0, 7.0, 7.0])  # 2 distinct frequencies, 12 rows
    with pytest.raises(IdentifiabilityError, match="no exponent M in 1..4") as info:
        identify(table, "kcd11", "power:auto")
    assert any(c.startswith("power:2: Kxx_2") for c in info.value.combinations)


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
    with pytest.raises(IdentifiabilityError, match="circular to within 2%") as info:
        identify(noisy, "kc8", "power:1")
    assert "Kxx_1 - Cxy" in info.value.combinations
    # the same noise on forward plus backward circles identifies fine
    both = orbit_table(true, frequencies(10))
    noisy_both = type(both)(both.spin, both.orbit, both.x + np.tile(noise[0], 2)[: both.n],
                            both.y + np.tile(noise[1], 2)[: both.n], both.fx, both.fy)
    assert identify(noisy_both, "kc8", "power:1").n_coefficients == 16

"""Identification from synthetic orbit tables of known coefficients (noise-free)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from support.identify_keys import keys
from support.reduction_synthetic import frequencies, keys_of, orbit_table, truth
from reduction.errors import IdentificationError, ReductionError
from reduction.identify import check_options, identify
from reduction.methods import METHODS, Solver
from reduction.models import MODELS, parse_freq_dep
from reduction.table import OrbitTable

ELLIPSES = (("forward",), (5e-6, 2e-6, 0.4), (3e-6, -4e-6, 1.1))  # b < 0: backward-whirling ellipse

IDENTIFIABLE = [
    ("kc7", "none"),
    ("kc8", "none"),
    ("kcd11", "none"),
    ("kcd12", "none"),
    ("kc7", "power:1"),
    ("kc8", "power:2"),
    ("kcd11", "power:1"),
    ("kcd12", "power:3"),
    ("kcd11", "power:1,3,4"),
    ("kc7", "poly:2"),
    ("kc8", "poly:3"),
    ("kcd12", "poly:1"),
]


def _max_rel_err(result, true):
    expected = keys_of(true)
    assert set(result.coefficients) == set(expected)
    return max(abs(result.coefficients[k] - v) / abs(v) for k, v in expected.items())


@pytest.mark.parametrize("model, freq_dep", IDENTIFIABLE)
@pytest.mark.parametrize("orbits", ["fwd+bwd circles", "ellipses"])
def test_noise_free_data_give_the_coefficients_back(model, freq_dep, orbits):
    true = truth(model, parse_freq_dep(freq_dep).orders)
    shapes = ("forward", "backward") if orbits == "fwd+bwd circles" else ELLIPSES[1:]
    table = orbit_table(true, frequencies(10), shapes)
    result = identify(table, model, freq_dep)
    assert _max_rel_err(result, true) < 1e-9
    assert result.residual_rms < 1e-9 * np.sqrt(np.mean(np.abs(table.fx) ** 2))
    assert result.n_frequencies == table.n


@pytest.mark.parametrize("method", ["wls", "tls", "iv"])
def test_every_method_is_exact_on_noise_free_data(method):
    true = truth("kcd11", {"K": (0,), "C": (0,), "D": (0,)})
    table = orbit_table(true, frequencies(6), gamma2=[0.99, 0.98, 0.97, 0.995])
    assert _max_rel_err(identify(table, "kcd11", "none", method), true) < 1e-9


def test_minimum_number_of_frequencies_is_enough():
    true = truth("kc7", {"K": (0,), "C": (0,)})
    table = orbit_table(true, frequencies(2), ("forward",))  # 2 frequencies, 8 equations, 7 unknowns
    result = identify(table, "kc7")
    assert result.min_frequencies == 2 and _max_rel_err(result, true) < 1e-9


def test_solvers_agree_to_rounding_on_noisy_data():
    rng = np.random.default_rng(3)
    true = truth("kcd11", {"K": (0, 1), "C": (0, 1), "D": (0, 1)})
    table = orbit_table(true, frequencies(12))
    noisy = type(table)(
        table.spin,
        table.orbit,
        table.x,
        table.y,
        table.fx * (1 + 0.01 * rng.standard_normal(table.n)),
        table.fy + 5 * rng.standard_normal(table.n),
    )
    results = {s: identify(noisy, "kcd11", "power:1", solver=s) for s in Solver}
    assert [r.solver for r in results.values()] == ["qr", "svd", "lu"]  # stored as the plain word
    ref = results["qr"].coefficients
    for s in (Solver.SVD, Solver.LU):
        for k, v in results[s].coefficients.items():
            assert v == pytest.approx(ref[k], rel=1e-10, abs=1e-10 * results["qr"].std_errors[k])
        assert results[s].std_errors == pytest.approx(results["qr"].std_errors, rel=1e-8)
    assert _max_rel_err(results["qr"], true) > 1e-6  # the noise is real


def test_power_auto_picks_the_true_exponent_and_skips_unidentifiable_ones():
    true = truth("kcd11", {"K": (0, 3), "C": (0, 3), "D": (0, 3)})
    table = orbit_table(true, frequencies(10))
    result = identify(table, "kcd11", "power:auto")
    assert result.exponent == 3 and result.freq_dep == "power:auto"
    assert result.skipped == {}  # v2: power:2 fits with K_2 absorbed by D
    assert any("exponent M = 3" in n for n in result.notes)
    assert _max_rel_err(result, true) < 1e-9
    d = result.to_dict()
    assert d["exponent"] == 3 and "Kxx_3" in d["coefficients"]


def test_to_dict_is_the_spec_object():
    true = truth("kcd11", {"K": (0,), "C": (0,), "D": (0,)})
    table = orbit_table(true, frequencies(5))
    d = identify(table, "kcd11").to_dict()
    assert list(d) == keys(has_uncertainty=False)
    assert (d["model"], d["freq_dep"], d["method"]) == ("kcd11", "none", "ols")
    assert (d["n_coefficients"], d["min_frequencies"], d["n_frequencies"]) == (11, 3, 10)
    assert list(d["coefficients"]) == [
        "Kxx",
        "Kxy",
        "Kyx",
        "Kyy",
        "Cxx",
        "Cxy",
        "Cyx",
        "Cyy",
        "Dxx",
        "Dxy",
        "Dyx",
        "Dyy",
    ]
    assert list(d["std_errors"]) == list(d["coefficients"])
    assert d["coefficients"]["Dxy"] == d["coefficients"]["Dyx"]
    assert d["condition_number"] >= 1
    assert len(d["fit"]) == 10
    assert set(d["fit"][0]) == {"orbit_hz", "fx_amp_err_pct", "fx_phase_err_deg", "fy_amp_err_pct", "fy_phase_err_deg"}
    assert d["fit"][0]["orbit_hz"] == pytest.approx(table.orbit[0] / (2 * np.pi))


def test_matrices_and_reproduce():
    true = truth("kc8", {"K": (0, 2), "C": (0, 2)})
    table = orbit_table(true, frequencies(8))
    result = identify(table, "kc8", "power:2")
    w = 70.0
    K, C, D = result.matrices(w)
    np.testing.assert_allclose(K, true[("K", 0)] + w**2 * true[("K", 2)], rtol=1e-9)
    np.testing.assert_allclose(C, true[("C", 0)] + w**2 * true[("C", 2)], rtol=1e-9)
    assert np.all(D == 0)
    fx, fy = result.reproduce(table)
    np.testing.assert_allclose(fx, table.fx, rtol=1e-9)
    np.testing.assert_allclose(fy, table.fy, rtol=1e-9)


def test_fit_diagnostics_report_amplitude_and_phase_errors():
    true = truth("kcd11", {"K": (0,), "C": (0,), "D": (0,)})
    table = orbit_table(true, frequencies(5))
    # distort one measured force by +2 % and +1 degree: the fit shows it at that frequency
    fx = table.fx.copy()
    fx[3] *= 1.02 * np.exp(1j * np.radians(1.0))
    distorted = type(table)(table.spin, table.orbit, table.x, table.y, fx, table.fy)
    fit = identify(distorted, "kcd11").fit
    worst = max(range(len(fit)), key=lambda k: abs(fit[k]["fx_amp_err_pct"]))
    assert worst == 3
    assert fit[3]["fx_amp_err_pct"] < -1.0 and fit[3]["fx_phase_err_deg"] < -0.5


def test_wls_without_coherence_is_a_clear_error():
    true = truth("kc8", {"K": (0,), "C": (0,)})
    with pytest.raises(IdentificationError, match="gamma2"):
        identify(orbit_table(true, frequencies(4)), "kc8", method="wls")


@pytest.mark.parametrize(
    ("kw", "says"),
    [
        ({"method": "mle"}, "unknown method 'mle': use one of ols, wls, tls, iv"),
        ({"solver": "chol"}, "unknown solver 'chol': use one of qr, svd, lu"),
        ({"model": "kd4"}, "kd4"),
        ({"freq_dep": "poly"}, "poly"),
    ],
)
def test_unknown_options_are_refused(kw, says):
    true = truth("kc8", {"K": (0,), "C": (0,)})
    args = {"model": "kc8", **kw}
    with pytest.raises(ReductionError, match=re.escape(says)):
        identify(orbit_table(true, frequencies(4)), **args)


@pytest.mark.parametrize(
    "kw",
    [{"method": "mle"}, {"model": "kd4"}, {"freq_dep": "poly"}, {"freq_dep": "power:x"}],
)
def test_check_options_refuses_as_identify_does_without_a_table(kw):
    args = {"model": "kc8", "freq_dep": "none", "method": "ols", **kw}
    with pytest.raises(ReductionError) as checked:
        check_options(**args)
    with pytest.raises(ReductionError) as identified:
        identify(orbit_table(truth("kc8", {"K": (0,), "C": (0,)}), frequencies(4)), **args)
    assert str(checked.value) == str(identified.value)
    assert str(checked.value).split(" ")[0] in ("unknown", "freq-dep")


def test_check_options_lets_every_known_option_pass():
    for model in MODELS:
        for method in METHODS:
            check_options(model, "power:auto", method)
            check_options(model, "poly:2", method)


V2_ABSORBED = [
    ("kcd11", "power:2", 18),
    ("kcd11", "poly:2", 29),
    ("kcd12", "power:2", 20),
    ("kcd12", "poly:2", 32),
    ("kcd11", "power:4,2,2", 18),
    ("kcd12", "power:2,1,1", 20),
]


@pytest.mark.parametrize("model, freq_dep, count", V2_ABSORBED)
@pytest.mark.parametrize("orbits", ["fwd+bwd circles", "ellipses"])
def test_v2_models_with_absorbed_stiffness_orders_are_recovered_exactly(model, freq_dep, count, orbits):
    from reduction.models import model_spec

    spec = model_spec(model, freq_dep)
    true = truth(model, {m: spec.orders(m) for m in "KCD"})  # no K order absorbed by D
    shapes = ("forward", "backward") if orbits == "fwd+bwd circles" else ELLIPSES[1:]
    result = identify(orbit_table(true, frequencies(10), shapes), model, freq_dep)
    assert result.n_coefficients == count == len(result.free) and result.min_frequencies == -(-count // 4)
    assert _max_rel_err(result, true) < 1e-8
    assert len(result.notes) == 1 and result.warnings == []


def test_an_absorbed_stiffness_term_is_carried_by_the_inertia():
    # data WITH Omega^2 K_2: kcd11 power:2 reports D_0 - K_2 (the note's claim), all else exact
    true = truth("kcd11", {"K": (0, 2), "C": (0, 2), "D": (0, 2)})
    true[("K", 2)] = (true[("K", 2)] + true[("K", 2)].T) / 2  # symmetric: kcd11's D can carry it
    result = identify(orbit_table(true, frequencies(10)), "kcd11", "power:2")
    d0 = true[("D", 0)] - true[("K", 2)]
    assert result.coefficients["Dxx"] == pytest.approx(d0[0, 0], rel=1e-8)
    assert result.coefficients["Dxy"] == pytest.approx(d0[0, 1], rel=1e-8)
    assert result.coefficients["Kxx"] == pytest.approx(true[("K", 0)][0, 0], rel=1e-9)
    assert result.residual_rms < 1e-9 * np.sqrt(np.mean(np.abs(orbit_table(true, frequencies(10)).fx) ** 2))


@pytest.mark.parametrize(
    "field, value, says",
    [
        ("gamma2", np.array([[1.0, 1.0, 1.0, 1.0], [0.9, np.nan, 1.0, 1.0]]), "gamma2 at row index 1, column yfx: nan"),
        ("u", np.array([[1.0, 1.0, 1.0, 1.0], [0.9, 1.0, np.inf, 1.0]]), "u at row index 1, column fx: inf"),
        ("fy", np.array([1.0, np.nan]), "fy is not finite at row index 1"),
    ],
)
def test_a_bad_table_value_is_named_by_row_and_column(field, value, says):
    """A coherence of a dead channel (NaN: zero power) read 'gamma2 values must lie in [0, 1]'
    with no row or column."""
    columns = dict(spin=1.0, orbit=[1.0, 2.0], x=[1, 1], y=[-1j, 1j], fx=[1, 1], fy=[1, 1])
    with pytest.raises(ReductionError, match=re.escape(says)):
        OrbitTable(**(columns | {field: value}))


def test_iv_refuses_orbits_far_from_circles_and_says_by_how_much():
    """Orbits of three radii (1, 2, 4 times) are no common circle: the misfit (rms |d - circle| /
    rms |d|) is said as a percentage with a space before % (SI style), as the CLI writes them."""
    true = truth("kc8", {"K": (0,), "C": (0,)})
    table = orbit_table(true, frequencies(6))
    scale = np.resize([1.0, 1.0, 2.0, 2.0, 4.0, 4.0], table.n)
    wide = OrbitTable(table.spin, table.orbit, table.x * scale, table.y * scale, table.fx * scale, table.fy * scale)
    with pytest.raises(IdentificationError, match=r"\(misfit \d+ % > 30 %\), so the circle instruments do not fit"):
        identify(wide, "kc8", method="iv")


@pytest.mark.parametrize("method", ["ols", "iv", "wls"])
def test_the_note_says_where_chi2_aic_and_bic_are_taken_with_stated_noise(method):
    """ols and iv with u_* columns: chi2, AIC and BIC at the wls solution (reduction.statistics),
    the method's coefficients and covariance its own; wls: at its own solution, no such clause.
    The note named them 'aic and bic' in lower case, as no table heads them."""
    from support.reduction_synthetic import with_noise

    clean = orbit_table(truth("kc8", {"K": (0,), "C": (0,)}), frequencies(10))
    table = with_noise(clean, np.random.default_rng(3), (1e-7, 1e-7, 1.0, 1.0))
    result = identify(table, "kc8", "none", method=method)
    (note,) = [n for n in result.notes if n.startswith("covariance, weights and chi2 from the table's u_x")]
    said = "; chi2, AIC and BIC at the wls solution (the coefficients and their covariance this method's own)"
    assert note.endswith(said) == (method != "wls") and "aic" not in note, note

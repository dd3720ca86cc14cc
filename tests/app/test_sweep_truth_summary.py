"""The impedance error of the sweep's closing table, checked by hand: a stored kcd11 fit whose
matrices are the truth's times 1.02 reproduces Z 2 % high at every frequency."""

import numpy as np
import pytest

from orbitrig.cli.sweep_summary import best_impedance_error, compare_with_truth, worst_impedance_error
from orbitrig.run.truth import impedance_deviation, stored_impedance

K = np.array([[3.3e7, 5.4e6], [-5.4e6, 3.3e7]])
C = np.array([[1.16e5, 0.0], [0.0, 1.16e5]])
D = np.array([[4.0, 0.0], [0.0, 4.0]])
ORBIT = np.array([25.9, -25.9, 60.0, -60.0, 130.6, -130.6])


def _truth(scale_c: float = 1.0) -> dict:
    w = np.abs(ORBIT)[:, None, None]
    z = K + 1j * w * C * scale_c - w**2 * D
    return {
        "orbit": ORBIT.tolist(),
        "Z_re": z.real.tolist(),
        "Z_im": z.imag.tolist(),
        "K0": K.tolist(),
        "C0": C.tolist(),
        "D0": D.tolist(),
    }


def _result(factor: float) -> dict:
    coef = {
        f"{m}{a}{b}": factor * float(M[i, j])
        for m, M in zip("KCD", (K, C, D))
        for i, a in enumerate("xy")
        for j, b in enumerate("xy")
    }
    return {"model": "kcd12", "freq_dep": "none", "coefficients": coef}


def test_a_fit_two_percent_high_is_two_percent_off_at_every_frequency():
    dev = impedance_deviation(_result(1.02), _truth())
    assert dev.shape == (6,) and dev == pytest.approx(np.full(6, 0.02), rel=1e-9)
    assert worst_impedance_error(_result(1.0), _truth()) == pytest.approx(0.0, abs=1e-9)
    assert worst_impedance_error(_result(1.02), {"K0": K.tolist()}) is None  # a truth without Z


def test_a_truth_the_constant_model_cannot_reach_shows_in_the_worst_frequency():
    # the true damping is 10 % higher than the fit's: |dZ| = 0.1 w |C| at each w, worst at the top speed
    w = 130.6
    z_top = K + 1j * w * C * 1.1 - w**2 * D
    expected = np.linalg.norm(0.1 * w * C) / np.linalg.norm(z_top) * 100
    assert worst_impedance_error(_result(1.0), _truth(scale_c=1.1)) == pytest.approx(expected, rel=1e-9)
    z = stored_impedance(_result(1.0), [w])
    assert np.allclose(z[0], K + 1j * w * C - w**2 * D)


def test_the_summary_cell_is_the_fit_that_reproduces_z_best():
    fits = [_result(1.005), _result(1.02)]
    assert best_impedance_error(fits, _truth()) == "0.50 %"
    assert best_impedance_error(fits, {"K0": K.tolist()}) == "-"
    errors = compare_with_truth(_result(1.02), _truth())  # a fit without its own truth: against K0, C0, D0
    assert errors["Kxx"] == pytest.approx(2.0) and errors["Cyy"] == pytest.approx(2.0)


def test_a_fit_is_compared_with_its_own_truth_when_it_has_one():
    fit = _result(1.02)
    own = {k: v / 1.02 * 1.01 for k, v in fit["coefficients"].items()}  # the model's reach: 1 % high
    fit["truth"] = {"coefficients": own, "definition": "..."}
    errors = compare_with_truth(fit, _truth())
    # |1.02 - 1.01| / 1.01 of the largest entry of each matrix
    assert errors["Kxx"] == pytest.approx(100 * 0.01 / 1.01) and errors["Dyy"] == pytest.approx(100 * 0.01 / 1.01)
    assert errors["Kxy"] == pytest.approx(100 * 0.01 / 1.01 * 5.4e6 / 3.3e7)


def test_percentages_of_the_closing_table_are_written_alike():
    """A coefficient's error and the impedance error, side by side in the point's table, both
    with a space between the number and % (SI style): '(2.0 %)' as '0.50 %'."""
    from orbitrig.cli.sweep_summary import _cell

    fit = _result(1.02)
    errors = compare_with_truth(fit, _truth())
    assert _cell(fit, "Kxx", errors["Kxx"]) == "33.66 (2.0 %)"  # MN/m, as reduce and identify show K
    assert best_impedance_error([_result(1.005)], _truth()) == "0.50 %"

"""reduction.information: the predicted standard errors of a list's Fisher information, and
its one test of a list that cannot identify the model (np.inf for a search, a refusal naming
the coefficients for a list a user gave). Hand-checkable cases."""

from __future__ import annotations

import numpy as np
import pytest

from reduction.errors import IdentifiabilityError
from reduction.information import identified_errors, predicted_errors
from reduction.models import model_spec


def test_one_parameter_error_is_one_over_root_n_f():
    """One coefficient, F = 4 per revolution (1/SI^2), n = 25 revolutions: se = 1/sqrt(100)."""
    assert predicted_errors([[25 * 4.0]]) == pytest.approx([0.1], rel=1e-15)


def test_well_conditioned_errors_are_the_inverse_diagonal():
    """A correlated 2 x 2 information: se_j = sqrt((I^-1)_jj) = sqrt(I_kk / det), exactly
    what np.linalg.inv gives (the figures of every design are unchanged)."""
    info = np.array([[4.0, 1.0], [1.0, 2.0]])  # det 7
    se = predicted_errors(info)
    assert se == pytest.approx([np.sqrt(2 / 7), np.sqrt(4 / 7)], rel=1e-14)
    assert np.array_equal(se, np.sqrt(np.diag(np.linalg.inv(info))))


def test_a_coefficient_the_list_cannot_identify_has_infinite_error():
    """a and b seen only as a + b (information [[1, 1], [1, 1]]), c on its own with I = 4:
    a and b are undetermined (inf), c keeps 1/sqrt(4); nearly singular (a relative eigenvalue
    of 1e-16, below the identification's 1e-7 squared) counts as singular, 1e-10 does not."""
    info = np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 4.0]])
    se = predicted_errors(info)
    assert np.isinf(se[:2]).all() and se[2] == pytest.approx(0.5, rel=1e-12)
    near = np.array([[1.0, 1.0], [1.0, 1.0 + 1e-15]])
    assert np.isinf(predicted_errors(near)).all()
    assert np.isfinite(predicted_errors([[1.0, 1.0], [1.0, 1.0 + 1e-10]])).all()
    assert np.isinf(predicted_errors(np.zeros((2, 2)))).all()


def test_identified_errors_names_the_coefficients_and_the_direction():
    """kc8 information with Kxx and Cxy seen only as Kxx - 2 Cxy (a null direction Kxx +
    0.5 Cxy in SI): refused by name; the other coefficients alone would pass."""
    spec = model_spec("kc8")
    p = spec.n_coefficients
    info = np.eye(p)
    i, j = spec.names.index("Kxx"), spec.names.index("Cxy")
    v = np.zeros(p)
    v[i], v[j] = 1.0, -2.0
    info[[i, j], :] = 0.0
    info[:, [i, j]] = 0.0
    info += np.outer(v, v)
    with pytest.raises(IdentifiabilityError) as err:
        identified_errors(info, spec, "the list (ratios 0.5)")
    text = str(err.value)
    assert text.startswith("the list (ratios 0.5) cannot identify kc8 none: Kxx, Cxy undetermined")
    assert err.value.combinations == ["Kxx + 0.5*Cxy"]
    assert identified_errors(np.eye(p), spec, "x") == pytest.approx(np.ones(p))

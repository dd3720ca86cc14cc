"""Truth per model (orbitrig.run.model_truth) against limits checkable by hand.

A bearing whose Z is exactly K + i w C - w^2 D with symmetric D: kcd11's truth is K, C, D
themselves. Give D a skew part (Dxy = -Dyx = s, as recess compressibility does): on circular
orbits the skew inertia term -w^2 s [[0, 1], [-1, 0]] acts on d like a skew stiffness, so
a model with symmetric D cannot take it: kcd11's truth keeps D's symmetric part
(Dxy = Dyx = its symmetric value) and the skew part goes into its skew K, averaged over the
frequencies by the least squares. kc8 (no D) moves -w^2 D into
K: at a single frequency w0 exactly, Kij = K0ij - w0^2 Dij."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from orbitrig.run.model_truth import model_truth
from reduction.identify import identify, tls_noise_ratio
from reduction.impedance import forces
from reduction.table import OrbitTable

K = np.array([[3.3e7, 5.4e6], [-5.4e6, 3.1e7]])
C = np.array([[1.16e5, -1.2e4], [1.2e4, 1.1e5]])
D_SYM = np.array([[-96.0, 3.0], [3.0, -90.0]])
R = 2.4e-6


def _table(orbits, z) -> OrbitTable:
    """Forward and backward circular orbits at each |Omega|; forces -Z d plus a little noise."""
    w = np.repeat(orbits, 2)
    x = np.full(len(w), R, dtype=complex)
    y = np.tile([-1j * R, 1j * R], len(orbits))
    fx, fy = forces(z(w), x, y)
    rng = np.random.default_rng(3)
    noise = lambda: 5.0 * (rng.normal(size=len(w)) + 1j * rng.normal(size=len(w)))  # noqa: E731
    return OrbitTable(100.0, w, x, y, fx + noise(), fy + noise())


def _z(D):
    return lambda w: K + 1j * w[:, None, None] * C - w[:, None, None] ** 2 * D


def test_a_bearing_the_model_describes_is_its_own_truth():
    table = _table(np.array([30.0, 60.0, 90.0, 120.0]), _z(D_SYM))
    fit = identify(table, "kcd11")
    true = model_truth(fit, table, _z(D_SYM)(table.orbit))["coefficients"]
    for m, M in zip("KCD", (K, C, D_SYM)):
        for i, a in enumerate("xy"):
            for j, b in enumerate("xy"):
                assert true[f"{m}{a}{b}"] == pytest.approx(M[i, j], rel=1e-9, abs=1e-9 * abs(M).max())


def test_skew_inertia_goes_where_the_model_can_put_it():
    s, w0 = 26.9, 80.0
    D = D_SYM + s * np.array([[0.0, 1.0], [-1.0, 0.0]])
    table = _table(np.array([w0]), _z(D))  # forward and backward: 8 equations, kc8's 8 unknowns
    z = _z(D)(table.orbit)
    kc8 = model_truth(identify(table, "kc8"), table, z)["coefficients"]
    assert "Dxy" not in kc8
    assert kc8["Kxx"] == pytest.approx(K[0, 0] - w0**2 * D[0, 0], rel=1e-9)
    assert kc8["Kxy"] == pytest.approx(K[0, 1] - w0**2 * (D_SYM[0, 1] + s), rel=1e-9)
    assert kc8["Kyx"] == pytest.approx(K[1, 0] - w0**2 * (D_SYM[1, 0] - s), rel=1e-9)
    assert kc8["Cxy"] == pytest.approx(C[0, 1], rel=1e-9)
    # over several frequencies kcd11 keeps its D symmetric: the skew part is not in it
    table = _table(np.array([30.0, 60.0, 90.0, 120.0]), _z(D))
    kcd11 = model_truth(identify(table, "kcd11"), table, _z(D)(table.orbit))["coefficients"]
    assert kcd11["Dxy"] == kcd11["Dyx"] == pytest.approx(D_SYM[0, 1], rel=1e-6)
    assert kcd11["Dxx"] == pytest.approx(D[0, 0], rel=1e-6)


def test_the_truth_uses_the_fits_method_and_chosen_exponent():
    table = _table(np.array([30.0, 60.0, 90.0, 120.0]), _z(D_SYM))
    fit = identify(table, "kcd11", "power:auto")
    true = model_truth(fit, table, _z(D_SYM)(table.orbit))
    assert set(true["coefficients"]) == set(fit.coefficients)
    assert "error" in model_truth(identify(table, "kc8"), table, np.zeros((3, 2, 2)))  # rows do not match


def test_a_tls_fits_truth_weighs_its_rows_at_the_fits_noise_ratio():
    """tls without u_* given a noise ratio (here a tenth of the default rms|f| / rms|d|): its truth,
    the noise-free fit, weighs the rows as the fit did (Identification.tls_ratio). With the skew
    inertia kcd11 cannot take, the projection depends on the weights: at the exact forces' default
    ratio (as before) Kyx was 1e4 N/m (0.2 %) away."""
    D = D_SYM + 26.9 * np.array([[0.0, 1.0], [-1.0, 0.0]])
    table = _table(np.array([30.0, 60.0, 90.0, 120.0]), _z(D))
    z = _z(D)(table.orbit)
    fit = identify(table, "kcd11", method="tls", tls_ratio=0.1 * tls_noise_ratio(table))
    true = model_truth(fit, table, z)["coefficients"]
    fx, fy = forces(z, table.x, table.y)
    exact = dataclasses.replace(table, fx=fx, fy=fy)
    same = identify(exact, "kcd11", method="tls", tls_ratio=fit.tls_ratio).coefficients
    default = identify(exact, "kcd11", method="tls").coefficients
    for key, value in same.items():
        assert true[key] == pytest.approx(value, rel=1e-9, abs=1e-6 * abs(same["Kxx"])), key
    assert abs(default["Kyx"] - same["Kyx"]) > 1e-4 * abs(same["Kxx"])  # the weights matter here

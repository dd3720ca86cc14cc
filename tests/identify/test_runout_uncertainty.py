"""The subtracted runout's recorded uncertainty in a point's budget (docs/calibration.md, Runout):
an error of the runout taken out is common to every block of the point, so it is propagated as a
type-B term fully correlated across the rows (reduction.systematic.DisplacementTerm), its columns
the change of each row's x, y when the runout subtracted moves by its u and every block is
corrected again (orbitrig.run.identification.runout_term)."""

from __future__ import annotations

import dataclasses

import h5py
import numpy as np
import pytest

from orbitrig.run.corrections import Corrections, spin_turns
from orbitrig.config import CalibrationUncertainty, ModelSpec
from orbitrig.run.identification import corrected_probes, identify_operating_point, orbit_table, runout_term
from orbitrig.analysis.quality import budget_covariance
from orbitrig.load_systems import LoadSystem
from orbitrig.run.point_analysis import lms_calibration
from orbitrig.run.steps import Block
from orbitrig.store.annotate import annotate
from orbitrig.store.fit_analysis import write_fit_analysis
from orbitrig.store.pieces import fixed_text
from reduction.fourier import phasor
from reduction.identify import identify
from reduction.lms_comparison import lms_difference
from reduction.systematic import (
    Calibration,
    DisplacementTerm,
    displacement_jacobian,
    uncertainty_budget,
)
from reduction.table import OrbitTable
from tests.support.phasor_blocks import CH, SLOTS, phasor_block

THETA = 2 * np.pi * SLOTS / 360
SPIN = 2 * np.pi * 30.0  # rad/s
K, C, M = 3.3e7, 2.0e4, 5.0  # N/m, N s/m, kg (isotropic, no cross terms)
R = 2e-6  # orbit radius, m
U_RUNOUT = 30e-9  # each runout phasor's standard uncertainty (complex, k = 1), m


def _point(runout: np.ndarray, rng: np.random.Generator, revolutions: int = 12) -> list:
    """Blocks at 11, 15, 19, 23 Hz, forward and backward, the probes carrying ``runout`` (4, 2)."""
    recs = []
    for i, hz in enumerate((11.0, 15.0, 19.0, 23.0)):
        w, rho = 2 * np.pi * hz, SPIN / (2 * np.pi * hz)
        z = K + 1j * w * C - w**2 * M
        for direction in (1, -1):
            d = R * np.array([1.0, -1j * direction])
            rows = []
            for n in range(revolutions):
                dn = d * (1 + 0.02 * (rng.standard_normal(2) + 1j * rng.standard_normal(2)))
                ph = np.zeros(8, complex)
                ph[[CH["x_a"], CH["x_b"]]], ph[[CH["y_a"], CH["y_b"]]] = dn[0], dn[1]
                f = -z * dn
                ph[[CH["fx_piezo"], CH["fx_strain"]]], ph[[CH["fy_piezo"], CH["fy_strain"]]] = f[0], f[1]
                v = np.real(ph[:, None] * np.exp(1j * THETA))
                psi = 1.1 * i + 2 * np.pi * rho * n + rho * THETA[4:]
                v[4:] += np.real(runout[:, :1] * np.exp(1j * psi) + runout[:, 1:] * np.exp(2j * psi))
                rows.append(phasor(v, THETA))
            recs.append(phasor_block(Block(2 * i + (direction < 0), direction, w), np.array(rows), measured=w))
    return recs


def _table(recs: list, corr: Corrections) -> tuple[OrbitTable, list]:
    probes = corrected_probes(recs, CH, corr, _bases(corr, recs))
    return orbit_table(SPIN, recs, CH, "piezo", corr, probes), probes


def _bases(corr: Corrections, recs: list) -> list:
    return [corr.runout_basis(r, CH, spin_turns(r, CH, SPIN)) for r in recs]


def test_a_displacement_error_common_to_every_row_scales_z_as_a_probe_sensitivity_error():
    """Hand check: every row's x, y s = 1 % high (dd = s (x, y)) scales every entry of Z by 1 - s: the
    term's standard uncertainty of each coefficient is 1 % of it."""
    rng = np.random.default_rng(3)
    table, _ = _table(_point(np.zeros((4, 2), complex), rng), Corrections())
    ident = identify(table, model="kcd11")
    term = DisplacementTerm(["all"], 0.01 * np.stack([table.x, table.y], axis=1)[:, :, None])
    b = uncertainty_budget(ident, table, Calibration(), runout=term)
    for key in ("Kxx", "Kyy", "Cxx", "Dxx"):
        assert b.runout[key] == pytest.approx(0.01 * abs(ident.coefficients[key]), rel=1e-9)
    assert b.systematic["Kxx"] == pytest.approx(b.runout["Kxx"], rel=1e-12)  # the only systematic term


def test_the_runout_term_matches_the_spread_of_refits_with_drawn_runout_errors():
    """The chain: runout errors drawn at the stated u (30 nm complex, u / sqrt(2) per part), every
    block corrected again with its spin phase fitted again: each row's x, y moves by the term's
    columns times the draw within 2 % (linear in the runout). Monte Carlo: 200 draws of those
    moves, K, C, D refitted (ols): the spread of each coefficient is the budget's runout term
    within 15 % (3 standard errors of a standard deviation from 200 draws). A recorded runout
    without u keeps the old budget."""
    rng = np.random.default_rng(11)
    runout = 2e-6 * np.exp(1j * rng.uniform(0, 2 * np.pi, (4, 2))) * np.array([1.0, 0.5])
    recs = _point(runout, rng, revolutions=6)
    corr = Corrections(runout=runout, runout_u=np.full((4, 2), U_RUNOUT))
    table, probes = _table(recs, corr)
    ident = identify(table, model="kcd11")
    term = runout_term(recs, CH, corr, _bases(corr, recs))
    assert term is not None and term.dd.shape == (8, 2, 16)
    for _ in range(2):
        z = rng.standard_normal((4, 2, 2))  # (probe, harmonic, re/im) as the term's labels
        moved, _ = _table(recs, Corrections(runout=runout + U_RUNOUT / np.sqrt(2) * (z[..., 0] + 1j * z[..., 1])))
        change = np.stack([moved.x - table.x, moved.y - table.y], axis=1)
        assert np.abs(change - term.dd @ z.reshape(-1)).max() < 0.02 * np.abs(change).max()
    b = uncertainty_budget(ident, table, Calibration(), runout=term)
    keys = list(b.runout)
    draws = []
    for _ in range(200):
        dd = term.dd @ rng.standard_normal(16)
        fit = identify(dataclasses.replace(table, x=table.x + dd[:, 0], y=table.y + dd[:, 1]), model="kcd11")
        draws.append([fit.coefficients[k] for k in keys])
    spread = np.std(np.array(draws), axis=0, ddof=1)
    for key, s in zip(keys, spread):
        assert s == pytest.approx(b.runout[key], rel=0.15), key
    assert b.runout["Kxx"] / abs(ident.coefficients["Kxx"]) > 1e-4  # not a vanishing term
    old = Corrections(runout=runout)  # a record without h1_u_um, h2_u_um
    assert runout_term(recs, CH, old, _bases(old, recs)) is None
    assert uncertainty_budget(ident, table, Calibration()).runout == {}


def test_the_point_stores_the_runout_term_inside_its_expanded_uncertainty(tmp_path):
    """The sweep's point (identify_operating_point, a stated calibration of 0.1 % probe sensitivity):
    the budget stores the runout term ("runout", "runout_covariance") and U = k sqrt(stat^2 + sys^2)
    with it inside the systematic part; the same blocks corrected without the runout's u: no term."""
    rng = np.random.default_rng(5)
    runout = 2e-6 * np.exp(1j * rng.uniform(0, 2 * np.pi, (4, 2)))
    recs = _point(runout, rng, revolutions=6)
    stated = CalibrationUncertainty(probe_sensitivity_pct=0.1)
    spec = ModelSpec(model="kcd11")
    corr = Corrections(runout=runout, runout_u=np.full((4, 2), U_RUNOUT))
    u = identify_operating_point(SPIN, recs, CH, [spec], None, stated, corr).identifications[("piezo", spec.key)][
        "json"
    ]
    budget = u["uncertainty"]
    assert np.array(budget["runout_covariance"]).shape == (11, 11)
    term = runout_term(recs, CH, corr, _bases(corr, recs))
    table, _ = _table(recs, corr)
    alone = uncertainty_budget(identify(table, model="kcd11"), table, Calibration(), runout=term)
    assert budget["runout"]["Kxx"] == pytest.approx(alone.runout["Kxx"], rel=1e-9)
    sens = uncertainty_budget(identify(table, model="kcd11"), table, Calibration(sensitivity=0.001))
    assert budget["systematic"]["Kxx"] == pytest.approx(np.hypot(sens.systematic["Kxx"], alone.runout["Kxx"]), rel=1e-9)
    assert u["expanded_uncertainty"]["values"]["Kxx"] == pytest.approx(budget["expanded"]["Kxx"], rel=1e-12)
    fit = identify(table, model="kcd11")  # a report's combined covariance from the stored budget adds the term
    full = uncertainty_budget(fit, table, lms_calibration(stated, LoadSystem.PIEZO), runout=term)
    assert budget_covariance(fit, table, budget) == pytest.approx(full.covariance_combined, rel=1e-9)
    names = list(u["coefficients"])
    with h5py.File(tmp_path / "fit.h5", "w") as f:  # run.h5's fit group: uncertainty/runout beside systematic
        write_fit_analysis(f.create_group("fit"), u, names)
        f["fit"].create_dataset("names", data=fixed_text(names))
        annotate(f)
        stored = f["fit/uncertainty/runout"][()]
        assert stored[names.index("Kxx")] == pytest.approx(budget["runout"]["Kxx"], rel=1e-12)
        assert f["fit/uncertainty/runout"].attrs["units_Kxx"] == f["fit/uncertainty/systematic"].attrs["units_Kxx"]
        # and its covariance, what rebuilds the term (as sources and source_std the calibration's)
        cov = f["fit/uncertainty/runout_covariance"]
        assert [str(n) for n in cov.attrs["names"]] == list(u["free"])
        np.testing.assert_allclose(cov[()], alone.covariance_runout, rtol=1e-9, atol=0)
        assert cov.attrs["units_Kxx"] == "N/m" and cov.attrs["units_Cxx"] == "N s/m"
    none = identify_operating_point(SPIN, recs, CH, [spec], None, stated, Corrections(runout=runout))
    assert "runout" not in none.identifications[("piezo", spec.key)]["json"]["uncertainty"]


def test_the_two_systems_share_the_runout_term_so_their_difference_holds_what_does_not_cancel():
    """The two load measuring systems' tables share x, y, so a runout error moves both fits: their
    difference's covariance gains (J_a - J_b)(J_a - J_b)^T, nothing for two identical tables, and
    for forces 2 % apart in gain exactly the difference of the two fits' columns."""
    rng = np.random.default_rng(5)
    runout = 2e-6 * np.exp(1j * rng.uniform(0, 2 * np.pi, (4, 2)))
    recs = _point(runout, rng, revolutions=6)
    corr = Corrections(runout=runout, runout_u=np.full((4, 2), U_RUNOUT))
    table, _ = _table(recs, corr)
    term = runout_term(recs, CH, corr, _bases(corr, recs))
    a = identify(table, model="kcd11")
    other = dataclasses.replace(table, fx=1.02 * table.fx, fy=1.02 * table.fy)
    b = identify(other, model="kcd11")
    none = Calibration()
    _, same_without = lms_difference(a, table, a, table, none, none)
    _, same_with = lms_difference(a, table, a, table, none, none, term)
    assert np.allclose(same_with, same_without, rtol=0, atol=0)
    _, without = lms_difference(a, table, b, other, none, none)
    _, with_runout = lms_difference(a, table, b, other, none, none, term)
    jd = displacement_jacobian(a, table, term) - displacement_jacobian(b, other, term)
    scale = np.outer(*[np.sqrt(np.diag(without))] * 2)  # each entry against its coefficients' own sizes
    assert (with_runout - without) / scale == pytest.approx(jd @ jd.T / scale, abs=1e-9)
    assert jd[0] == pytest.approx(-0.02 / 1.02 * displacement_jacobian(b, other, term)[0], rel=1e-6)

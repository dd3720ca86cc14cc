"""`orbitrig sweep --sim` end to end on each simulator scenario, at the paper's Table 1
operating point (1000 rpm, eps_d 0.04, eps_s 0, p_r 0.4826 MPa, beta 0.25, its ten
Omega/omega, forward and backward, 50 revolutions): the impedance of the identified model
against the simulator's true Z(Omega), the model-adequacy test, and the coherence.

Uncertainty of Z at each frequency: the fit's statistical covariance plus the type-B budget
of the rig's stated calibration uncertainty (config/rig.toml [calibration_uncertainty]; the
budget the sweep stores, recomputed here with its covariance), propagated to Z's eight real
parts; the check is |Z_id - Z_true| <= k u(Z) with the sweep's k = 2, the largest of the
point's 20 frequencies allowed 1.3 of it (LARGEST: the frequencies share one fit). The model-adequacy
verdict is the one the sweep stores with the frequency-dependent fit (reduction.adequacy.
frequency_dependence); "not rejected" is judged at alpha = 2e-5, so that a bearing that
truly has constant coefficients (paper, clean) fails it 4 times in 100 000 runs of the file (at
1e-3 it was 2 in 1000); the compressible bearing's p is below 1e-8.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from support.e2e_sweep import impedance_misfit, stated_calibration, sweep, the_point
from reduction.adequacy import frequency_dependence
from reduction.identify import identify
from reduction.impedance import forces

ALPHA = 2e-5
#: the largest misfit of a point's 20 frequencies (1: k u(Z) on the norm, k = 2). They share the
#: fit's coefficients; drawn from the fit's own covariance (4e6 draws), clean's statistics-only
#: check passes 1 in 2.9e-3 of the runs and 1.3 in 1.1e-5; paper's piezo check (its chain's fixed
#: error, 0.58, plus the run's noise; 5 sweeps gave 0.58-0.72) passes 1 in 5e-3 and 1.3 in none
#: of 4e5. A budget that leaves out the chain's errors is far beyond (compressible: 6.4).
LARGEST = 1.3
SCENARIOS = {"clean": "config/sim/clean.toml", "compressible": "config/sim/compressible.toml", "paper": None}
#: the model that describes each scenario's bearing
ADEQUATE = {"clean": "none", "compressible": "power:1", "paper": "none"}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """One sweep per scenario, made on first use."""
    made: dict = {}

    def get(name: str):
        if name not in made:
            made[name] = sweep(tmp_path_factory.mktemp(name), SCENARIOS[name])
        return made[name]

    return get


@pytest.mark.parametrize("name", SCENARIOS)
def test_identified_impedance_is_within_its_uncertainty_of_the_true_one(runs, name):
    out, _ = runs(name)
    point = the_point(out)
    for lms in ("piezo", "strain"):
        misfit = impedance_misfit(point, lms, ADEQUATE[name], stated_calibration(out, lms), stored_budget=True)
        assert len(misfit) == 20 and np.all(misfit <= LARGEST), (lms, misfit.round(2))
    if name == "clean":  # no chain errors on the piezo forces: the statistics alone cover it
        assert np.all(impedance_misfit(point, "piezo", "none", None) <= LARGEST)
    if name == "compressible":  # low noise: the chain's errors are outside the statistics alone
        assert np.max(impedance_misfit(point, "piezo", ADEQUATE[name], None)) > 1.0


@pytest.mark.parametrize("name", SCENARIOS)
def test_frequency_dependence_is_found_only_in_the_compressible_bearing(runs, name):
    point = the_point(runs(name)[0])
    stored = point.identification("piezo", "kcd11", "power:1").result["adequacy"]
    assert stored["constant"] == "kcd11 none ols", stored  # the constant fit it was tested against
    if name == "compressible":
        assert stored["supported"] and stored["p_value"] < 1e-8, stored["verdict"]
        # the bearing needs nothing beyond power:1: on its true Z (the table's orbits and u,
        # noise-free forces) a richer polynomial gains nothing
        table = point.tables["piezo"]
        fx, fy = forces(np.asarray(point.truth["Z_re"]) + 1j * np.asarray(point.truth["Z_im"]), table.x, table.y)
        true_table = dataclasses.replace(table, fx=fx, fy=fy)
        richer = frequency_dependence(identify(true_table, "kcd11", "power:1"), identify(true_table, "kcd11", "poly:2"))
        assert not richer.supported, richer.verdict
        # the measured table: at this low noise the chain's frequency-dependent phase (force delay,
        # filters; the systematic budget) can reach the 5 % level, never the bearing's 1e-8
        measured = frequency_dependence(identify(table, "kcd11", "power:1"), identify(table, "kcd11", "poly:2"))
        assert measured.p_value > 1e-6, measured.verdict  # (10 sweeps: 1.7e-4 .. 0.86)
    else:  # a constant bearing: p is uniform, so the sweep's 5 % verdict errs once in 20 runs by
        # design; held here at ALPHA (20 sweeps of paper and clean gave p >= 0.10)
        assert stored["p_value"] > ALPHA, stored["verdict"]


def test_table1_coherence_lies_in_the_papers_range(runs):
    point = the_point(runs("paper")[0])
    coherence = np.array([f.coherence for f in point.frequencies])  # (20, 2 LMS, 4 pairs)
    assert coherence.shape == (20, 2, 4)
    assert 0.91 <= coherence.min() and coherence.max() <= 0.996, (coherence.min(), coherence.max())


def test_the_run_stores_the_true_impedance_and_its_best_fits(runs):
    import h5py

    out, stdout = runs("clean")
    truth = the_point(out).truth
    z = np.asarray(truth["Z_re"]) + 1j * np.asarray(truth["Z_im"])
    assert z.shape == (20, 2, 2) and len(truth["orbit"]) == 20
    w = np.abs(np.asarray(truth["orbit"]))
    c = truth["fits"]["constant"]
    # compressibility off: Z = K + i w C - w^2 M exactly, so the constant best fit reproduces it
    fit = np.asarray(c["K"]) + 1j * w[:, None, None] * np.asarray(c["C"]) - w[:, None, None] ** 2 * np.asarray(c["D"])
    assert np.abs(fit - z).max() < 1e-6 * np.abs(z).max()
    assert truth["K0"] == c["K"] and np.array_equal(truth["band"], np.unique(w))
    with h5py.File(out / "run.h5", "r") as f:
        g = f["points/0000/truth"]
        assert g["Z"].attrs["units"] == "N/m" and g["orbit"].attrs["units"] == "rad/s"
        assert np.allclose(g["Z"][()], z) and np.allclose(g["fits/constant/K"][()], c["K"])
        assert g["fits/power/Km"].attrs["units"] == "N/m (rad/s)^-1"
        assert f.attrs["sim_scenario_name"] == "config/sim/clean.toml"
        assert "compressible = false" in f.attrs["sim_scenario_config"]
    text = " ".join(stdout.split())
    assert "|dZ|/|Z|" in text and "true = the simulator's true Z(Omega) projected onto each fit's model" in text


def test_every_fit_stores_its_own_truth_expanded_uncertainty_and_not_determined(runs):
    """The compressible run: each fit's truth is its model's projection of the stored true Z
    (remade here from the stored table), and coefficients.csv, run.h5 and the closing table
    carry it with U (k = 2, combined) and the not-determined marks."""
    import csv

    import h5py

    from orbitrig.run.model_truth import model_truth
    from orbitrig.run.truth import true_impedance
    from orbitrig.store.reader import freq_dep_key

    out, stdout = runs("compressible")
    point = the_point(out)
    rows = list(csv.DictReader(open(out / "coefficients.csv")))
    with h5py.File(out / "run.h5", "r") as f:
        for lms in ("piezo", "strain"):
            for fd in ("none", "power:1"):
                d = point.identification(lms, "kcd11", fd).result
                table = point.tables[lms]
                again = model_truth(identify(table, "kcd11", fd), table, true_impedance(point.truth))
                assert d["truth"]["coefficients"] == pytest.approx(again["coefficients"], rel=1e-9)
                u = d["expanded_uncertainty"]
                assert u["basis"] == "combined" and u["values"] == d["uncertainty"]["expanded"]
                assert d["not_determined"] == [k for k, v in d["coefficients"].items() if u["values"][k] > abs(v)]
                row = next(r for r in rows if (r["lms"], r["model"], r["freq_dep"]) == (lms, "kcd11", fd))
                assert float(row["true_Dxy [kg]"]) == pytest.approx(d["truth"]["coefficients"]["Dxy"], rel=1e-6)
                assert float(row["Kxx_U [N/m]"]) == pytest.approx(u["values"]["Kxx"], rel=1e-5)
                assert row["not_determined"].split() == d["not_determined"]
                g = f[f"points/0000/identification/{lms}__kcd11__{freq_dep_key(fd)}__ols"]
                names = [n.decode() for n in g["names"][()]]
                assert np.allclose(g["truth"][()], [d["truth"]["coefficients"][k] for k in names])
                assert np.allclose(g["expanded_uncertainty"][()], [u["values"][k] for k in names])
                assert [n for n, m in zip(names, g["not_determined"][()]) if m] == d["not_determined"]
        # kcd11 forces D symmetric: its truth does too, while the constant best fit is skew
        const = point.truth["fits"]["constant"]["D"]
        assert const[0][1] > 20 and const[1][0] < -20
        d = point.identification("piezo", "kcd11", "none").result["truth"]["coefficients"]
        assert d["Dxy"] == d["Dyx"] and abs(d["Dxy"]) < 0.2 * const[0][1]
    text = " ".join(stdout.split())
    assert "D = apparent inertia (added mass)" in text and "const. fit = the constant K, C, D" in text

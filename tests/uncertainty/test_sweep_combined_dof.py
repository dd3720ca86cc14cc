"""The sweep's combined U takes each calibration part at its record's degrees of freedom
(orbitrig.run.calibration_dof -> point_analysis -> reduction.combined_dof): the loads fit's 8, a
probe's or a lag's line of 5 steps 3, the runout's revolutions; a record written before dof as
`calibrate show` reads it; rig.toml's typed-in u exact, and the stored budget says so."""

from __future__ import annotations

import copy
import math

import h5py
import numpy as np
import pytest

from support.reduction_synthetic import frequencies, orbit_table, truth, with_noise
from orbitrig.catalog.compare import coverage
from orbitrig.config import CalibrationRecord, CalibrationUncertainty
from orbitrig.load_systems import LoadSystem
from orbitrig.run.calibration_dof import TYPED_IN, calibration_dof
from orbitrig.run.point_analysis import analyse_point, lms_calibration
from orbitrig.store.fit_analysis import write_fit_analysis
from orbitrig.store.fit_record import expanded_ks
from reduction.identify import identify
from reduction.statistics import Interval, coverage_factor

RUNOUT = {"h1_um": [1.0, 0.0], "h2_um": [0.1, 0.0], "h1_u_um": 0.01, "h2_u_um": 0.01}


def _record(new: bool = True) -> CalibrationRecord:
    dof = {"dof": 8} if new else {}
    line = {"dof": 3} if new else {}
    return CalibrationRecord.model_validate(
        {
            "date": "2026-12-01T08:30:00Z",
            "operator": "a",
            "step": "probes",
            "loads": {"piezo": {"gain": [[1, 0], [0, 1]], "gain_u": [[0.01, 0], [0, 0.01]], "loads": 7, **dof}},
            "probes": {p: {"gain": 1.0, "gain_u": 0.01, "steps": 5, **line} for p in ("x_a", "y_a", "x_b")},
            "delay": {"fx_piezo": {"phase_deg": 0.1, "delay_us": 2.0, **line}},
            "runout": {"spin_rpm": 60, "revolutions": 10, **{p: RUNOUT for p in ("x_a", "y_a", "x_b", "y_b")}},
        }
    )


def test_each_channel_takes_its_fits_dof_from_the_record():
    d = calibration_dof(_record())
    assert d.gain_of("fx_piezo") == d.gain_of("fy_piezo") == 8  # one gain-matrix fit, 2 (7 - 3)
    assert d.gain_of("x_a") == 3 and d.lag_of("fx_piezo") == 3  # lines of 5 steps, 5 speeds
    assert math.isinf(d.gain_of("y_b")) and math.isinf(d.gain_of("fx_strain")) and math.isinf(d.lag_of("x_a"))
    assert d.runout == 9 and d.notes == []  # the scatter of 10 revolutions
    cal = lms_calibration(CalibrationUncertainty(), LoadSystem.PIEZO, d)
    assert (cal.fx.gain_dof, cal.fx.lag_dof, cal.fy.gain_dof) == (8, 3, 8)
    assert cal.x.gain_dof == cal.y.gain_dof == 3  # y: y_a's 3 and y_b's none (exact): the smaller


def test_a_record_before_dof_is_read_as_calibrate_show_reads_it_and_says_so():
    d = calibration_dof(_record(new=False))
    assert d.gain_of("fx_piezo") == 8 and d.gain_of("x_a") == 3  # from its loads and steps
    assert math.isinf(d.lag_of("fx_piezo"))  # its speeds not kept: exact, as before
    assert "[loads.piezo] written before records held dof: its u at its fit's 8 dof" in d.notes
    assert "[delay.fx_piezo] written before records held dof: its u taken as exactly known" in d.notes
    typed = calibration_dof(None)
    assert typed.notes == [TYPED_IN] and math.isinf(typed.gain_of("fx_piezo"))


def test_a_record_that_measured_the_runout_alone_keeps_its_revolutions_dof():
    only = CalibrationRecord.model_validate(_record().model_dump() | {"loads": {}, "probes": {}, "delay": {}})
    d = calibration_dof(only)
    assert d.runout == 9  # was inf: the record's channel u typed in, its runout measured all the same
    assert d.notes == [TYPED_IN] and math.isinf(d.gain_of("fx_piezo"))


def _point(stated, dof):
    TRUE = truth("kc8", {"K": (0,), "C": (0,)})
    clean = orbit_table(TRUE, frequencies(4))
    s = 3e-3 * float(np.sqrt(np.mean(np.abs(clean.fx) ** 2)))
    tables = {lms: with_noise(clean, np.random.default_rng(i), (0, 0, s, s)) for i, lms in enumerate(LoadSystem)}
    fits = {(lms, "kc8"): identify(t, "kc8") for lms, t in tables.items()}
    idents = {key: {"spec": None, "json": f.to_dict()} for key, f in fits.items()}
    analyse_point(clean.spin, tables, fits, idents, stated, np.array([20.0]), None, dof)
    return idents[(LoadSystem.PIEZO, "kc8")]["json"]


def test_the_stored_u_has_each_coefficients_k_at_its_effective_dof():
    stated = CalibrationUncertainty.model_validate({"fx_piezo": {"gain_pct": 5.0}, "fy_piezo": {"gain_pct": 5.0}})
    d = _point(stated, calibration_dof(_record()))
    u, e = d["uncertainty"], d["expanded_uncertainty"]
    # K's u is the 5 % gain's, 8 dof: k near t(8) = 2.37; the fit's own part (u_*: normal) adds dof
    assert u["dof"]["Kxx"] == pytest.approx(8, rel=0.05)
    assert u["k_values"]["Kxx"] == pytest.approx(coverage_factor(Interval.STUDENT_T, 8), abs=0.01)
    assert u["expanded"]["Kxx"] == pytest.approx(u["k_values"]["Kxx"] * u["combined"]["Kxx"])
    assert u["k"] == max(u["k_values"].values()) and e["k_values"] == u["k_values"] and e["values"] == u["expanded"]
    assert u["dof_notes"] == []
    typed = _point(stated, calibration_dof(None))["uncertainty"]
    assert set(typed["k_values"].values()) == {2.0} and set(typed["dof"].values()) == {None}
    assert typed["dof_notes"] == [TYPED_IN]


def test_run_h5_and_the_catalog_read_each_coefficients_k_and_an_older_run_its_one_k(tmp_path):
    stated = CalibrationUncertainty.model_validate({"fx_piezo": {"gain_pct": 5.0}, "fy_piezo": {"gain_pct": 5.0}})
    d = _point(stated, calibration_dof(_record()))
    names, ks = list(d["coefficients"]), d["uncertainty"]["k_values"]
    assert min(ks.values()) < 2.1 < 2.3 < max(ks.values())  # Cxy's part of the gain small, Kxx's large
    old = copy.deepcopy(d)  # a run stored before k_values: one k, the budget's
    for part in (old["uncertainty"], old["expanded_uncertainty"]):
        part.pop("k_values")
        part.pop("dof", None)
    for label, fit, want in (("new", d, ks), ("old", old, dict.fromkeys(names, d["uncertainty"]["k"]))):
        assert expanded_ks(fit) == pytest.approx(want)  # the CSV's KEY_k and the catalog's k_values
        with h5py.File(tmp_path / f"{label}.h5", "w") as f:
            write_fit_analysis(f.create_group("fit"), fit, names)
            assert list(f["fit/expanded_k"][()]) == pytest.approx([want[n] for n in names])
            assert ("k_values" in f["fit/uncertainty"]) == (label == "new")
            if label == "new":
                assert list(f["fit/uncertainty/k_values"][()]) == pytest.approx(list(f["fit/expanded_k"][()]))
        row = {"coefficients_json": {"k": d["uncertainty"]["k"], "k_values": expanded_ks(fit)}}
        assert coverage(row, "Cxy") == pytest.approx(want["Cxy"])  # catalog compare: u = U / this k


def test_the_stored_source_dof_rebuilds_each_k():
    """The budget keeps each source's dof (source_dof, null: exact) beside source_std: a fit made
    later from the same table (a ROSS constant fit) rebuilds the sweep's k from them, none else."""
    from orbitrig.analysis.quality import budget_coverage

    stated = CalibrationUncertainty.model_validate({"fx_piezo": {"gain_pct": 5.0}, "fy_piezo": {"gain_pct": 5.0}})
    TRUE = truth("kc8", {"K": (0,), "C": (0,)})
    clean = orbit_table(TRUE, frequencies(4))
    s = 3e-3 * float(np.sqrt(np.mean(np.abs(clean.fx) ** 2)))
    tables = {lms: with_noise(clean, np.random.default_rng(i), (0, 0, s, s)) for i, lms in enumerate(LoadSystem)}
    fits = {(lms, "kc8"): identify(t, "kc8") for lms, t in tables.items()}
    idents = {key: {"spec": None, "json": f.to_dict()} for key, f in fits.items()}
    analyse_point(clean.spin, tables, fits, idents, stated, np.array([20.0]), None, calibration_dof(_record()))
    u = idents[(LoadSystem.PIEZO, "kc8")]["json"]["uncertainty"]
    dof = dict(zip(u["sources"], u["source_dof"]))
    assert dof["fx.gain"] == dof["fy.gain"] == 8 and dof["fx.phase"] == dof["fx.delay"] == 3
    assert dof["x.sensitivity"] is None  # the reference's certificate: exact
    ks = budget_coverage(fits[(LoadSystem.PIEZO, "kc8")], tables[LoadSystem.PIEZO], u)
    assert ks == pytest.approx(u["k_values"], rel=1e-12) and max(ks.values()) > 2.3

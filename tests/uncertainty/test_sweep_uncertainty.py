"""A sweep on the simulator reports how far its coefficients can be trusted: orbit tables with
u_* and n_records, the uncertainty budget from rig.toml's calibration uncertainty, the two load
measuring systems' consistency, the model-adequacy verdict, derived quantities, warnings and
refused models - stored, in run.log, on the terminal and in the exported tables."""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import h5py
import numpy as np
import pytest

from support.cli_helpers import orbitrig
from support.paths import ROOT

# compressible scenario: the constant model misses the falling damping (with 40 revolutions per
# block far beyond the phasor uncertainty: bad chi2 -> a warning, frequency dependence supported);
# kcd12 poly:4 needs 12 frequencies (refused with 5)
REVOLUTIONS = 40
MATRIX = f"""name = "judged"
revolutions = {REVOLUTIONS}
[operating]
spin_rpm = [1000.0]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.4]
static_eccentricity = [0.0]
dynamic_eccentricity = [0.096]
[orbit]
ratios = [0.3, 0.5, 0.7, 0.9, 1.2]
directions = ["forward", "backward"]
[[models]]
model = "kcd11"
[[models]]
model = "kcd11"
freq_dep = "power:1"
[[models]]
model = "kcd12"
freq_dep = "poly:4"
"""


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    work = tmp_path_factory.mktemp("judged")
    (work / "judged.toml").write_text(MATRIX)
    out = work / "run"
    res = orbitrig(
        "sweep",
        "--sim",
        "--sim-config",
        "config/sim/compressible.toml",
        "--matrix",
        str(work / "judged.toml"),
        "--out",
        str(out),
        timeout=240,
    )
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    return out, res.stdout + res.stderr


def _fits(run: Path) -> dict[str, h5py.Group]:
    f = h5py.File(run / "run.h5", "r")
    return f, f["points/0000"]


def _stated() -> dict:
    return tomllib.loads((ROOT / "config" / "rig.toml").read_text())["calibration_uncertainty"]


def test_orbit_tables_carry_revolutions_and_phasor_uncertainties(sweep):
    run, _ = sweep
    f, g = _fits(run)
    with f:
        for lms in ("piezo", "strain"):
            t = g[f"table/{lms}"]
            assert t["n_records"][()].tolist() == [REVOLUTIONS] * 10
            u = t["u"][()]
            assert u.shape == (10, 4) and np.all(u > 0)
            # orbit 0.096 x 60 um; per-revolution noise ~0.1 um probes, ~55 N forces, over sqrt(40)
            assert np.all(u[:, :2] < 0.03 * 0.096 * 60e-6) and np.all(u[:, 2:] < 25.0)
            fit = json.loads(g[f"identification/{lms}__kcd11__none__ols"].attrs["json"])
            assert fit["chi2"] is not None and 0 <= fit["p_value"] <= 1


def test_budget_uses_the_stated_calibration_uncertainty(sweep):
    run, _ = sweep
    stated = _stated()
    f, g = _fits(run)
    with f:
        for lms in ("piezo", "strain"):
            h = g[f"identification/{lms}__kcd11__none__ols"]
            u = h["uncertainty"]
            sources = [s.decode() for s in u["sources"][()]]
            sd = dict(zip(sources, u["source_std"][()]))
            assert math.isclose(sd["fx.gain"], stated[f"fx_{lms}"]["gain_pct"] / 100)
            assert math.isclose(sd["fy.phase"], math.radians(stated[f"fy_{lms}"]["phase_deg"]))
            assert math.isclose(sd["fx.delay"], stated[f"fx_{lms}"]["delay_us"] * 1e-6)
            assert math.isclose(sd["x.sensitivity"], stated["probe_sensitivity_pct"] / 100)
            stat, sys_, comb, exp = (u[k][()] for k in ("statistical", "systematic", "combined", "expanded"))
            np.testing.assert_allclose(comb, np.hypot(stat, sys_), rtol=1e-9)
            np.testing.assert_allclose(exp, 2 * comb, rtol=1e-12)
            assert u.attrs["k"] == 2.0
            names = [s.decode() for s in h["names"][()]]
            k = np.array([n in ("Kxx", "Kyy") for n in names])
            # force gain 0.5 % (piezo) / 2.5 % (strain), probe sensitivity 1 %: Kxx, Kyy relative systematic part
            rel = sys_[k] / np.abs(h["coefficients"][()][k])
            lo, hi = (0.025, 0.04) if lms == "strain" else (0.01, 0.02)
            assert np.all(rel > lo) and np.all(rel < hi), rel
            assert h["interval_95"].shape == (len(names), 2)
        strain_sys = g["identification/strain__kcd11__none__ols/uncertainty/systematic"][()]
        piezo_sys = g["identification/piezo__kcd11__none__ols/uncertainty/systematic"][()]
        assert strain_sys[0] > 1.5 * piezo_sys[0]  # Kxx: the strain gauges' 2.5 % against 0.5 %


def test_adequacy_consistency_and_derived_quantities_are_stored(sweep):
    run, _ = sweep
    f, g = _fits(run)
    with f:
        a = g["identification/piezo__kcd11__power_1__ols/adequacy"].attrs
        assert a["supported"] and a["verdict"].startswith("frequency dependence supported: yes (p = ")
        assert a["p_value"] < 0.05 and a["constant"] == "kcd11 none ols" and a["aic"].shape == (2,)
        assert "adequacy" not in g["identification/piezo__kcd11__none__ols"]
        c = g["identification/piezo__kcd11__none__ols/lms_consistency"]
        assert c.attrs["basis"] == "combined" and c["e_n"].attrs["units"] == "1"
        assert 0 < c.attrs["max_abs"] == np.nanmax(np.abs(c["e_n"][()]))
        # the verdict is the joint chi2 of kcd11's 11 free coefficients (D symmetric: Dxy = Dyx)
        # at the family-wise 5 % level: limit chi2(11) 95 % quantile = 19.675
        assert c.attrs["test"] == "chi2" and c.attrs["level"] == 0.05 and c.attrs["dof"] == 11
        assert c.attrs["consistent"] == (c.attrs["chi2"] <= c.attrs["limit"]) and c.attrs["limit"] == pytest.approx(
            19.675, abs=1e-3
        )
        d = g["identification/piezo__kcd11__none__ols/derived"]
        np.testing.assert_allclose(d["orbit_hz"][()], np.array([0.3, 0.5, 0.7, 0.9, 1.2]) * 1000 / 60, rtol=1e-9)
        fit = json.loads(g["identification/piezo__kcd11__none__ols"].attrs["json"])
        names = list(fit["coefficients"])
        theta = fit["coefficients"]
        w = d["orbit"][()]
        np.testing.assert_allclose(d["c_eff_xx"][()], theta["Cxx"] - theta["Kxy"] / w, rtol=1e-9)
        wfr = (theta["Kxy"] - theta["Kyx"]) / (1000 * 2 * math.pi / 60 * (theta["Cxx"] + theta["Cyy"]))
        np.testing.assert_allclose(d["wfr"][()], wfr, rtol=1e-9)
        assert d.attrs["covariance"] == "combined" and np.all(d["c_eff_xx_std"][()] > 0)
        assert len(names) == 12

        def units(name, obj):
            if isinstance(obj, h5py.Dataset) and obj.dtype.kind in "fciu":  # one unit, or one per entry
                assert any(k == "units" or k.startswith("units_") for k in obj.attrs), name

        g["identification"].visititems(units)


def test_warnings_refusals_and_verdicts_reach_the_terminal_and_run_log(sweep):
    run, out = sweep
    log = (run / "run.log").read_text()
    for text in (out, log):
        assert "piezo kcd11 none ols: warning: bad fit: chi2 = " in text
        assert "piezo kcd12 poly:4 ols: refused: kcd12 with freq-dep poly:4 (48 coefficients)" in text
        assert "piezo kcd11 power:1 ols: frequency dependence supported: yes (p = " in text
        assert "kcd11 none ols: load measuring systems piezo - strain: " in text
        assert " on 11 coefficients " in text.split("kcd11 none ols: load measuring systems piezo - strain: ")[1]
    assert "(the full reason is in run.log)" in out and "What would separate them" not in out
    assert " | " in log.split("kcd12 poly:4 ols: refused:")[1].splitlines()[0]  # the whole reason, one line
    assert (
        "\u00b1" in out and "expanded uncertainty U (a coverage probability of about 95 %: k = 2, or Student's t" in out
    )


def test_exported_tables_give_chi2_to_identify(sweep, tmp_path):
    run, _ = sweep
    res = orbitrig("export", str(run), "--format", "csv", "--out", str(tmp_path))
    assert res.returncode == 0, res.stderr
    table = tmp_path / "point_0000_strain.csv"
    header = table.read_text().splitlines()[0].split(",")
    assert {"n_records [1]", "u_x [m]", "u_y [m]", "u_fx [N]", "u_fy [N]", "direction [1]"} <= set(header)
    res = orbitrig("identify", str(table), "--model", "kcd11", "--json")
    assert res.returncode == 0, res.stderr
    fit = json.loads(res.stdout)
    assert fit["chi2"] > 0 and 0 <= fit["p_value"] <= 1 and fit["dof"] == 40 - 11


@pytest.mark.parametrize("bad, why", [("nan", "finite number"), ("-0.5", "greater than or equal to 0")])
def test_a_bad_calibration_uncertainty_is_refused_with_file_line_and_key(tmp_path, bad, why):
    text = (ROOT / "config" / "rig.toml").read_text()
    head, _, tail = text.partition("[calibration_uncertainty.fy_strain]")
    tail = tail.replace("gain_pct = 2.5", f"gain_pct = {bad}", 1)
    rig = tmp_path / "rig.toml"
    rig.write_text(head + "[calibration_uncertainty.fy_strain]" + tail)
    line = (head + "[calibration_uncertainty.fy_strain]" + tail).splitlines().index(f"gain_pct = {bad}") + 1
    res = orbitrig("sweep", "--dry-run", "--config", str(rig), "--matrix", "demo", timeout=60)
    assert res.returncode == 2
    assert f"{rig}: line {line}: key 'calibration_uncertainty.fy_strain.gain_pct'" in res.stderr
    assert why in res.stderr and "Traceback" not in res.stderr


def test_result_payload_carries_the_warnings_of_a_stored_run(sweep):
    from orbitrig import config as cfg
    from orbitrig.config import ModelSpec
    from orbitrig.run.plan import make_plan
    from orbitrig.run.point_report import result_payload
    from orbitrig.service.protocol import result_payload as mqtt_result
    from orbitrig.store.reader import read_run
    from orbitrig.store.records import PointResults

    run, _ = sweep
    stored = read_run(run).complete_points[0]
    idents = {}
    for i in stored.identifications:
        spec = ModelSpec(model=i.model, freq_dep=i.freq_dep, method=i.method)
        idents[(i.lms, spec.key)] = {"spec": spec, **({"json": i.result} if i.ok else {"error": i.error})}
    plan = make_plan(cfg.matrix_from_text(MATRIX, "judged.toml"), cfg.load_rig())
    res = PointResults(stored.tables, idents, stored.lms_comparison)
    obj = json.loads(mqtt_result("r1", result_payload("r1", plan.points[0], res)))
    assert any(w.startswith("piezo kcd11 none ols: bad fit: chi2 = ") for w in obj["warnings"])
    row = next(r for r in obj["identification"] if (r["lms"], r["model"], r["freq_dep"]) == ("piezo", "kcd11", "none"))
    assert row["warnings"] and set(row["confidence_95"]) == set(row["coefficients"])
    assert (
        set(row["units"]) == set(row["coefficients"])
        and row["units"]["Kxx"] == "N/m"
        and row["units"]["Cxy"] == "N s/m"
    )
    u = row["expanded_uncertainty"]
    assert u["basis"] == "combined" and u["values"] == row["uncertainty"]["expanded"]
    assert row["not_determined"] == [k for k, v in row["coefficients"].items() if u["values"][k] > abs(v)]
    assert {a["verdict"][:36] for a in obj["adequacy"]} == {"frequency dependence supported: yes "}

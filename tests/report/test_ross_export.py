"""orbitrig export --format ross: the identified bearings as ROSS BearingElement data, loaded
into ross-rotordynamics (the `ross` extra) for a small rotor's modal analysis."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from orbitrig.cli import app
from orbitrig.store.reader import read_run
from support.units import UREG


def _export(run_dir, out, *fit):
    res = CliRunner().invoke(app, ["export", str(run_dir), "--format", "ross", "--out", str(out), *fit])
    assert res.exit_code == 0, res.output
    return json.loads((out / "ross_bearings.json").read_text())


def test_export_gives_the_stored_fit_at_the_rotor_speed(synthetic_run, tmp_path):
    """One spin per test condition here: each point is a bearing of one speed (its spin, rad/s),
    the constant fit as stored, the frequency-dependent one at the synchronous whirl Omega = omega."""
    run = read_run(synthetic_run)
    doc = _export(synthetic_run, tmp_path / "c")
    assert [b["points"] for b in doc["bearings"]] == [[p.index] for p in run.complete_points]
    for bearing, point in zip(doc["bearings"], run.complete_points):
        stored = point.identification("piezo", "kcd11", "none").result["coefficients"]
        assert bearing["frequency"] == [point.settings.spin]  # the rotor speed, not the whirl frequencies
        for ross_key, ours in (("kxy", "Kxy"), ("cyx", "Cyx"), ("mxx", "Dxx"), ("kyy", "Kyy")):
            np.testing.assert_allclose(bearing[ross_key], [stored[ours]], rtol=1e-12)
    doc = _export(synthetic_run, tmp_path / "p", "--fit", "strain:kcd11:power:1:ols")
    bearing = doc["bearings"][0]
    stored = run.points[0].identification("strain", "kcd11", "power:1").result["coefficients"]
    w = run.points[0].settings.spin
    np.testing.assert_allclose(bearing["kxx"], [stored["Kxx"] + stored["Kxx_1"] * w], rtol=1e-12)
    assert bearing["speeds"][0]["used"] == "synchronous" and bearing["speeds"][0]["whirl"] == w
    assert bearing["lms"] == "strain" and "f = -(K d" in doc["conventions"]["force"]
    # every number's unit, for a program (pint parses each): the coefficients', the speeds', the condition's
    units = doc["units"]
    assert (units["frequency"], units["kxy"], units["cyx"], units["mxx"]) == ("rad/s", "N/m", "N s/m", "kg")
    assert (units["recess_pressure"], units["static_eccentricity"], units["whirl"]) == ("Pa", "1", "rad/s")
    numeric = {k for k, v in bearing.items() if isinstance(v, list) and v and isinstance(v[0], float)}
    numeric |= {k for k, v in bearing["condition"].items()} | {"spin", "whirl", "whirl_range"}
    assert numeric <= set(units), numeric - set(units)
    assert UREG.Quantity(bearing["kxx"][0], units["kxx"]).to("MN/m").magnitude == pytest.approx(
        bearing["kxx"][0] * 1e-6
    )
    bad = CliRunner().invoke(app, ["export", str(synthetic_run), "--format", "ross", "--fit", "piezo:kcd11"])
    assert bad.exit_code == 2 and "LMS:MODEL:FREQ_DEP:METHOD" in bad.output
    typo = CliRunner().invoke(app, ["export", str(synthetic_run), "--format", "ross", "--fit", "piezzo:kcd11:none:ols"])
    assert typo.exit_code == 2 and "LMS is one of piezo, strain" in typo.output  # not an empty bearings file


def _invoke(run_dir, out, *args):
    return CliRunner().invoke(app, ["export", str(run_dir), "--format", "ross", "--out", str(out), *args])


def test_a_fit_no_point_stores_exits_2_naming_the_fits_there_are(synthetic_run, tmp_path):
    for fit in ("piezo:nosuchmodel:none:ols", "piezo:kcd11:none:wls"):  # a model, a method not stored
        res = _invoke(synthetic_run, tmp_path / "x", "--fit", fit)
        assert res.exit_code == 2, res.output
        assert f"--fit {fit}: not stored in {synthetic_run}" in res.stderr
        assert "piezo:kcd11:none:ols" in res.stderr and "strain:kcd11:power:1:ols" in res.stderr
        assert not (tmp_path / "x" / "ross_bearings.json").exists()  # no empty bearings file
    res = _invoke(synthetic_run, tmp_path / "x", "--fit", "piezo:kcd11:none:xyz")
    assert res.exit_code == 2 and "METHOD is one of ols, wls, tls, iv" in res.stderr, res.output
    res = _invoke(synthetic_run, tmp_path / "y", "--fit", "strain:kcd12:poly:8:ols")  # refused at every point
    assert res.exit_code == 2 and "no point gives it" in res.stderr and "refused" in res.stderr, res.output


def test_points_without_the_fit_are_skipped_and_named(synthetic_run, tmp_path, monkeypatch):
    """A point that lacks the fit (here: point 1 stores no piezo kcd11) is named on standard
    error and the exit status is 1, as export names a skipped point; the others are exported."""
    import orbitrig.store.reader as reader

    run = read_run(synthetic_run)
    point = run.points[1]
    point.identifications = [i for i in point.identifications if (i.lms, i.model) != ("piezo", "kcd11")]
    monkeypatch.setattr(reader, "read_run", lambda directory: run)
    res = _invoke(synthetic_run, tmp_path, "--fit", "piezo:kcd11:none:ols")
    assert res.exit_code == 1, res.output
    assert "error: point 0001 skipped: fit piezo:kcd11:none:ols not stored" in res.stderr
    assert "point 0002 not included: never completed" in res.stderr  # the stopped run's last point: a note
    doc = json.loads((tmp_path / "ross_bearings.json").read_text())
    assert [b["points"] for b in doc["bearings"]] == [[0]]
    res = _invoke(synthetic_run, tmp_path / "one", "--point", "0")  # only the point asked for
    assert res.exit_code == 0 and "skipped" not in res.stderr, res.output
    doc = json.loads((tmp_path / "one" / "ross_bearings.json").read_text())
    assert [b["points"] for b in doc["bearings"]] == [[0]]


def test_measured_bearings_in_a_ross_rotor_give_finite_log_decrements(synthetic_run, tmp_path):
    from orbitrig.analysis.ross_elements import bearing_elements, import_ross

    ross = import_ross()  # the ross extra (tools/run-tests installs .[test,ross])

    _export(synthetic_run, tmp_path)
    steel = ross.materials.steel
    shaft = [ross.ShaftElement(L=0.2, idl=0.0, odl=0.06, material=steel) for _ in range(6)]
    disk = ross.DiskElement.from_geometry(n=3, material=steel, width=0.07, i_d=0.06, o_d=0.3)
    with pytest.warns(UserWarning, match="not determined"):  # point 1's apparent mass: U > |D|
        bearings = bearing_elements(tmp_path / "ross_bearings.json", [0, 6], point=1)
    np.testing.assert_allclose(bearings[0].K(40.0)[0, 0], 3.3e7, rtol=0.02)  # K_TRUE xx, interpolated
    modal = ross.Rotor(shaft, [disk], bearings).run_modal(speed=100.0)
    log_dec = np.asarray(modal.log_dec)[:6]
    assert np.all(np.isfinite(log_dec)) and np.all(np.asarray(modal.wd)[:6] > 0)
    assert np.any(log_dec > 0)  # the film's damping shows in the modes


def test_ross_imported_through_orbitrig_leaves_the_warning_format_as_it_was():
    """A dependency of ROSS (plotly.tools) sets warnings.formatwarning on import ("file:line:
    Category:", a blank line, the message): a command's later warnings, e.g. a calibration record's
    at its file and line, would no longer read as one line. Imported through orbitrig, it is kept."""
    import warnings

    from orbitrig.analysis.ross_elements import import_ross

    import_ross()
    text = warnings.formatwarning("an older record", UserWarning, "cal/runout.toml", 3)
    assert text == "cal/runout.toml:3: UserWarning: an older record\n"

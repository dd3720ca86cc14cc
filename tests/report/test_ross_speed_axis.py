"""orbitrig export --format ross over rotor speed: ROSS evaluates a bearing at the rotor speed, so
the export's axis is the points' spin omega, each speed with the fit at the synchronous whirl
Omega = omega (or the constant fit when omega is outside the tested whirl range), U and the
coefficients not determined; bearing_elements holds the end values outside the speeds, checked
with ross-rotordynamics itself (the `ross` extra)."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from orbitrig import config as cfg
from orbitrig.analysis.reduce import identify_point
from orbitrig.cli import app
from orbitrig.store.fit_record import point_fits
from orbitrig.store.reader import read_run

SPINS_RPM = (500.0, 1000.0, 1500.0)
MATRIX = """
name = "speeds"
description = "ross export: three spins of one test condition"

[operating]
spin_rpm = [500.0, 1000.0, 1500.0]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.25]
static_eccentricity = [0.0]
dynamic_eccentricity = [0.04]

[orbit]
ratios = [0.3, 0.5, 0.7, 0.9, 1.1, 1.2]
directions = ["forward", "backward"]

[[models]]
model = "kcd11"

[[models]]
model = "kcd11"
freq_dep = "power:1"

[[models]]
model = "kc8"
freq_dep = "power:1"
"""
KEYS = [f"{c}{e}" for c in "kcm" for e in ("xx", "xy", "yx", "yy")]
OURS = {"k": "K", "c": "C", "m": "D"}


@pytest.fixture(scope="module")
def speed_run(tmp_path_factory):
    """Three complete points at 500, 1000 and 1500 rpm, one test condition, a stated calibration
    uncertainty (U combined); kcd11 constant and power:1, kc8 power:1 (its constant fit not stored)."""
    import support.report_synthetic as synthetic

    stated = cfg.CalibrationUncertainty(
        probe_sensitivity_pct=1.0,
        fx_piezo=cfg.ChannelUncertainty(gain_pct=0.5, phase_deg=0.05, delay_us=20.0),
        fy_piezo=cfg.ChannelUncertainty(gain_pct=0.5, phase_deg=0.05, delay_us=20.0),
    )
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(synthetic, "MATRIX", MATRIX)
        return synthetic.write_synthetic_run(
            tmp_path_factory.mktemp("speeds") / "run", n_points=3, incomplete=0, calibration=stated
        )


def _invoke(run_dir, out, *args):
    return CliRunner().invoke(app, ["export", str(run_dir), "--format", "ross", "--out", str(out), *args])


def _doc(out):
    return json.loads((out / "ross_bearings.json").read_text())


def _record(point, lms, model, freq_dep):
    return next(f for f in point_fits(point) if (f.lms, f.model, f.freq_dep) == (lms, model, freq_dep))


def _at(record, key, w):
    """Our K, C, D entry of ROSS ``key`` summed over the record's orders at whirl w."""
    name = OURS[key[0]] + key[1:]
    return sum(v * w ** int(n.partition("_")[2] or 0) for n, v in zip(record.names, record.value) if n[:3] == name)


def test_the_frequency_axis_is_the_rotor_speed_with_synchronous_coefficients(speed_run, tmp_path):
    run = read_run(speed_run)
    res = _invoke(speed_run, tmp_path, "--fit", "piezo:kcd11:power:1:ols")
    assert res.exit_code == 0, res.output
    spins = [p.settings.spin for p in run.complete_points]
    assert [b["frequency"] for b in _doc(tmp_path)["bearings"]] == [spins]  # one condition: one bearing over speed
    (bearing,) = _doc(tmp_path)["bearings"]
    np.testing.assert_allclose(spins, np.array(SPINS_RPM) * 2 * np.pi / 60, rtol=1e-12)
    assert bearing["points"] == [0, 1, 2] and bearing["frequency"] == spins
    for i, point in enumerate(run.complete_points):
        record = _record(point, "piezo", "kcd11", "power:1")
        for key in KEYS:
            np.testing.assert_allclose(bearing[key][i], _at(record, key, spins[i]), rtol=1e-12, atol=1e-12)
        speed = bearing["speeds"][i]
        assert (speed["used"], speed["whirl"], speed["fit"]) == ("synchronous", spins[i], "piezo:kcd11:power:1:ols")
        assert speed["whirl_range"] == pytest.approx([0.3 * spins[i], 1.2 * spins[i]], rel=1e-12)
    assert "end values held below 52.3599 and above 157.08 rad/s" == bearing["outside"]
    # each speed with its unit, the points named as its warnings name them
    assert (
        "ross: piezo bearing of points 0000, 0001, 0002: 52.3599 rad/s synchronous (piezo:kcd11:power:1:ols), "
        in res.stderr
    )


def test_the_constant_fit_outside_the_tested_whirl_range(speed_run, tmp_path, monkeypatch):
    """Point 2 tested only below its spin (ratios < 1 kept): the constant fit of the same model
    and method there, the stored one, or for kc8 (none stored) one fitted from the orbit table."""
    import orbitrig.store.reader as reader

    run = read_run(speed_run)
    point = run.points[2]
    point.frequencies = [f for f in point.frequencies if abs(f.orbit) < point.settings.spin]
    monkeypatch.setattr(reader, "read_run", lambda directory: run)
    assert _invoke(speed_run, tmp_path / "a", "--fit", "piezo:kcd11:power:1:ols").exit_code == 0
    (bearing,) = _doc(tmp_path / "a")["bearings"]
    assert [s["used"] for s in bearing["speeds"]] == ["synchronous", "synchronous", "constant"]
    assert bearing["speeds"][2]["fit"] == "piezo:kcd11:none:ols" and bearing["speeds"][2]["whirl"] is None
    assert "outside the tested whirl range 47.1239..141.372 rad/s" in bearing["speeds"][2]["why"]
    constant = _record(point, "piezo", "kcd11", "none")
    for key in KEYS:
        assert bearing[key][2] == _at(constant, key, 0.0)
        assert bearing["U"][key][2] == constant.U[constant.names.index(OURS[key[0]] + key[1:])]
    assert _invoke(speed_run, tmp_path / "b", "--fit", "piezo:kc8:power:1:ols").exit_code == 0
    speed = _doc(tmp_path / "b")["bearings"][0]["speeds"][2]
    assert speed["fit"] == "piezo:kc8:none:ols (not stored: fitted here from the orbit table)"
    assert speed["basis"] == "combined"  # on the calibration the run stated (its stored budgets)
    fitted = identify_point(point, "piezo", "kc8", "none", "ols").identification.coefficients
    assert _doc(tmp_path / "b")["bearings"][0]["cxy"][2] == pytest.approx(fitted["Cxy"], rel=1e-12)


def test_a_second_point_at_a_speed_taken_is_skipped_and_named(speed_run, tmp_path, monkeypatch):
    import orbitrig.store.reader as reader

    run = read_run(speed_run)
    run.points[2].settings = dataclasses.replace(run.points[2].settings, spin=run.points[1].settings.spin)
    monkeypatch.setattr(reader, "read_run", lambda directory: run)
    res = _invoke(speed_run, tmp_path, "--fit", "piezo:kcd11:none:ols")
    assert res.exit_code == 1, res.output
    assert "error: point 0002 skipped: spin 104.72 rad/s and condition as point 0001" in res.stderr
    assert _doc(tmp_path)["bearings"][0]["points"] == [0, 1]


def test_every_coefficient_carries_its_U_at_every_speed(speed_run, tmp_path):
    run = read_run(speed_run)
    assert _invoke(speed_run, tmp_path / "c", "--fit", "piezo:kcd11:none:ols").exit_code == 0
    assert _invoke(speed_run, tmp_path / "p", "--fit", "piezo:kcd11:power:1:ols").exit_code == 0
    constant, power = _doc(tmp_path / "c")["bearings"][0], _doc(tmp_path / "p")["bearings"][0]
    for i, point in enumerate(run.complete_points):
        rec, w = _record(point, "piezo", "kcd11", "none"), point.settings.spin
        assert [constant["U"][k][i] for k in KEYS] == [rec.U[rec.names.index(OURS[k[0]] + k[1:])] for k in KEYS]
        rec = _record(point, "piezo", "kcd11", "power:1")
        assert rec.result["expanded_uncertainty"]["basis"] == "combined"
        for key, name in (("kxx", "Kxx"), ("cyx", "Cyx"), ("myx", "Dxy"), ("myy", "Dyy")):  # Dyx is Dxy in kcd11
            free = [rec.covariance_names.index(n) for n in (name, f"{name}_1") if n in rec.covariance_names]
            g = np.array([w**r for r in range(len(free))])
            var = g @ rec.covariance[np.ix_(free, free)] @ g
            sys = rec.budget["systematic"][rec.names.index(name)]
            if len(free) == 2:
                sys += w * rec.budget["systematic"][rec.names.index(f"{name}_1")]
            k = float(rec.budget["k"])
            assert power["U"][key][i] == pytest.approx(k * math.sqrt(var + sys**2), rel=1e-9)
            assert power["U"][key][i] >= k * math.sqrt(var)  # the calibration part only adds
    assert power["speeds"][0]["basis"] == "combined, calibration part bounded"


def test_coefficients_not_determined_are_listed_and_warned(synthetic_run, tmp_path):
    """The synthetic run's point 1, kcd11: the apparent mass is not determined (U > |D|)."""
    from orbitrig.analysis.ross_elements import bearing_elements

    record = _record(read_run(synthetic_run).points[1], "piezo", "kcd11", "none")
    expect = [
        (k, v, u)
        for k in KEYS
        for v, u in [(_at(record, k, 0.0), record.U[record.names.index(OURS[k[0]] + k[1:])])]
        if u > abs(v)
    ]
    assert [k for k, _, _ in expect] == ["mxx", "mxy", "myx"]
    res = _invoke(synthetic_run, tmp_path)
    assert res.exit_code == 0, res.output
    bearing = _doc(tmp_path)["bearings"][1]  # point 1's
    assert [(n["coefficient"], n["value"], n["U"]) for n in bearing["not_determined"]] == expect
    assert bearing["points"] == [1]
    assert all(n["point"] == 1 and n["fit"] == "piezo:kcd11:none:ols" for n in bearing["not_determined"])
    assert (
        "warning: point 0001 at 104.72 rad/s, fit piezo:kcd11:none:ols: mxx = 17.8 kg with U = 21.07 kg" in res.stderr
    )
    with pytest.warns(UserWarning, match=r"not determined .*point 0001 .*mxx = 17.8 kg with U = 21.07 kg"):
        bearing_elements(tmp_path / "ross_bearings.json", [0], point=1)
    with pytest.raises(ValueError, match=r"point 0001 \(104.72 rad/s\), fit piezo:kcd11:none:ols: mxx"):
        bearing_elements(tmp_path / "ross_bearings.json", [0], point=1, strict=True)


def _rotor(ross, bearings):
    steel = ross.materials.steel
    shaft = [ross.ShaftElement(L=0.2, idl=0.0, odl=0.06, material=steel) for _ in range(6)]
    disk = ross.DiskElement.from_geometry(n=3, material=steel, width=0.07, i_d=0.06, o_d=0.3)
    return ross.Rotor(shaft, [disk], bearings)


def _constant_bearings(ross, bearing, i):
    return [ross.BearingElement(n=n, **{k: bearing[k][i] for k in KEYS}) for n in (0, 6)]


def test_ross_evaluates_the_bearing_at_the_rotor_speed_and_holds_the_end_values(speed_run, tmp_path):
    from orbitrig.analysis.ross_elements import bearing_elements, import_ross

    ross = import_ross()

    assert _invoke(speed_run, tmp_path, "--fit", "piezo:kcd11:power:1:ols").exit_code == 0
    bearing = _doc(tmp_path)["bearings"][0]
    assert bearing["frequency"] == [p.settings.spin for p in read_run(speed_run).complete_points]
    s = np.asarray(bearing["frequency"])
    with pytest.warns(UserWarning, match="not determined"):  # the power:1 cross terms
        elements = bearing_elements(tmp_path / "ross_bearings.json", [0, 6])
    b = elements[0]
    for speed, i in [(s[0], 0), (s[1], 1), (s[2], 2), (0.0, 0), (0.5 * s[0], 0), (2 * s[2], 2), (1e4, 2), (1e6, 2)]:
        K, C, M = b.K(speed), b.C(speed), b.M(speed)
        for key, got in (("kxx", K[0, 0]), ("kxy", K[0, 1]), ("cyx", C[1, 0]), ("cyy", C[1, 1]), ("myy", M[1, 1])):
            assert got == pytest.approx(bearing[key][i], rel=1e-12), (speed, key)
    mid = (s[0] + s[1]) / 2  # linear between the speeds
    assert b.K(mid)[0, 0] == pytest.approx((bearing["kxx"][0] + bearing["kxx"][1]) / 2, rel=1e-12)
    rotor = _rotor(ross, elements)
    for speed, i in [(s[1], 1), (3 * s[2], 2), (0.2 * s[0], 0)]:  # at a speed, and outside on both sides
        ours = np.sort_complex(np.asarray(rotor.run_modal(speed=speed).evalues))
        want = np.sort_complex(
            np.asarray(_rotor(ross, _constant_bearings(ross, bearing, i)).run_modal(speed=speed).evalues)
        )
        np.testing.assert_allclose(ours, want, rtol=1e-9)


def test_one_speed_gives_ross_constant_coefficients(synthetic_run, tmp_path):
    """Every point of the synthetic run is at 1000 rpm (two test conditions): one speed per bearing."""
    from orbitrig.analysis.ross_elements import bearing_elements

    assert _invoke(synthetic_run, tmp_path).exit_code == 0
    bearing = _doc(tmp_path)["bearings"][0]  # point 0's
    assert bearing["frequency"] == [read_run(synthetic_run).points[0].settings.spin]
    assert bearing["outside"] == "one speed (104.72 rad/s): constant coefficients at every rotor speed"
    with pytest.warns(UserWarning, match="not determined"):  # its cross apparent mass
        b = bearing_elements(tmp_path / "ross_bearings.json", [0], point=0)[0]
    assert b.frequency is None
    for speed in (0.0, 10.0, bearing["frequency"][0], 1e4):
        assert b.K(speed)[0, 0] == bearing["kxx"][0] and b.M(speed)[1, 1] == bearing["myy"][0]
    with pytest.raises(KeyError, match="choose one with point="):
        bearing_elements(tmp_path / "ross_bearings.json", [0])


def test_ross_alone_would_extrapolate_these_arrays(tmp_path):
    """Why bearing_elements replaces ROSS's interpolation: its spline leaves the end values."""
    from orbitrig.analysis.ross_elements import bearing_elements, import_ross

    ross = import_ross()

    speeds, kxx = [50.0, 100.0, 150.0, 200.0], [3.0e7, 3.3e7, 3.1e7, 3.4e7]
    data = {k: [0.0] * 4 for k in KEYS} | {"kxx": kxx, "kyy": kxx, "cxx": [1e5] * 4, "cyy": [1e5] * 4}
    doc = {
        "bearings": [
            {"lms": "piezo", "point": 0, "points": [0, 1, 2, 3], "frequency": speeds, "not_determined": [], **data}
        ]
    }
    (tmp_path / "b.json").write_text(json.dumps(doc))
    raw = ross.BearingElement(n=0, frequency=speeds, **data)
    held = bearing_elements(tmp_path / "b.json", [0])[0]
    for speed, end in ((0.0, 3.0e7), (400.0, 3.4e7), (1000.0, 3.4e7)):
        assert held.K(speed)[0, 0] == end
        assert abs(raw.K(speed)[0, 0] - end) > 0.1 * end


@pytest.mark.parametrize("model, freq_dep", [("kcd11", "poly:3"), ("kcd12", "power:1,2,1"), ("kc7", "power:1")])
def test_values_and_U_at_a_whirl_agree_with_the_identification(speed_run, model, freq_dep):
    """The stored coefficients summed over their orders are Identification.matrices (absorbed K
    orders in D, symmetric pairs, no D); without a calibration budget U is k sqrt(g' S g)."""
    from orbitrig.analysis.ross_speed import coefficients_at, uncertainties_at
    from orbitrig.store.fit_record import coverage_of
    from reduction.derived import entry_gradient

    ident = identify_point(read_run(speed_run).points[1], "piezo", model, freq_dep, "ols").identification
    result, w = ident.to_dict(fit=False), 80.0
    values, U = coefficients_at(result, w), uncertainties_at(result, w)
    for letter, matrix, ours in zip("kcm", ident.matrices(w), "KCD"):
        for e, (i, j) in zip(("xx", "xy", "yx", "yy"), ((0, 0), (0, 1), (1, 0), (1, 1))):
            assert values[letter + e] == pytest.approx(matrix[i, j], rel=1e-12, abs=1e-9)
            g = entry_gradient(ident, ours, e, [w])[0]
            want = coverage_of(result) * math.sqrt(g @ ident.covariance @ g)
            assert (U[letter + e] or 0.0) == pytest.approx(want, rel=1e-9)
            assert (U[letter + e] is None) == (letter == "m" and model == "kc7")  # kc7 has no D


def test_the_export_says_one_point_and_each_speed_with_its_unit():
    """The line `export --format ross` prints first of a bearing of one point: `point 0000`, the
    speed as a number with its unit (it read `points 0000: rad/s 104.72 constant`)."""
    from orbitrig.analysis.ross_warnings import notes

    speed = {"spin": 104.71975511965977, "used": "constant", "fit": "piezo:kcd11:none:ols"}
    bearing = {"lms": "piezo", "points": [0], "speeds": [speed], "outside": "one speed", "not_determined": []}
    assert notes(bearing) == [
        "ross: piezo bearing of point 0000: 104.72 rad/s constant (piezo:kcd11:none:ols); one speed"
    ]

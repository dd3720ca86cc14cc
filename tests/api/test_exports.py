"""Every export carries the same content, read back by independent readers (scipy.io,
npTDMS, csv, pint, GNU Octave) against run.h5 read with h5py: coefficients with std and
U, the covariance with its names (11 x 11 for kcd11's 11 free coefficients), the budget,
derived quantities, truth, provenance and (mat, tdms, h5) the averaged waveforms; GNU Octave
loads the .mat and the exported .h5."""

from __future__ import annotations

import csv
import json
import shutil

import h5py
import numpy as np
import pytest
from nptdms import TdmsFile
from scipy.io import loadmat

from orbitrig.store.errors import RunDirError
from orbitrig.store.export import export_run
from orbitrig.store.export_h5 import octave_layout
from orbitrig.store.orbit_table import read_orbit_table
from orbitrig.store.reader import read_run
from support.octave import octave_eval
from support.units import UREG

FIT = "piezo__kcd11__none__ols"
UNIT = {"K": "N/m", "C": "N s/m", "D": "kg"}


@pytest.fixture(scope="module")
def stored(sim_run):
    """What run.h5 says, read with h5py."""
    with h5py.File(sim_run / "run.h5", "r") as f:
        g = f[f"points/0000/identification/{FIT}"]
        return {
            "names": list(g["names"].asstr()[()]),
            "units": list(g["units"].asstr()[()]),
            "value": g["coefficients"][()],
            "std": g["std_errors"][()],
            "U": g["uncertainty/expanded"][()],
            "combined": g["uncertainty/combined"][()],
            "cov": g["covariance"][()],
            "cov_names": list(g["covariance"].attrs["names"]),
            "c_eff_xx": g["derived/c_eff_xx"][()],
            "K0": f["points/0000/truth/fits/constant/K"][()],
            "mean": f["points/0000/frequencies/03_bwd/mean"][()],
            "fx": f["points/0000/table/piezo/fx"][()],
            "version": f.attrs["software_version"],
            "truth_orbit": f["points/0000/truth/orbit"][()],
            "phasors": f["points/0000/frequencies/03_bwd/phasors"][()],
            "Z": f["points/0000/truth/Z"][()],
            "events": f["logs/events"][()],
        }


@pytest.fixture(scope="module")
def exported(sim_run, tmp_path_factory):
    out = tmp_path_factory.mktemp("export")
    return {fmt: export_run(sim_run, fmt, out) for fmt in ("csv", "mat", "tdms", "h5")} | {"dir": out}


def _units_parse(units) -> None:
    for u in units:
        UREG.parse_units(u)  # every unit string, "1" and "" (text) included


def _tdms_units(tdms) -> None:
    """Every numeric channel's unit_string and every numeric property's <name>.unit_string
    is a unit pint parses; a text channel's is ""."""
    for where, props in [("root", tdms.properties)] + [(g.name, g.properties) for g in tdms.groups()]:
        _tdms_property_units(where, props)
    for g in tdms.groups():
        for c in g.channels():
            unit = c.properties["unit_string"]
            assert unit != "" or c.data.dtype.kind not in "fiuc", f"{g.name}/{c.name}: a number without a unit"
            assert unit == "" or c.data.dtype.kind in "fiuc", f"{g.name}/{c.name}: text with a unit"
            UREG.parse_units(unit)
            _tdms_property_units(f"{g.name}/{c.name}", c.properties)


def _tdms_property_units(where: str, props) -> None:
    for k, v in props.items():
        if k == "unit_string" or k.endswith(".unit_string") or isinstance(v, (str, bool, np.bool_)):
            continue
        assert f"{k}.unit_string" in props, f"{where}: property {k} has no {k}.unit_string"
        UREG.parse_units(props[f"{k}.unit_string"])


def test_mat(exported, stored):
    m = loadmat(exported["dir"] / "run.mat", simplify_cells=True)
    fit = m["points"]["p0000"]["identification"][FIT]
    assert list(fit["names"]) == stored["names"]
    np.testing.assert_array_equal(fit["coefficients"], stored["value"])
    np.testing.assert_array_equal(fit["U"], stored["U"])
    np.testing.assert_array_equal(fit["combined"], stored["combined"])
    assert fit["covariance"].shape == (11, 11) and list(fit["covariance_names"]) == stored["cov_names"]
    np.testing.assert_array_equal(fit["covariance"], stored["cov"])
    np.testing.assert_array_equal(fit["derived"]["c_eff_xx"], stored["c_eff_xx"])
    assert fit["derived_units"]["c_eff_xx"] == "N s/m"
    point = m["points"]["p0000"]
    np.testing.assert_array_equal(point["truth"]["K0"], stored["K0"])
    np.testing.assert_array_equal(point["waveforms"]["b03_bwd"]["mean"], stored["mean"])
    np.testing.assert_array_equal(point["piezo"]["fx"], stored["fx"])
    np.testing.assert_array_equal(point["piezo"]["direction"], np.sign(stored["truth_orbit"]))
    assert m["run"]["software_version"] == stored["version"]
    _units_parse(point["settings_units"].values())
    _units_parse(point["piezo"]["units"].values())
    _units_parse(m["units"].values())
    for lms in ("piezo", "strain"):  # the legend names every field of the load system's struct, as it does
        fields = set(point[lms]) - {"units"}
        assert fields == set(point[lms]["units"]) and point[lms]["units"].items() <= m["units"].items()
    assert {"gamma2_xfx", "gamma2_yfy", "u_fx"} <= set(m["units"]) and "gamma2" not in m["units"]


def test_tdms(exported, stored):
    tdms = TdmsFile.read(exported["dir"] / "run.tdms")
    table = tdms["point 0000 piezo"]
    assert isinstance(table.properties["spin_rpm"], float) and table.properties["spin_rpm.unit_string"] == "rpm"
    assert table["orbit_hz"].properties["unit_string"] == "Hz"
    np.testing.assert_array_equal(table["direction"][:], np.sign(stored["truth_orbit"]))
    fit = tdms[f"fit 0000 {FIT}"]
    rows = list(fit["quantity"][:])
    assert [c.name for c in fit.channels()][1:] == stored["names"] and rows[:3] == ["value", "std", "U"]
    for k, name in enumerate(stored["names"]):  # one channel per coefficient, in its own unit
        channel = fit[name]
        assert channel.properties["unit_string"] == UNIT[name[0]]
        assert channel[rows.index("U")] == stored["U"][k] and channel[rows.index("value")] == stored["value"][k]
        assert channel[rows.index("combined")] == stored["combined"][k]
        assert channel.properties["e_n.unit_string"] == "1"
    kxx = UREG.Quantity(fit["Kxx"][0], fit["Kxx"].properties["unit_string"]).to("MN/m")
    assert kxx.magnitude == pytest.approx(stored["value"][0] * 1e-6)
    cov = tdms[f"covariance 0000 {FIT}"]
    assert list(cov["name"][:]) == stored["cov_names"] and len(cov.channels()) == 12  # name + 11 columns
    corr = np.stack([cov[n][:] for n in stored["cov_names"]], axis=1)
    std = np.array([cov[n].properties["std"] for n in stored["cov_names"]])
    np.testing.assert_allclose(corr * np.outer(std, std), stored["cov"], rtol=1e-12)  # r_ij std_i std_j
    assert np.allclose(np.diag(corr), 1.0) and cov["Cxx"].properties["std.unit_string"] == "N s/m"
    assert {cov[n].properties["unit_string"] for n in stored["cov_names"]} == {"1"}
    np.testing.assert_array_equal(tdms[f"derived 0000 {FIT}"]["c_eff_xx"][:], stored["c_eff_xx"])
    np.testing.assert_array_equal(tdms["truth 0000"]["K0"][:], stored["K0"].ravel())
    wave = tdms["waveforms 0000 03_bwd"]
    np.testing.assert_array_equal(wave["fx_piezo"][:], stored["mean"][0])
    assert wave["x_a"].properties["unit_string"] == "m" and isinstance(wave.properties["orbit_hz"], float)
    assert tdms.properties["software_version"] == stored["version"]
    coef = tdms["coefficients"]
    k = stored["names"].index("Kxy")
    # the columns of coefficients.csv, every number to the last bit (not as the CSV prints it)
    assert stored["U"][k] in coef["Kxy_U"][:] and coef["Kxy_U"].properties["unit_string"] == "N/m"
    units = {c.name: c.properties["unit_string"] for c in coef.channels()}
    assert (units["spin_rpm"], units["recess_pressure_mpa"], units["residual_rms"]) == ("rpm", "MPa", "N")
    assert {units[c] for c in ("pressure_ratio", "static_eccentricity", "n_frequencies", "condition_number")} == {"1"}
    p = wave["fx_piezo"].properties
    assert [p[f"{k}.unit_string"] for k in ("dc", "uncertainty", "phasor_re", "phasor_im")] == ["N"] * 4
    assert p["phasor_re"] + 1j * p["phasor_im"] == stored["phasors"][0]
    _tdms_units(tdms)


def test_csv(exported, stored, sim_run):
    out = exported["dir"]
    with open(out / "point_0000_piezo.csv", newline="") as fh:
        header = next(csv.reader(fh))
    assert header[:2] == ["spin_rpm [rpm]", "orbit_hz [Hz]"] and header[-1] == "direction [1]"
    _units_parse(h.split("[")[1].rstrip("]") for h in header)
    table = read_orbit_table(out / "point_0000_piezo.csv")  # identify reads it back
    np.testing.assert_array_equal(table.fx, stored["fx"])
    with open(out / "point_0000_piezo.csv", newline="") as fh:
        assert [int(r["direction [1]"]) for r in csv.DictReader(fh)] == list(np.sign(stored["truth_orbit"]))
    with open(out / "fits.csv", newline="") as fh:
        rows = [r for r in csv.DictReader(fh) if r["lms"] == "piezo" and r["model"] == "kcd11"]
    assert [r["name"] for r in rows] == stored["names"]
    np.testing.assert_array_equal([float(r["U"]) for r in rows], stored["U"])
    # the fit's own truth: on the clean scenario (Z exactly constant K, C, D) the constant K
    np.testing.assert_allclose([float(r["true"]) for r in rows if r["name"] == "Kxy"], [stored["K0"][0, 1]], rtol=1e-9)
    _units_parse(r["unit"] for r in rows)
    with open(out / f"covariance_0000_{FIT}.csv", newline="") as fh:
        cov = list(csv.reader(fh))
    assert cov[0] == ["name", "unit"] + stored["cov_names"] and [r[0] for r in cov[1:]] == stored["cov_names"]
    unit = dict(zip(stored["names"], stored["units"]))
    assert [r[1] for r in cov[1:]] == [unit[n] for n in stored["cov_names"]]  # entry (a, b): unit(a) x unit(b)
    _units_parse(r[1] for r in cov[1:])
    np.testing.assert_array_equal([[float(v) for v in r[2:]] for r in cov[1:]], stored["cov"])
    with open(out / f"derived_0000_{FIT}.csv", newline="") as fh:
        derived = list(csv.DictReader(fh))
    np.testing.assert_array_equal([float(r["c_eff_xx [N s/m]"]) for r in derived], stored["c_eff_xx"])
    with open(out / "provenance.csv", newline="") as fh:
        provenance = dict(csv.reader(fh))
    assert provenance["software_version"] == stored["version"]
    with h5py.File(sim_run / "run.h5", "r") as f:  # who, where, which calibration: as run.h5 says
        for key in ("operator", "rig_id", "host", "calibration_record", "calibration_record_sha256", "started"):
            assert provenance[key] == f.attrs[key], key
        assert provenance["calibration_record_seal"] == f.attrs["calibration_record_seal"] == "as written"
    assert len(provenance["calibration_record_sha256"]) == 64 and provenance["ended"]
    # each channel's sensor by its serial number (config/rig.toml), as a JSON object
    serials = json.loads(provenance["sensor_serials"])
    assert serials["fx_piezo"] == "PZ-2231-X" and serials["y_b"] == "EC-5583-YB" and len(serials) == 8


def test_h5_export_is_run_h5_in_the_layout_octave_reads(exported, stored, tmp_path):
    path = exported["dir"] / "run.h5"
    with h5py.File(path, "r") as f:
        g = f[f"points/0000/identification/{FIT}"]
        np.testing.assert_array_equal(g["uncertainty/expanded"][()], stored["U"])
        assert g["coefficients"].attrs["units_Kxx"] == "N/m" and "description" in g["coefficients"].attrs
        assert json.loads(g.attrs["json"])["free"] == stored["cov_names"]
        fx = f["points/0000/table/piezo/fx"][()]
        assert fx.dtype.names == ("real", "imag")
        np.testing.assert_array_equal(fx["real"] + 1j * fx["imag"], stored["fx"])
        events = f["logs/events"]
        assert isinstance(events, h5py.Group) and list(events["state"][()]) == list(stored["events"]["state"])
        counts = {"attributes": 0, "mirrored": 0}
        f.visititems(lambda name, obj: _octave_readable(name, obj, counts))
        assert counts["mirrored"] == counts["attributes"] + len(f.attrs) > 2000
        for name in (
            "",
            "points/0000",
            "points/0000/table/piezo",
            "points/0000/table/piezo/fx",
            "logs/events",
            f"points/0000/identification/{FIT}",
            f"points/0000/identification/{FIT}/coefficients",
        ):
            _same_attributes(f, name)
    shutil.copy(path, tmp_path / "run.h5")  # orbitrig reads the export as it reads run.h5
    table = read_run(tmp_path).points[0].tables["piezo"]
    np.testing.assert_array_equal(table.fx, stored["fx"])


def _octave_readable(name: str, obj, counts: dict) -> None:
    """`obj` is what Octave's load reads (numbers, fixed-length text, real/imag compounds);
    counts the attributes of the tree and the datasets mirroring them under /attributes."""
    if isinstance(obj, h5py.Dataset):
        dt = obj.dtype
        assert dt.kind in "iufS" or dt.names == ("real", "imag"), f"{name}: {dt}"
        counts["mirrored"] += name.startswith("attributes/")
    counts["attributes"] += len(obj.attrs) if not name.startswith("attributes/") else 0


def _same_attributes(f: h5py.File, name: str) -> None:
    obj = f[name or "/"]
    for key, value in obj.attrs.items():
        copy = f["/".join(filter(None, ("attributes", name, key)))][()]
        if isinstance(value, str):
            assert copy.decode() == value, f"{name}: {key}"
        elif isinstance(value, np.ndarray) and value.dtype.kind == "O":
            assert [c.decode() for c in copy] == list(value), f"{name}: {key}"
        else:
            np.testing.assert_array_equal(copy, value, err_msg=f"{name}: {key}")


def test_h5_export_of_a_folder_holding_only_run_h5(sim_run, exported, tmp_path):
    """A copy of run.h5 alone in a folder (sent to a colleague) exports to the same layout."""
    alone = tmp_path / "alone"
    alone.mkdir()
    shutil.copy(sim_run / "run.h5", alone / "run.h5")
    (path,) = export_run(alone, "h5", tmp_path / "out").files
    with h5py.File(path, "r") as f, h5py.File(exported["dir"] / "run.h5", "r") as first:
        np.testing.assert_array_equal(f["points/0000/table/piezo/fx"][()], first["points/0000/table/piezo/fx"][()])
        assert sorted(f["logs/can"]) == sorted(first["logs/can"]) and sorted(f["attributes"]) == sorted(
            first["attributes"]
        )
        assert f["attributes/points/0000/table/piezo/fx/units"][()] == b"N"
    with pytest.raises(RunDirError, match="would replace the run's own run.h5"):
        export_run(alone, "h5", alone)


def test_octave_layout_names_an_attribute_that_a_member_shadows(tmp_path):
    with h5py.File(tmp_path / "t.h5", "w") as f:
        g = f.create_group("g")
        g.attrs["d"], g.attrs["ok"] = "the group's d", np.bool_(True)
        g.create_dataset("d", data=np.array(["a", "bb"], dtype=h5py.string_dtype())).attrs["units"] = "m"
        for _ in range(2):  # a file exported before is laid out again the same
            octave_layout(f)
            assert f["attributes/g/d/units"][()] == b"m" and f["attributes/g/d_attribute"][()] == b"the group's d"
            assert f["attributes/g/ok"].dtype == np.uint8 and f["attributes/g/ok"][()] == 1
            assert list(f["g/d"][()]) == [b"a", b"bb"] and f["g/d"].attrs["units"] == "m"
            assert sorted(f["attributes/g"]) == ["d", "d_attribute", "ok"]


def test_octave_loads_the_h5_export(exported, stored, tmp_path):
    """One octave-cli start: Octave's load gives complex phasors, coefficients with U, a log
    column and the software version, equal to the last bit to what h5py reads in run.h5."""
    script = (
        f"x = load('{exported['dir'] / 'run.h5'}');\n"
        "p = x.points._0000; k = p.identification." + FIT + ";\n"
        "fx = p.table.piezo.fx; printf('fx %.17g %.17g\\n', [real(fx(:)) imag(fx(:))]');\n"
        "ph = p.frequencies._03_bwd.phasors; printf('ph %.17g %.17g\\n', [real(ph(:)) imag(ph(:))]');\n"
        "printf('Zsize %d %d %d\\n', size(p.truth.Z)); Z = p.truth.Z(:);\n"
        "printf('Z %.17g %.17g\\n', [real(Z) imag(Z)]');\n"
        "printf('coef %s %.17g %.17g\\n', [cellstr(k.names)'; num2cell(k.coefficients(:))';"
        " num2cell(k.uncertainty.expanded(:))']{:});\n"
        "printf('t %.17g\\n', x.logs.events.t); printf('state %s\\n', cellstr(x.logs.events.state){:});\n"
        "printf('version %s\\n', x.attributes.software_version);\n"
        "printf('unit %s\\n', x.attributes.points._0000.table.piezo.fx.units);\n"
    )
    done = octave_eval(script, tmp_path)
    assert done.returncode == 0 and "warning" not in done.stderr, done.stdout[-2000:] + done.stderr[-2000:]
    rows = {}
    for line in done.stdout.splitlines():
        key, _, rest = line.partition(" ")
        rows.setdefault(key, []).append(rest)

    def complex_rows(key):
        return np.array([complex(*map(float, r.split())) for r in rows[key]])

    np.testing.assert_array_equal(complex_rows("fx"), stored["fx"])
    np.testing.assert_array_equal(complex_rows("ph"), stored["phasors"])
    assert rows["Zsize"] == [" ".join(map(str, stored["Z"].shape[::-1]))]  # Octave lists HDF5's dimensions reversed
    np.testing.assert_array_equal(complex_rows("Z"), stored["Z"].ravel())
    coef = [r.split() for r in rows["coef"]]
    assert [c[0] for c in coef] == stored["names"]
    np.testing.assert_array_equal([float(c[1]) for c in coef], stored["value"])
    np.testing.assert_array_equal([float(c[2]) for c in coef], stored["U"])
    np.testing.assert_array_equal([float(t) for t in rows["t"]], stored["events"]["t"])
    assert rows["state"] == [s.decode() for s in stored["events"]["state"]]
    assert rows["version"] == [stored["version"]] and rows["unit"] == ["N"]


def test_octave_loads_the_mat_export(exported, stored, tmp_path):
    script = (
        f"m = load('{exported['dir'] / 'run.mat'}');\n"
        f"k = m.points.p0000.identification.{FIT};\n"
        "printf('U %.17g\\n', k.U);\n"
        "printf('cov %d %d %d\\n', size(k.covariance), numel(k.covariance_names));\n"
        "fx = m.points.p0000.piezo.fx;\n"
        "printf('fx %.17g %.17g\\n', [real(fx) imag(fx)]');\n"
        "printf('version %s\\n', m.run.software_version);\n"
    )
    done = octave_eval(script, tmp_path)
    lines = done.stdout.splitlines()
    assert "cov 11 11 11" in lines, done.stdout + done.stderr[-2000:]
    np.testing.assert_array_equal([float(ln.split()[1]) for ln in lines if ln.startswith("U ")], stored["U"])
    fx = np.array([[float(v) for v in ln.split()[1:]] for ln in lines if ln.startswith("fx ")])
    np.testing.assert_array_equal(fx[:, 0] + 1j * fx[:, 1], stored["fx"])
    assert f"version {stored['version']}" in lines


def test_ross_frequency_is_the_rotor_speed(sim_run, tmp_path):
    """ROSS evaluates a bearing at the rotor speed: the file's axis is the point's spin, here one
    speed (constant coefficients at every rotor speed), the constant fit's K, C, D as stored."""
    from typer.testing import CliRunner

    from orbitrig.cli import app

    res = CliRunner().invoke(app, ["export", str(sim_run), "--format", "ross", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    (bearing,) = json.loads((tmp_path / "ross_bearings.json").read_text())["bearings"]
    with h5py.File(sim_run / "run.h5", "r") as f:
        value = dict(
            zip(
                f[f"points/0000/identification/{FIT}/names"].asstr()[()],
                f[f"points/0000/identification/{FIT}/coefficients"][()],
            )
        )
    assert bearing["frequency"] == [read_run(sim_run).points[0].settings.spin]
    np.testing.assert_allclose(bearing["kxy"], [value["Kxy"]], rtol=1e-12)
    np.testing.assert_allclose(bearing["myx"], [value["Dyx"]], rtol=1e-12)
    assert bearing["speeds"][0]["used"] == "constant" and bearing["outside"].startswith("one speed")

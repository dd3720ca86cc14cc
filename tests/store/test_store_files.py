"""What users open without orbitrig: run.h5 (h5py), the exports (scipy .mat, npTDMS,
CSV) and coefficients.csv: units and names stated, numbers equal to the stored ones."""

from __future__ import annotations

import ast
import csv
import re

import h5py
import numpy as np
import pytest
import scipy.io
from nptdms import TdmsFile
from typer.testing import CliRunner

from orbitrig.cli import app
from orbitrig.store.reader import read_run
from orbitrig.store.orbit_table import read_orbit_table
from orbitrig.store.status import RunStatus

from support.paths import ROOT


def _s(values) -> list[str]:
    """Strings of an HDF5 string dataset or attribute (bytes or str, as h5py returns them)."""
    return [v.decode() if isinstance(v, bytes) else str(v) for v in values]


UNIT_COLUMN = re.compile(r"(true_)?[KCD][xy]{2}(_\d+)?(?:(_std|_U)? \[(N/m|N s/m|kg)( \(rad/s\)\^-\d+)?\]|(_k) \[1\])")


def test_run_h5_states_units_and_names(synthetic):
    with h5py.File(synthetic / "run.h5", "r") as f:
        assert f.attrs["format"] == "orbitrig-run/2" and f.attrs["status"] == "stopped"
        assert _s(f["channels"][()]) == ["fx_piezo", "fy_piezo", "fx_strain", "fy_strain", "x_a", "y_a", "x_b", "y_b"]
        assert _s(f["channel_units"][()]) == ["N"] * 4 + ["m"] * 4
        missing = []

        def visit(name, obj):
            units = [k for k in obj.attrs if k == "units" or k.startswith("units_")]  # one, or one per entry
            if isinstance(obj, h5py.Dataset) and not units and obj.dtype.kind != "S":  # text has no unit
                missing.append(name)

        f.visititems(visit)
        assert missing == []
        g = f["points/0000"]
        assert "spin: rad/s" in g.attrs["units_of_attributes"]
        fr = g["frequencies/00_fwd"]
        assert fr["raw_counts"].attrs["units"] == "count"
        assert _s(fr.attrs["channels"])[:2] == ["fx_piezo", "fy_piezo"]
        coh = fr["coherence"]
        assert _s(coh.attrs["rows"]) == ["piezo", "strain"]
        assert _s(coh.attrs["columns"]) == ["xfx", "yfx", "xfy", "yfy"] and coh.attrs["units"] == "1"
        t = g["table/piezo"]
        assert (t["x"].attrs["units"], t["fx"].attrs["units"], t["orbit"].attrs["units"]) == ("m", "N", "rad/s")
        np.testing.assert_allclose(t["orbit_hz"][()], t["orbit"][()] / (2 * np.pi))
        ident = g["identification/piezo__kcd11__none__ols"]
        names = _s(ident["names"][()])
        units = dict(zip(names, _s(ident["units"][()])))
        assert names[:4] == ["Kxx", "Kxy", "Kyx", "Kyy"]
        assert (units["Kxx"], units["Cyx"], units["Dxy"]) == ("N/m", "N s/m", "kg")
        stored = read_run(synthetic).points[0].identification("piezo", "kcd11", "none").result
        np.testing.assert_array_equal(ident["coefficients"][()], [stored["coefficients"][k] for k in names])
        np.testing.assert_array_equal(ident["std_errors"][()], [stored["std_errors"][k] for k in names])
        assert ident.attrs["residual_rms"] == pytest.approx(stored["residual_rms"])
        power = g["identification/piezo__kcd11__power_1__ols"]
        assert dict(zip(_s(power["names"][()]), _s(power["units"][()])))["Cxy_1"] == "N s/m (rad/s)^-1"
        refused = g["identification/piezo__kcd12__poly_8__ols"]
        assert "rank-deficient" in refused.attrs["error"] and "coefficients" not in refused


def test_coefficients_csv_has_units_and_one_line_per_row(synthetic):
    text = (synthetic / "coefficients.csv").read_text(encoding="utf-8")
    lines = text.splitlines()
    rows = list(csv.DictReader(lines))
    assert len(lines) == len(rows) + 1  # refusal messages stay on their row's line
    assert any("rank-deficient" in r["error"] and " | " in r["error"] for r in rows)
    header = lines[0].split(",")
    coef = [c for c in header if c[:1] in "KCD" or c.startswith("true_")]
    assert coef and all(UNIT_COLUMN.fullmatch(c) for c in coef), coef
    assert {"spin_rpm", "recess_pressure_mpa", "residual_rms [N]"} <= set(header)
    ok = [r for r in rows if not r["error"]]
    assert float(ok[0]["Kxx [N/m]"]) > 1e7 and float(ok[0]["true_Kxx [N/m]"]) == pytest.approx(3.3e7)


def test_points_kept_as_csv_text_render_the_same_file(synthetic):
    """A run keeps each complete point's rows as CSV text in its own columns (bounded memory);
    the file made from them is the file made from the rows, also when points differ in their
    columns (a point without truth, a point without some models)."""
    from orbitrig.store import csvfile

    rows = [csvfile.point_rows(p, True) for p in read_run(synthetic, blocks=False).complete_points]
    assert len(rows) == 2 and len(rows[0]) == 8
    mixed = [rows[0][2:5], [{k: v for k, v in r.items() if not k.startswith("true_")} for r in rows[1]], rows[0]]
    for points in (rows, mixed):
        kept = [csvfile.PointCsv.of(p) for p in points]
        assert csvfile.render_points(kept) == csvfile.render([r for p in points for r in p])
    assert (
        csvfile.render_points([csvfile.PointCsv.of(p) for p in rows]) == (synthetic / "coefficients.csv").read_bytes()
    )


def test_storage_md_states_the_columns_of_coefficients_csv(synthetic):
    """docs/storage.md's column list is the file's head; it names every kind of coefficient
    column the file has and says the true_* columns are each fit's own truth."""
    text = (ROOT / "docs" / "storage.md").read_text(encoding="utf-8")
    section = " ".join(text.split("## coefficients.csv")[1].split("\n## ")[0].split())
    listed = re.search(r"Columns: `([^`]*)`", section).group(1).split(", ")
    with open(synthetic / "coefficients.csv", newline="", encoding="utf-8") as fh:
        header = next(csv.reader(fh))
    assert header[: len(listed)] == listed
    kinds = {"": "`KEY [unit]`", "_std": "`KEY_std [unit]`", "_U": "`KEY_U [unit]`", "_k": "`KEY_k [1]`"}
    kinds["true_"] = "`true_KEY [unit]`"
    for column in header[len(listed) :]:
        m = UNIT_COLUMN.fullmatch(column)
        assert m, column
        assert kinds[m.group(1) or m.group(3) or m.group(6) or ""] in section, column
    assert "each fit's own truth" in section and "`not_determined`" in section  # not truth/fits/constant


def _export(run, fmt, out):
    r = CliRunner().invoke(app, ["export", str(run), "--format", fmt, "--out", str(out)])
    assert r.exit_code == 0, r.output
    return [line for line in r.stdout.splitlines() if line]


def test_export_mat_reads_in_scipy(synthetic, tmp_path):
    (path,) = _export(synthetic, "mat", tmp_path)
    m = scipy.io.loadmat(path, simplify_cells=True)
    run = read_run(synthetic)
    assert sorted(m["points"]) == ["p0000", "p0001"]  # complete points only
    p = m["points"]["p0000"]
    table = run.points[0].tables["piezo"]
    np.testing.assert_array_equal(p["piezo"]["fx"], table.fx)
    np.testing.assert_allclose(p["piezo"]["orbit_hz"], table.orbit / (2 * np.pi))
    assert p["spin_rpm"] == pytest.approx(1000.0)
    ident = p["identification"]["strain__kcd11__none__ols"]
    stored = run.points[0].identification("strain", "kcd11", "none").result
    assert list(ident["names"]) == list(stored["coefficients"])
    np.testing.assert_array_equal(ident["coefficients"], list(stored["coefficients"].values()))
    assert list(ident["units"][:5]) == ["N/m"] * 4 + ["N s/m"]
    assert ident["interval_95"].shape == (12, 2)
    expanded = stored["expanded_uncertainty"]["values"]
    np.testing.assert_allclose(ident["U"], [expanded[k] for k in stored["coefficients"]])
    assert list(np.atleast_1d(ident["not_determined"])) == stored["not_determined"]
    assert "rank-deficient" in p["identification"]["strain__kcd12__poly_8__ols"]["error"]
    assert list(m["run"]["channels"][:2]) == ["fx_piezo", "fy_piezo"] and m["units"]["fx"].startswith("N")


def test_export_tdms_reads_in_nptdms(synthetic, tmp_path):
    (path,) = _export(synthetic, "tdms", tmp_path)
    f = TdmsFile.read(path)
    groups = [g.name for g in f.groups()]
    tables = [g for g in groups if g.startswith("point ")]
    assert tables == ["point 0000 piezo", "point 0000 strain", "point 0001 piezo", "point 0001 strain"]
    assert groups[-1] == "coefficients"
    g = f["point 0001 strain"]
    table = read_run(synthetic).points[1].tables["strain"]
    np.testing.assert_array_equal(g["fy_im"][:], table.fy.imag)
    assert g["fy_im"].properties["unit_string"] == "N" and g["x_re"].properties["unit_string"] == "m"
    assert g["orbit_hz"].properties["unit_string"] == "Hz" and g.properties["spin_rpm"] == pytest.approx(1000.0)
    c = f["coefficients"]
    assert c["Kxx"].properties["unit_string"] == "N/m" and c["Cxx_std"].properties["unit_string"] == "N s/m"
    rows = list(csv.DictReader(open(synthetic / "coefficients.csv", encoding="utf-8")))
    np.testing.assert_allclose(c["Kxx"][:], [float(r["Kxx [N/m]"]) if r["Kxx [N/m]"] else np.nan for r in rows])
    assert list(c["lms"][:2]) == ["piezo", "piezo"]


def _python_repr(text: str) -> bool:
    """Whether `text` is Python's repr of a list, a tuple or a numpy scalar rather than plain text."""
    if re.search(r"\bnp\.\w+\(|numpy\.\w+\(", text):
        return True
    try:
        return isinstance(ast.literal_eval(text.strip()), (list, tuple))
    except (ValueError, SyntaxError, MemoryError, RecursionError):
        return False


def test_export_tdms_properties_are_numbers_or_plain_text(synthetic, tmp_path):
    """Every property of a run with a frequency-dependent model (kcd11 power:1: the adequacy
    test) is a number with its unit or plain text; the test's two dof are numbers."""
    (path,) = _export(synthetic, "tdms", tmp_path)
    f = TdmsFile.read(path)
    owners = [("root", f.properties)] + [(g.name, g.properties) for g in f.groups()]
    owners += [(f"{g.name}/{c.name}", c.properties) for g in f.groups() for c in g.channels()]
    for where, props in owners:
        for name, value in props.items():
            assert isinstance(value, (str, int, float, np.number, np.bool_)), (where, name, value)
            assert not (isinstance(value, str) and _python_repr(value)), (where, name, value)
    fits = [g for g in f.groups() if g.name.startswith("fit 0000 ") and "adequacy_p_value" in g.properties]
    assert {g.name for g in fits} == {"fit 0000 piezo__kcd11__power_1__ols", "fit 0000 strain__kcd11__power_1__ols"}
    with h5py.File(synthetic / "run.h5", "r") as h5:
        stored = h5["points/0000/identification/piezo__kcd11__power_1__ols/adequacy"].attrs["dof"]
    props = f["fit 0000 piezo__kcd11__power_1__ols"].properties
    assert "adequacy_dof" not in props
    assert (props["adequacy_dof_numerator"], props["adequacy_dof_denominator"]) == tuple(stored)
    assert props["adequacy_dof_numerator.unit_string"] == props["adequacy_dof_denominator.unit_string"] == "1"


def test_export_csv_orbit_tables_read_back(synthetic, tmp_path):
    files = _export(synthetic, "csv", tmp_path)
    assert [p.rsplit("/", 1)[-1] for p in files][:6] == [
        "point_0000_piezo.csv",
        "point_0000_strain.csv",
        "point_0001_piezo.csv",
        "point_0001_strain.csv",
        "coefficients.csv",
        "fits.csv",
    ]
    table = read_run(synthetic).points[0].tables["strain"]
    back = read_orbit_table(tmp_path / "point_0000_strain.csv")
    np.testing.assert_allclose(back.orbit, table.orbit, rtol=1e-15)  # stored as orbit_hz
    for name in ("x", "y", "fx", "fy", "gamma2"):
        np.testing.assert_array_equal(getattr(back, name), getattr(table, name))
    assert (tmp_path / "coefficients.csv").read_bytes() == (synthetic / "coefficients.csv").read_bytes()


def test_export_h5_of_a_cut_run_and_bad_arguments(tmp_path):
    from support.report_synthetic import write_synthetic_run

    run = write_synthetic_run(tmp_path / "cut", n_points=1, incomplete=1, finished=False)
    assert not (run / "run.h5").exists()
    (path,) = _export(run, "h5", tmp_path / "out")
    with h5py.File(path, "r") as f:
        assert f.attrs["status"] == "running" and [bool(g.attrs["complete"]) for g in f["points"].values()] == [
            True,
            False,
        ]
    r = CliRunner().invoke(app, ["export", str(run), "--format", "xls"])
    assert r.exit_code == 2 and "csv, mat, tdms, h5" in r.stderr
    r = CliRunner().invoke(app, ["export", str(tmp_path / "nope")])
    assert r.exit_code == 2 and "no such directory" in r.stderr


def test_v2_results_and_uncertainties_are_numeric_datasets(synthetic, tmp_path):
    with h5py.File(synthetic / "run.h5", "r") as f:
        ident = f["points/0000/identification/piezo__kcd11__none__ols"]
        stored = read_run(synthetic).points[0].identification("piezo", "kcd11", "none").result
        names = _s(ident["names"][()])
        lo_hi = np.array([stored["confidence_95"][k] for k in names])
        np.testing.assert_array_equal(ident["interval_95_statistical"][()], lo_hi)
        assert (ident["interval_95"][:, 0] < ident["coefficients"][()]).all()
        assert ident.attrs["interval_95_basis"] == "statistical only"  # value -+ U, no budget stated
        assert _s(ident["covariance"].attrs["names"]) == stored["free"]
        np.testing.assert_array_equal(ident["covariance"][()], np.array(stored["covariance"]))
        assert _s(ident["notes"][()]) == stored["notes"] and _s(ident["warnings"][()]) == stored["warnings"]
        assert ident.attrs["dof"] == stored["dof"]


def test_orbit_table_uncertainty_and_block_stop_reason_round_trip(tmp_path):
    from orbitrig import config as cfg
    from orbitrig.config import ModelSpec
    from orbitrig.run.plan import operating_points
    from orbitrig.store.writer import BlockRecord, PointResults, RunStore
    from reduction.table import OrbitTable

    rig, m = cfg.load_rig(), cfg.load_matrix(cfg.default_matrix_path("demo"))
    p = operating_points(m, rig)[0]
    t = OrbitTable(
        spin=p.spin,
        orbit=np.array([10.0, 20.0]),
        x=np.ones(2, complex),
        y=-1j * np.ones(2),
        fx=np.ones(2, complex),
        fy=np.ones(2, complex),
        n_records=np.array([50, 73]),
        u=np.array([[1e-8, 2e-8, 0.5, 0.6], [1.5e-8, 2.5e-8, 0.7, 0.8]]),
    )
    store = RunStore.create(tmp_path / "run", rig_text=rig.text, matrix_text=m.text, matrix_name=m.name, sim=False)
    store.begin_point(p)
    b = p.blocks[0]
    store.write_block(
        p.index,
        BlockRecord(
            block=b,
            measured_orbit_speed=abs(b.orbit),
            raw_counts=np.zeros((73, 8, 45), np.int16),
            slots=np.zeros((8, 45), np.int16),
            gains=np.ones(8),
            offsets=np.zeros(8),
            mean=np.zeros((8, 45)),
            record_phasors=np.zeros((73, 8), complex),
            phasors=np.ones(8, complex),
            dc=np.zeros(8),
            rms_residual=np.zeros(8),
            coherence=np.ones((2, 4)),
            uncertainty=np.full(8, 0.25),
            n_records=73,
            stop_reason="target",
        ),
    )
    spec = ModelSpec(model="kc8")
    store.write_results(p.index, PointResults({"piezo": t}, {("piezo", spec.key): {"spec": spec, "error": "x\ny"}}, {}))
    store.complete_point(p.index)
    store.set_status(RunStatus.COMPLETED, "")
    with h5py.File(tmp_path / "run/run.h5", "r") as f:
        fr = f[f"points/0000/frequencies/{b.tag}"]
        assert (fr.attrs["n_records"], fr.attrs["stop_reason"]) == (73, "target")
        np.testing.assert_array_equal(fr["uncertainty"][()], np.full(8, 0.25))
        tg = f["points/0000/table/piezo"]
        np.testing.assert_array_equal(tg["u"][()], t.u)
        assert _s(tg["u"].attrs["columns"]) == ["x", "y", "fx", "fy"]
        assert [tg["u"].attrs[f"units_{c}"] for c in ("x", "y", "fx", "fy")] == ["m", "m", "N", "N"]
        np.testing.assert_array_equal(tg["n_records"][()], [50, 73])
    back = read_run(tmp_path / "run").points[0].tables["piezo"]
    np.testing.assert_array_equal(back.u, t.u)
    np.testing.assert_array_equal(back.n_records, [50, 73])
    _export(tmp_path / "run", "csv", tmp_path / "csv")
    header = (tmp_path / "csv/point_0000_piezo.csv").read_text().splitlines()[0].split(",")
    assert header[-6:] == ["n_records [1]", "u_x [m]", "u_y [m]", "u_fx [N]", "u_fy [N]", "direction [1]"]
    table = read_orbit_table(tmp_path / "csv/point_0000_piezo.csv")
    np.testing.assert_array_equal(table.u, t.u)
    assert (
        (tmp_path / "run/coefficients.csv").read_text().splitlines()[1].endswith("x | y,,")
    )  # the error, then not_determined and warnings (empty)

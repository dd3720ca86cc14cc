"""A fit's warnings (its reasons to distrust it: ill-conditioning, a bad chi2, weak excitation,
bias) reach every CSV a person opens and `orbitrig reduce`'s standard error, as the contract
says ("without --json they go to standard error"): the `warnings` column of coefficients.csv,
reduce_*.csv and the export's fits.csv, and the TDMS coefficients group. Read back with
pandas, csv and npTDMS against the identification JSON stored in run.h5 (h5py)."""

from __future__ import annotations

import csv
import json
import re
import shutil

import h5py
import pandas as pd
import pytest
from nptdms import TdmsFile
from typer.testing import CliRunner

from orbitrig.analysis.reduce import csv_path
from orbitrig.cli import app


def _stored(run) -> dict[tuple[int, str, str, str], dict]:
    """(point, lms, model, freq_dep) -> the stored identify JSON (None for a refused model), read with h5py."""
    out = {}
    with h5py.File(run / "run.h5", "r") as f:
        for p, g in f["points"].items():
            for key, ig in g.get("identification", {}).items():
                raw = ig.attrs.get("json")
                lms, model = key.split("__")[:2]
                out[(int(p), lms, model, str(ig.attrs["freq_dep"]))] = None if raw is None else json.loads(raw)
    return out


def _chi2_warned(stored) -> list:
    fits = [(k, d) for k, d in stored.items() if d and d["warnings"]]
    assert fits, "the synthetic run's fits warn of their chi2"
    return fits


def test_coefficients_csv_has_each_fits_warnings(synthetic):
    stored = _stored(synthetic)
    table = pd.read_csv(synthetic / "coefficients.csv", keep_default_na=False)
    assert "warnings" in table.columns
    assert list(table.columns).index("warnings") == list(table.columns).index("not_determined") + 1
    for (point, lms, model, freq_dep), d in stored.items():
        (row,) = table[
            (table.point == point) & (table.lms == lms) & (table.model == model) & (table.freq_dep == freq_dep)
        ].to_dict("records")
        assert row["warnings"] == (" | ".join(d["warnings"]) if d else ""), (point, lms, model)
    for (point, lms, model, _), d in _chi2_warned(stored):
        chi2 = f"chi2 = {d['chi2']:.4g} for {d['dof']} degrees of freedom"
        cells = table[(table.point == point) & (table.lms == lms) & (table.model == model)]["warnings"]
        assert any(cell.startswith(chi2) for cell in cells)


def test_export_csv_and_tdms_carry_the_warnings(synthetic, tmp_path):
    stored = _stored(synthetic)
    for fmt in ("csv", "tdms"):
        res = CliRunner().invoke(app, ["export", str(synthetic), "--format", fmt, "--out", str(tmp_path / fmt)])
        assert res.exit_code == 0, res.output
    with open(tmp_path / "csv" / "fits.csv", newline="", encoding="utf-8") as fh:
        fits = list(csv.DictReader(fh))
    for (point, lms, model, freq_dep), d in stored.items():
        rows = [
            r for r in fits if (int(r["point"]), r["lms"], r["model"], r["freq_dep"]) == (point, lms, model, freq_dep)
        ]
        expected = " | ".join(d["warnings"]) if d else ""
        assert rows and {r["warnings"] for r in rows} == {expected}, (point, lms, model)  # on each of its rows
        if d is None:
            assert len(rows) == 1 and rows[0]["error"]  # a refused model: one row, its error
    exported = pd.read_csv(tmp_path / "csv" / "coefficients.csv", keep_default_na=False)
    assert list(exported["warnings"]) == list(
        pd.read_csv(synthetic / "coefficients.csv", keep_default_na=False)["warnings"]
    )
    coef = TdmsFile.read(tmp_path / "tdms" / "run.tdms")["coefficients"]
    assert coef["warnings"].properties["unit_string"] == ""
    assert list(coef["warnings"][:]) == list(exported["warnings"])
    assert any(w.startswith("chi2 = ") for w in coef["warnings"][:])


@pytest.mark.parametrize("fmt", ["text", "csv", "json"])
def test_reduce_puts_the_warnings_in_its_csv_and_on_stderr(synthetic, tmp_path, fmt):
    run = shutil.copytree(synthetic, tmp_path / "run")
    args = ["reduce", str(run), "--model", "kcd11", "--freq-dep", "poly:2", "--format", fmt]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    own = json.loads(CliRunner().invoke(app, [*args[:-2], "--json"]).stdout)["results"]
    with csv_path(run, "kcd11", "poly:2", "ols").open(newline="", encoding="utf-8") as fh:
        reduced = list(csv.DictReader(fh))
    assert [(int(r["point"]), r["lms"]) for r in reduced] == [(o["point"], o["lms"]) for o in own]
    assert all(o["warnings"] for o in own)  # chi2 far below its dof: the stated u_* look overstated
    for r, o in zip(reduced, own):
        assert r["warnings"] == " | ".join(o["warnings"])
        chi2 = re.escape(f"{o['chi2']:.4g}")
        assert re.match(rf"chi2 = {chi2} for {o['dof']} degrees of freedom", r["warnings"])
    lines = [line for line in res.stderr.splitlines() if line.startswith("warning: ")]
    if fmt == "json":  # the warnings are in the object
        assert lines == []
    else:
        assert lines == [f"warning: point {o['point']:04d} {o['lms']}: {w}" for o in own for w in o["warnings"]]
        assert "warning: " not in res.stdout

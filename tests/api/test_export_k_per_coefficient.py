"""Every export carries each coefficient's k beside its U (the sweep's combined U: Student's t at
95.45 % at its effective dof, fit_record.expanded_ks), as coefficients.csv has KEY_k: mat's
``expanded_k`` (GNU Octave loads it), tdms's channel property ``k``, fits.csv's ``k [1]``. The
fit's one ``k`` stays, the largest, for readers written before. It was the one k, the largest, alone."""

from __future__ import annotations

import csv
import json
import shutil

import h5py
import numpy as np
import pytest
from nptdms import TdmsFile
from scipy.io import loadmat

from orbitrig.store.durable import digest
from orbitrig.store.export import export_run
from support.octave import octave_eval

FIT = "piezo__kcd11__none__ols"
OWN = {"Kxx": 2.52, "Kxy": 3.31}  # each k other than 2, as a loads fit of 8 or 3 dof gives


@pytest.fixture(scope="module")
def exported(synthetic_run, tmp_path_factory):
    """The run with point 0000's FIT stored as the sweep stores a combined U with its own k per
    coefficient, exported as csv, mat and tdms; the ks by name."""
    run = tmp_path_factory.mktemp("k_values") / "run"
    shutil.copytree(synthetic_run, run)
    for path, prefix in ((run / "run.h5", "points/0000/"), (run / "points/0000/results.h5", "")):
        with h5py.File(path, "r+") as f:  # the run file and the point's piece alike
            g = f[f"{prefix}identification/{FIT}"]
            result = json.loads(g.attrs["json"])
            ks = {k: OWN.get(k, 2.0) for k in result["coefficients"]}
            values = {k: ks[k] * result["std_errors"][k] for k in ks}
            result["expanded_uncertainty"] = {"values": values, "k": 3.31, "k_values": ks, "basis": "combined"}
            g.attrs["json"] = json.dumps(result)
    record = run / "points/0000/complete.json"  # the commit record names the piece as it is now
    files = json.loads(record.read_text())
    size, sha = digest(run / "points/0000/results.h5")
    files["files"]["results.h5"] = {"size": size, "sha256": sha}
    record.write_text(json.dumps(files))
    for fmt in ("csv", "mat", "tdms"):
        export_run(run, fmt, run / "out" / fmt)
    return run / "out", ks


def test_mat_has_each_k_beside_u_and_the_largest(exported):
    out, ks = exported
    m = loadmat(out / "mat" / "run.mat", simplify_cells=True)
    fit = m["points"]["p0000"]["identification"][FIT]
    np.testing.assert_array_equal(fit["expanded_k"], [ks[n] for n in fit["names"]])
    assert fit["k"] == 3.31 and m["units"]["expanded_k"] == "1"


def test_tdms_channel_k_and_csv_column(exported):
    out, ks = exported
    g = TdmsFile.read(out / "tdms" / "run.tdms")[f"fit 0000 {FIT}"]
    assert g.properties["k"] == 3.31
    for name, k in ks.items():
        assert g[name].properties["k"] == k and g[name].properties["k.unit_string"] == "1", name
    with open(out / "csv" / "fits.csv", newline="", encoding="utf-8") as fh:
        rows = [r for r in csv.DictReader(fh) if (r["point"], r["model"], r["freq_dep"]) == ("0", "kcd11", "none")]
    rows = [r for r in rows if r["lms"] == "piezo"]
    assert {r["name"]: float(r["k [1]"]) for r in rows} == ks


def test_octave_reads_each_k(exported, tmp_path):
    out, ks = exported
    script = (
        f"m = load('{out / 'mat' / 'run.mat'}');\n"
        f"f = m.points.p0000.identification.{FIT};\n"
        "printf('k %s %.17g\\n', [cellstr(f.names)'; num2cell(f.expanded_k(:))']{:});\n"
    )
    done = octave_eval(script, tmp_path)
    got = {ln.split()[1]: float(ln.split()[2]) for ln in done.stdout.splitlines() if ln.startswith("k ")}
    assert got == ks, done.stdout + done.stderr[-2000:]

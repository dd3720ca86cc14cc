"""A run's provenance names the SHA-256 of rig.toml and of the matrix file as read
(`rig_sha256`, `matrix_sha256`): run.json stores both texts, but a matrix that uses a design is
stored with its [design_used] table appended, so the matrix file's own hash could not be
computed from the run. Real parts: `orbitrig sweep --sim` in a lab folder, a matrix with
`[orbit] design = "NAME"`; the hashes are hashlib's of the files' bytes, in run.json, run.h5 and
an export alike."""

from __future__ import annotations

import csv
import hashlib
import json

import h5py
import pytest

from orbitrig.config.home import HOME_ENV
from orbitrig.store.export import export_run
from orbitrig.store.reader import read_run

from support.cli_helpers import orbitrig
from support.rig_configs import patient_lab

pytestmark = pytest.mark.timeout(300)

MATRIX = """name = "dsha"
[operating]
spin_rpm = [1000.0]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.4]
static_eccentricity = [0.0]
dynamic_eccentricity = [0.096]
[orbit]
design = "kcd11-demo"
[averaging]
min_revolutions = 4
max_revolutions = 8
[[models]]
model = "kc8"
"""


def test_the_provenance_holds_the_sha256_of_rig_toml_and_of_the_matrix_file_as_read(tmp_path):
    lab = patient_lab(tmp_path / "lab")
    matrix = lab / "matrices" / "dsha.toml"
    matrix.write_bytes(MATRIX.encode())
    out = tmp_path / "run"
    args = ("sweep", "--sim", "--matrix", "dsha", "--out", str(out), "--speedup", "40", "--no-draw-figures")
    done = orbitrig(*args, timeout=240, columns=None, env={HOME_ENV: str(lab)})
    assert done.returncode == 0, done.stdout + done.stderr
    rig_sha = hashlib.sha256((lab / "rig.toml").read_bytes()).hexdigest()
    matrix_sha = hashlib.sha256(matrix.read_bytes()).hexdigest()

    header = json.loads((out / "run.json").read_text(encoding="utf-8"))
    prov = header["provenance"]
    assert (prov["rig_sha256"], prov["matrix_sha256"]) == (rig_sha, matrix_sha)
    assert "[design_used]" in header["matrix_config"]  # the stored text is not the file's: its hash is not
    assert hashlib.sha256(header["matrix_config"].encode()).hexdigest() != matrix_sha
    assert hashlib.sha256(header["rig_config"].encode()).hexdigest() == rig_sha  # rig.toml stored byte-exact

    with h5py.File(out / "run.h5", "r") as f:
        assert (f.attrs["rig_sha256"], f.attrs["matrix_sha256"]) == (rig_sha, matrix_sha)
        assert f.attrs["matrix_sha256__description"].startswith("SHA-256 of the matrix file's text as read")
    run = read_run(out)
    assert (run.provenance["rig_sha256"], run.provenance["matrix_sha256"]) == (rig_sha, matrix_sha)
    (provenance_csv,) = [p for p in export_run(out, "csv", tmp_path / "export").files if p.name == "provenance.csv"]
    with provenance_csv.open(newline="", encoding="utf-8") as f:
        rows = dict(csv.reader(f))
    assert (rows["rig_sha256"], rows["matrix_sha256"]) == (rig_sha, matrix_sha)

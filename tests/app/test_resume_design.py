"""`sweep --resume` of a matrix with `[orbit] design = "NAME"`: the design is fixed when the run
starts and stored with the run's matrix ([design_used]: name, file, sha256, text), and the
remaining points are measured with that copy. A design file overwritten (`orbitrig design
--save NAME`) or deleted between the stop and the resume changes nothing but one warning line;
a run that stored only the design's name (made before) reads the file again, with a warning."""

from __future__ import annotations

import hashlib
import json
import shutil
import tomllib

import h5py
import pytest

from orbitrig import config as cfg
from orbitrig.config.home import HOME_ENV
from orbitrig.store.reader import read_run

from support.rig_configs import patient_lab
from support.cli_helpers import orbitrig, orbitrig_cmd, orbitrig_here
from support.sweep_helpers import stop_after_first_point

pytestmark = pytest.mark.timeout(300)

MATRIX = """name = "dres"
[operating]
spin_rpm = [1000.0, 1500.0]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.4]
static_eccentricity = [0.0]
dynamic_eccentricity = [0.096]
[orbit]
design = "kcd11-demo"
[averaging]
min_revolutions = 4
max_revolutions = 12
[[models]]
model = "kc8"
"""


def _orbitrig(lab, *args, timeout=180):
    return orbitrig(*args, timeout=timeout, columns=None, env={HOME_ENV: str(lab)})


@pytest.fixture(scope="module")
def stopped_once(tmp_path_factory):
    """(folder, a copy of it): a lab (folder/lab) and a 2-point --sim run of MATRIX in it
    (folder/run), stopped by SIGTERM once point 0 is complete (exit 3)."""
    folder = tmp_path_factory.mktemp("dres")
    lab = patient_lab(folder / "lab")
    (lab / "matrices" / "dres.toml").write_text(MATRIX)
    out = folder / "run"
    cmd = orbitrig_cmd("sweep", "--sim", "--matrix", "dres", "--out", str(out), "--speedup", "10", "--no-draw-figures")
    stop_after_first_point(cmd, out, env={HOME_ENV: str(lab)})
    assert [p.complete for p in read_run(out).points] == [True, False]
    kept = tmp_path_factory.mktemp("dres-kept")
    for name in ("lab", "run"):
        shutil.copytree(folder / name, kept / name)
    return folder, kept


@pytest.fixture
def stopped(stopped_once):
    """(lab, design file, its text, run directory): the stopped run and its lab as they were left,
    in the places the run recorded (its design file's path among them), whatever a test before
    did to them."""
    folder, kept = stopped_once
    for name in ("lab", "run"):
        shutil.rmtree(folder / name)
        shutil.copytree(kept / name, folder / name)
    design = folder / "lab" / "designs" / "kcd11-demo.toml"
    return folder / "lab", design, design.read_text(), folder / "run"


def _blocks(out):
    """Per point: its blocks' (|Omega|/omega rounded, direction)."""
    run = read_run(out)
    assert len(run.points) == 2 and all(p.complete for p in run.points)
    return [sorted((round(abs(f.orbit) / p.settings.spin, 4), f.direction) for f in p.frequencies) for p in run.points]


def _assert_measured_with(out, original: str) -> None:
    """Both points measured the original design's ratios, and the run (run.json and run.h5)
    records that design: its text, SHA-256 and values in the stored matrix."""
    design = tomllib.loads(original)
    expected = sorted((r, d) for r in design["ratios"] for d in (1, -1))
    assert _blocks(out) == [expected, expected]
    with h5py.File(out / "run.h5", "r") as f:
        assert f.attrs["status"] == "completed"
        stored_h5 = str(f.attrs["matrix_config"])
    stored = json.loads((out / "run.json").read_text())["matrix_config"]
    assert stored_h5 == stored
    record = tomllib.loads(stored)["design_used"]
    assert record["name"] == "kcd11-demo" and record["text"] == original
    assert record["sha256"] == hashlib.sha256(original.encode()).hexdigest()
    mat = cfg.matrix_from_text(stored, "stored")  # the design's ratios, revolutions and targets, as run
    assert mat.orbit.ratio_list == sorted(design["ratios"])
    by_ratio = sorted(zip(design["ratios"], design["revolutions"], design["target_pct"]))
    per_ratio = [(mat.orbit.revolutions_at(k), mat.orbit.target_pct_at(k)) for k in range(len(by_ratio))]
    assert per_ratio == [(n, t) for _, n, t in by_ratio]


def test_a_design_overwritten_between_stop_and_resume_does_not_change_the_remaining_points(stopped):
    lab, design, original, out = stopped
    design_args = ("--model", "kc8", "--spin", "1000", "--matrix", "demo", "--match", "--save", "kcd11-demo")
    saved = orbitrig_here("design", *design_args, env={HOME_ENV: str(lab)})
    assert saved.returncode == 0, saved.stderr
    now = tomllib.loads(design.read_text())
    assert now["ratios"] != tomllib.loads(original)["ratios"]  # the audit's seven ratios, other targets

    p = _orbitrig(lab, "sweep", "--sim", "--resume", "--out", str(out), "--no-draw-figures")
    assert p.returncode == 0, p.stderr
    _assert_measured_with(out, original)
    line = f"warning: design file {design.resolve()} has changed since the run started"
    assert line in p.stderr and line in (out / "run.log").read_text()
    assert tomllib.loads(design.read_text()) == now  # the lab's file is left as it is


def test_a_deleted_design_file_does_not_break_the_resume(stopped):
    lab, design, original, out = stopped
    design.unlink()
    p = _orbitrig(lab, "sweep", "--sim", "--resume", "--out", str(out), "--no-draw-figures")
    assert p.returncode == 0, p.stderr
    _assert_measured_with(out, original)
    line = f"warning: design file {design.resolve()} no longer exists"
    assert line in p.stderr and line in (out / "run.log").read_text()


def test_a_run_that_stored_only_the_design_name_reads_it_again_with_a_warning(stopped):
    lab, design, original, out = stopped
    header = json.loads((out / "run.json").read_text())
    assert "[design_used]" in header["matrix_config"]
    header["matrix_config"] = MATRIX  # as a run made before designs were stored: the matrix file's text
    (out / "run.json").write_text(json.dumps(header, indent=1))
    p = _orbitrig(lab, "sweep", "--sim", "--resume", "--out", str(out), "--no-draw-figures")
    assert p.returncode == 0, p.stderr
    expected = sorted((r, d) for r in tomllib.loads(original)["ratios"] for d in (1, -1))
    assert _blocks(out) == [expected, expected]  # the file is unchanged: as today
    line = "the run stored only the name of its design 'kcd11-demo'"
    assert line in p.stderr and line in (out / "run.log").read_text()
    assert f"read again from {design.resolve()}" in p.stderr

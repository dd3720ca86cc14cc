"""`sweep --dry-run --resume`: the plan the resume runs, not the whole matrix afresh. Its points
in the order the run started with (run.json's point_order: the changeover times may have been
edited since, and a point's files are named by that order), the points complete marked, and
what is left said first.

Real parts: a `sweep --sim` run of the demo matrix (a subprocess on the simulator); its run.json
given another matrix and a started order for the second case (a run stopped before any point);
the dry runs (which start nothing) in the test's process."""

from __future__ import annotations

import json
import re

import pytest

from orbitrig.config import load_matrix, load_rig
from orbitrig.run.plan import make_plan
from support.cli_helpers import orbitrig, orbitrig_here
from support.paths import ROOT

pytestmark = pytest.mark.timeout(240)


def test_the_dry_run_of_a_resume_shows_the_started_order_and_what_is_left(tmp_path):
    run = tmp_path / "run"
    s = orbitrig("sweep", "--sim", "--sim-config", "clean", "--out", str(run))
    assert s.returncode == 0, s.stderr
    d = orbitrig_here("sweep", "--dry-run", "--sim", "--resume", "--out", str(run))
    assert d.returncode == 0, d.stderr
    # nothing left: the resume starts nothing (it read 'estimated 0:02', the closing stop of the drives)
    assert "resume: 1 of 1 points complete (0000); left: 0 points, nothing to measure (the totals" in d.stdout, d.stdout
    assert re.search(r"^ 0000 .*_ed0\.096  \(complete\)$", d.stdout, re.M), d.stdout
    # a run of three points started in another order than the rig's estimates give now
    matrix = ROOT / "config/matrices/eccentricity.toml"
    started = [2, 0, 1]
    assert list(make_plan(load_matrix(matrix), load_rig()).order or range(3)) != started  # a plan made now differs
    header = json.loads((run / "run.json").read_text())
    header.update(matrix_config=matrix.read_text(), matrix_name="eccentricity", point_order=started)
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "run.json").write_text(json.dumps(header))
    e = orbitrig_here("sweep", "--dry-run", "--sim", "--resume", "--out", str(tmp_path / "other"))
    assert e.returncode == 0, e.stderr
    assert "resume: 0 of 3 points complete; left: 3 points, " in e.stdout, e.stdout
    written = make_plan(load_matrix(matrix), load_rig(), list(range(3))).points
    labels = re.findall(r"^ (000\d) +\S+ +\S+ +\d+  (\S+)$", e.stdout, re.M)
    assert labels == [(f"000{i}", written[k].label) for i, k in enumerate(started)], e.stdout

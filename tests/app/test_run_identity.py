"""One id per run: the sweep's (its log, its MQTT status and results), the catalog's and a
resume's are the same, ``<rig id>@<created>`` of run.json."""

from __future__ import annotations

import re

import pytest

from orbitrig.catalog.rows import run_rows
from orbitrig.config.home import HOME_ENV
from orbitrig.store.identity import run_identity
from orbitrig.store.reader import read_run

from support.rig_configs import patient_lab
from support.cli_helpers import orbitrig, orbitrig_cmd
from support.sweep_helpers import stop_after_first_point

pytestmark = pytest.mark.timeout(300)

MATRIX = """name = "ident"
revolutions = 6
[operating]
spin_rpm = [800.0, 1000.0, 1500.0]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.4]
static_eccentricity = [0.0]
dynamic_eccentricity = [0.096]
[orbit]
ratios = [0.5, 1.5]
[[models]]
model = "kc8"
"""


def test_a_resumed_run_keeps_the_id_the_catalog_gives_it(tmp_path):
    lab = patient_lab(tmp_path / "lab")
    (lab / "matrices" / "ident.toml").write_text(MATRIX)
    env = {HOME_ENV: str(lab)}
    out = tmp_path / "run"
    sweep = orbitrig_cmd(
        "sweep", "--sim", "--matrix", "ident", "--out", str(out), "--speedup", "10", "--no-draw-figures"
    )
    stop_after_first_point(sweep, out, env=env)  # three points: some left however late the stop lands
    resumed = orbitrig(
        "sweep",
        "--sim",
        "--resume",
        str(out),
        "--speedup",
        "10",
        "--no-draw-figures",
        timeout=240,
        columns=None,
        env=env,
    )
    assert resumed.returncode == 0, resumed.stderr[-3000:]

    run = read_run(out)
    assert run.run_id == run_identity(run.provenance["rig_id"], run.created)
    assert run.provenance["rig_id"] and run.created
    sessions = re.findall(r"\b(start|resume) run (\S+):", (out / "run.log").read_text())
    assert [kind for kind, _ in sessions] == ["start", "resume"]
    assert {rid for _, rid in sessions} == {run.run_id}
    rows = run_rows(run)
    assert rows and {r["run_id"] for r in rows} == {run.run_id}

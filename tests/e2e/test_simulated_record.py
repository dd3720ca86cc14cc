"""A record measured on the simulator says so (``simulator``: the scenario it ran) and is refused
by the rig: its runout, lags and gains are the simulator's (random runout phases, declared chain
errors), and a run or step on the rig would take them silently (its ``rig`` is the lab's id and
its channel setup the lab's, so neither check sees it). A --sim run takes it; one on another
scenario than the record's warns at its start, naming both.

Real parts: `orbitrig calibrate runout --sim` writes the record in a lab folder (a subprocess
on the simulator); `orbitrig sweep`, `orbitrig calibrate loads` and `orbitrig serve` without --sim then refuse it
before they reach for the rig (exit 2, the record file and its `simulator` line named, nothing
made); `calibrate list` marks it; `orbitrig sweep --sim` runs with it (on another scenario: warned)."""

from __future__ import annotations

import re
import shutil

import pytest

from orbitrig.cli.scenarios import default_scenario
from orbitrig.config import digest, load_rig
from sim.scenario_files import scenario_path
from support.rig_configs import patient_rig_config
from support.cli_helpers import orbitrig
from support.paths import ROOT

pytestmark = pytest.mark.timeout(240)


def _lab(tmp_path):
    patient_rig_config(tmp_path)  # a link that holds with both cores busy
    shutil.copytree(ROOT / "config/calibration", tmp_path / "calibration")
    return tmp_path / "rig.toml"


def test_a_record_measured_on_the_simulator_is_refused_on_the_rig(tmp_path):
    rig = _lab(tmp_path)
    p = orbitrig("calibrate", "runout", "--sim", "--sim-config", "clean", "--config", str(rig), "--revolutions", "4")
    assert p.returncode == 0, p.stderr
    name = load_rig(rig).calibration_record
    path = tmp_path / "calibration" / f"{name}.toml"
    text = path.read_text()
    assert re.search(r'^simulator = ".*clean\.toml"$', text, re.M), text  # the scenario it ran
    assert f'\nsimulator_sha256 = "{digest(scenario_path("clean").read_text())}"\n' in text  # and its content
    line = text.splitlines().index(next(x for x in text.splitlines() if x.startswith("simulator = "))) + 1
    for args, nothing in (
        (("sweep", "--matrix", "demo", "--out", str(tmp_path / "run")), "no run directory was made"),
        (("sweep", "--dry-run", "--matrix", "demo"), "no run directory was made"),  # its plan says so too
        (("calibrate", "loads", "--reference-id", "DW-7", "--reference-u-pct", "0.02"), "no record was written"),
        (("serve", "--broker", "mqtt://127.0.0.1:1"), "the service was not started"),
    ):
        q = orbitrig(*args, "--config", str(rig), timeout=60)
        assert q.returncode == 2 and "Traceback" not in q.stderr, q.stderr
        assert f"{path}: line {line}: key 'simulator': this runout record was measured on the simulator" in q.stderr
        assert nothing in q.stderr and "does not answer" not in q.stderr, q.stderr
    assert not (tmp_path / "run").exists()
    # a service started on the rig before the record was made active refuses the next start with it
    from orbitrig.cli.serve import _reloaded
    from orbitrig.service.rig_service import CommandRefused

    with pytest.raises(CommandRefused, match=f"line {line}: key 'simulator': this runout record was measured on"):
        _reloaded(rig, load_rig(ROOT / "config/rig.toml"), on_the_rig=True)
    assert _reloaded(rig, load_rig(rig), on_the_rig=False).record.simulator  # serve --sim takes it
    listed = orbitrig("calibrate", "list", "--config", str(rig)).stdout
    assert re.search(rf"^\* {name} .*  runout .*  on the simulator$", listed, re.M), listed
    s = orbitrig("sweep", "--sim", "--sim-config", "clean", "--config", str(rig), "--out", str(tmp_path / "sim"))
    assert s.returncode == 0, s.stderr  # the simulator's own record, on the simulator
    assert "measured on the simulator scenario" not in s.stderr, s.stderr  # on its own scenario: no warning


def test_a_sim_sweep_on_another_scenario_than_its_records_warns_naming_both(tmp_path):
    """A record measured on the scenario `clean` corrects a sweep on the default scenario with
    clean's runout and lags: the sweep runs (CI and training use it), warning at its start."""
    rig = _lab(tmp_path)
    p = orbitrig("calibrate", "runout", "--sim", "--sim-config", "clean", "--config", str(rig), "--revolutions", "4")
    assert p.returncode == 0, p.stderr
    path = tmp_path / "calibration" / f"{load_rig(rig).calibration_record}.toml"
    clean = re.search(r'^simulator = "(.*)"$', path.read_text(), re.M)
    assert clean is not None and clean[1].endswith("clean.toml")
    s = orbitrig("sweep", "--sim", "--config", str(rig), "--out", str(tmp_path / "sim"))
    assert s.returncode == 0, s.stderr
    warning = next((x for x in s.stderr.splitlines() if "measured on the simulator scenario" in x), "")
    assert warning.startswith(f"warning: the calibration record {path} was measured on the simulator scenario "), (
        s.stderr
    )
    paper = default_scenario()
    sha = (digest(scenario_path("clean").read_text())[:12], digest(paper.text)[:12])
    assert f"scenario {clean[1]} (SHA-256 {sha[0]}), this run runs {paper.name} (SHA-256 {sha[1]}): " in warning

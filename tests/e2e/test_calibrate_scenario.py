"""`orbitrig calibrate --sim --sim-config` takes a shipped scenario by name, as `sweep` does
(one resolver: orbitrig.cli.scenarios.scenario_file). Real subprocess runs on the simulator."""

from __future__ import annotations

import shutil

import pytest

from orbitrig.config import read_record
from orbitrig.run.provenance import software_version
from support.rig_configs import patient_rig_config
from support.cli_helpers import orbitrig, orbitrig_here
from support.paths import ROOT

pytestmark = pytest.mark.timeout(120)


def _rig(tmp_path):
    patient_rig_config(tmp_path)  # a link that holds with both cores busy
    shutil.copytree(ROOT / "config/calibration", tmp_path / "calibration")
    return tmp_path / "rig.toml"


def test_a_shipped_scenario_is_taken_by_name(tmp_path):
    rig = _rig(tmp_path)
    before = set((tmp_path / "calibration").iterdir())
    p = orbitrig("calibrate", "runout", "--sim", "--sim-config", "clean", "--config", str(rig), "--revolutions", "4")
    assert p.returncode == 0, p.stderr
    assert "both drives stopped" in p.stderr
    (new,) = set((tmp_path / "calibration").iterdir()) - before  # the new record
    # it names the code that wrote it as a run's provenance does (source digest, git), not the
    # version number alone (a record written before a fix of a step reads the same otherwise)
    assert read_record(new.parent, new.stem)[0].software == software_version()


def test_an_unknown_scenario_name_is_refused_naming_the_shipped_ones(tmp_path):
    p = orbitrig("calibrate", "runout", "--sim", "--sim-config", "nosuch", "--config", str(_rig(tmp_path)))
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    assert "nosuch: no such file" in p.stderr and "clean" in p.stderr
    assert "slow roll:" not in p.stderr


@pytest.mark.parametrize(
    "command",
    [("sweep", "--dry-run"), ("calibrate", "runout"), ("serve", "--broker", "mqtt://127.0.0.1:1")],
    ids=["sweep", "calibrate", "serve"],
)
def test_every_command_refuses_a_sim_config_without_sim(tmp_path, command):
    """One check (orbitrig.cli.scenarios.needs_sim), in one form, before anything starts."""
    p = orbitrig_here(*command, "--sim-config", "clean", "--config", str(_rig(tmp_path)))
    assert p.returncode == 2 and "--sim-config needs --sim" in p.stderr and "Traceback" not in p.stderr, p.stderr

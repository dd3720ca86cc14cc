"""Each probe's own time delay (`[chain] probe_delay`, four values in sim.config.PROBE_NAMES order)
reaches that probe's channel by its name, wherever the channel order (sim.config.CHANNEL_NAMES)
puts the probes."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import pytest

from sim.chain import calibration_errors, channel_chains
from sim.config import CHANNEL_NAMES, PROBE_NAMES
from sim.scenario_files import sim_config_from_text
from support.cli_helpers import child_env
from support.paths import ROOT

SCENARIO = (
    "[chain]\nforce_delay = 5e-6\nprobe_delay = [1e-6, 2e-6, 3e-6, 4e-6]\nfilter_cutoff = [0, 0, 0, 0, 0, 0, 0, 0]\n"
)
OWN = {"x_a": 1e-6, "y_a": 2e-6, "x_b": 3e-6, "y_b": 4e-6}


def test_each_probe_has_its_own_delay_and_the_forces_theirs():
    assert PROBE_NAMES == ("x_a", "y_a", "x_b", "y_b") and set(PROBE_NAMES) < set(CHANNEL_NAMES)
    chains = channel_chains(sim_config_from_text(SCENARIO))
    assert {name: chains[name].delay for name in PROBE_NAMES} == OWN
    assert [chains[name].delay for name in CHANNEL_NAMES if name not in PROBE_NAMES] == [5e-6] * 4
    errors = calibration_errors(sim_config_from_text(SCENARIO))
    assert errors["x"]["delay"] == pytest.approx(2e-6) and errors["y"]["delay"] == pytest.approx(3e-6)


def test_a_probe_delay_list_not_of_four_values_is_refused_naming_the_order():
    with pytest.raises(ValueError, match=r"chain.probe_delay needs 4 values \(order x_a, y_a, x_b, y_b\)"):
        sim_config_from_text("[chain]\nprobe_delay = [0.0, 1e-6, 0.0]\n")


PROBE = """
import json
from sim.chain import channel_chains
from sim.config import CHANNEL_NAMES
from sim.scenario_files import sim_config_from_text
chains = channel_chains(sim_config_from_text({scenario!r}))
print(json.dumps([list(CHANNEL_NAMES), {{name: chains[name].delay for name in CHANNEL_NAMES}}]))
"""


def test_the_probes_interleaved_with_the_forces_keep_their_own_delays(tmp_path):
    """The simulator's channel order changed in its one place (sim/config.py's CHANNEL_NAMES, a
    probe after each force channel): the four delays still go to x_a, y_a, x_b, y_b."""
    package = tmp_path / "sim"
    package.mkdir()
    (package / "__init__.py").write_text("")
    for module in ("chain.py", "scenario_files.py"):
        shutil.copyfile(ROOT / "sim" / module, package / module)
    config = (ROOT / "sim" / "config.py").read_text()
    line = 'CHANNEL_NAMES = ("fx_piezo", "fy_piezo", "fx_strain", "fy_strain", "x_a", "y_a", "x_b", "y_b")'
    assert line in config
    order = ("fx_piezo", "x_a", "fy_piezo", "y_a", "fx_strain", "x_b", "fy_strain", "y_b")
    (package / "config.py").write_text(config.replace(line, f"CHANNEL_NAMES = {order!r}"))
    done = subprocess.run(
        [sys.executable, "-c", PROBE.format(scenario=SCENARIO)],
        cwd=tmp_path,
        env=child_env({"PYTHONPATH": str(tmp_path)}),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    names, delays = json.loads(done.stdout)
    assert tuple(names) == order
    assert {name: delays[name] for name in OWN} == OWN
    assert [delays[name] for name in order if name.startswith("f")] == [5e-6] * 4

"""The shipped rig configuration describes the bearing the simulator simulates: `sweep --sim`
records config/rig.toml with the run, so its [bearing] must be the simulated one (the paper's
D = L = 38.1 mm, c = 60 um; config/sim.toml)."""

from __future__ import annotations

import pytest

from orbitrig.config import load_rig, shipped_config
from orbitrig.config.rig import Bearing
from sim.scenario_files import scenario


def test_shipped_rig_bearing_is_the_simulators():
    rig = load_rig(shipped_config() / "rig.toml")
    for name in ("paper", "clean", "compressible"):
        sim = scenario(name)
        assert 2 * rig.bearing.radius_mm * 1e-3 == pytest.approx(sim.bearing.diameter, rel=1e-12), name
        assert rig.bearing.clearance == pytest.approx(sim.geometry.clearance, rel=1e-12), name
    assert rig.bearing == Bearing()  # the model's defaults are this bearing (a lab's rig.toml must give its own)
    assert rig.bearing.radius_mm == 19.05

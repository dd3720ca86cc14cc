"""A `--sim` run of several operating points stores each point's own truth: the simulator's
bearing at that point's manual settings, not at the next point's (the identification runs in
the background while the next point's settings are being made).

Two points that differ only in static eccentricity (0 and 0.3): a centred journal has Kxx = Kyy,
an eccentric one does not. Each stored true Z must equal the simulator's physics set by hand to
that point's settings, to the rounding of the stored numbers.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from orbitrig.store.reader import read_run
from sim.scenario_files import load_sim_config
from sim.physics import RigPhysics

from support.paths import ROOT
from support.cli_helpers import orbitrig

SCENARIO = "config/sim/clean.toml"
MATRIX = """
name = "eccentricity"
revolutions = 8
order = "written"
[operating]
spin_rpm = [1000.0]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.4]
static_eccentricity = [0.0, 0.3]
dynamic_eccentricity = [0.096]
[orbit]
ratios = [0.3, 0.6, 0.9]
[[models]]
model = "kc8"
"""


def _true_z(settings, orbit: np.ndarray) -> np.ndarray:
    """Z (n, 2, 2) of the scenario's bearing at `settings` (the stored operating point), by hand."""
    cfg = load_sim_config(ROOT / SCENARIO)
    physics = RigPhysics(cfg)
    physics.set_manual(
        orbit_radius=settings.orbit_radius,
        static_eccentricity=settings.static_eccentricity,
        recess_pressure=settings.recess_pressure,
        pressure_ratio=settings.pressure_ratio,
    )
    return physics.impedances(settings.spin, orbit)


@pytest.mark.timeout(180)
def test_each_point_stores_the_truth_at_its_own_settings(tmp_path):
    matrix = tmp_path / "eccentricity.toml"
    matrix.write_text(MATRIX)
    out = tmp_path / "run"
    done = orbitrig(
        "sweep",
        "--sim",
        "--sim-config",
        SCENARIO,
        "--matrix",
        str(matrix),
        "--out",
        str(out),
        timeout=170,
        columns=None,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    run = read_run(out)
    assert [p.settings.static_eccentricity for p in run.points] == [0.0, 0.3]
    for point in run.points:
        truth = point.truth
        z = np.asarray(truth["Z_re"]) + 1j * np.asarray(truth["Z_im"])
        expected = _true_z(point.settings, np.asarray(truth["orbit"]))
        assert np.allclose(z, expected, rtol=1e-9, atol=0), (point.name, z[0], expected[0])
    centred, eccentric = (np.asarray(p.truth["K0"]) for p in run.points)
    assert math.isclose(centred[0, 0], centred[1, 1], rel_tol=1e-6)  # a centred journal: Kxx = Kyy
    assert not math.isclose(eccentric[0, 0], eccentric[1, 1], rel_tol=1e-3)

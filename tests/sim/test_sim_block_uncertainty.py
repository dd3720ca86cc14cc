"""The u_* of an averaged block against its actual error, on the simulator's paper point with
every disturbance on (spindle tones at 1x and 2x spin, ball-pass orders, line frequency,
jitter): the fundamental of the time-synchronous average at non-integer spin/orbit ratios,
including 2.5 spin turns per orbit (half a turn per revolution: an even block cancels the 1x
tone, an odd one keeps 1/n of it) and the paper's 0.978 near synchronous."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support.coverage_points import table1_physics

from reduction.noise import mean_uncertainty
from sim.config import SimConfig
from sim.revolutions import revolution_phasors, simulate_revolutions

SPIN = 1000 * 2 * math.pi / 60
BLOCKS = 30


@pytest.mark.parametrize("ratio, n", [(0.4, 50), (0.4, 51), (0.978, 50), (0.363, 50)])
def test_the_stated_uncertainty_of_a_block_is_its_error(ratio, n):
    """RMS over 30 blocks of |mean - true| / u within 1 +- 0.25, for the 4 force channels and
    for the 4 probes (120 complex errors each: the ratio's spread is about 6.5 %, so the band
    is about 4 standard deviations). The plain scatter of the revolutions would read the
    probes' u 1.4 to 2.2 times too large (ratio 0.45 to 0.7)."""
    ratios = []
    for seed in range(BLOCKS):
        cfg = SimConfig(seed=seed)
        ph = table1_physics(cfg)
        orbit = ratio * SPIN
        q = revolution_phasors(*simulate_revolutions(ph, SPIN, orbit, n, t0=0.37 * seed))
        true = ph.true_phasors(SPIN, orbit)
        err = np.abs(q.mean(axis=0) - np.array([true[c.name] for c in ph.channels]))
        ratios.append(err / mean_uncertainty(q, SPIN / orbit))
    r = np.square(ratios)
    forces, probes = float(np.sqrt(np.mean(r[:, :4]))), float(np.sqrt(np.mean(r[:, 4:])))
    assert [c.name[0] for c in ph.channels] == ["f"] * 4 + ["x", "y"] * 2
    assert forces == pytest.approx(1.0, abs=0.25) and probes == pytest.approx(1.0, abs=0.25), (forces, probes)

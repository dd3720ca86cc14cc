"""The runout step records each runout phasor's standard uncertainty (orbitrig.run.calibration_measure.runout_of;
docs/calibration.md): the harmonics of the slow roll's mean, and the scatter of its revolutions'
harmonics (reduction.noise.phasor_uncertainty), from the raw counts the block keeps."""

from __future__ import annotations

import numpy as np
import pytest

from orbitrig.config import ProbeRunout
from orbitrig.run.calibration_measure import runout_of

THETA = 2 * np.pi * np.arange(360) / 360


def test_the_runout_is_the_mean_revolutions_harmonics_and_its_uncertainty_their_scatter():
    gain, offset, n = 2e-8, 1e-5, 6  # m per count
    # 1x: 1000 counts, +-100 counts alternating revolution by revolution; 2x: 300 counts at 90 degrees
    counts = np.array(
        [
            np.round(200 + (1000 + (100 if r % 2 else -100)) * np.cos(THETA) + 300 * np.cos(2 * THETA + np.pi / 2))
            for r in range(n)
        ]
    ).astype(np.int16)
    h, u = runout_of(counts, gain, offset, THETA)
    assert h[0] == pytest.approx(1000 * gain, rel=1e-4) and abs(h[0].imag) < 1e-3 * 1000 * gain
    assert h[1] == pytest.approx(300j * gain, rel=1e-3)
    # sqrt(sum |d|^2 / (n - 1)) / sqrt(n) with |d| = 100 counts: 100 / sqrt(n - 1)
    assert u[0] == pytest.approx(100 * gain / np.sqrt(n - 1), rel=1e-3)
    assert u[1] < 1e-3 * u[0]  # the 2x does not scatter (the counts' rounding alone)
    one, u_one = runout_of(counts[:1], gain, offset, THETA)
    assert np.isinf(u_one).all() and one[0] == pytest.approx(900 * gain, rel=1e-4)
    # a record keeps them in micrometres; one without them (an older record) reads as before
    track = ProbeRunout.model_validate({"h1_um": [0.02, 0.0], "h2_um": [0.0, 0.006], "h1_u_um": 0.0008})
    assert track.h1_u_um == 0.0008 and track.h2_u_um is None
    with pytest.raises(ValueError):
        ProbeRunout.model_validate({"h1_um": [0.02, 0.0], "h2_um": [0.0, 0.006], "h1_u_um": -0.1})

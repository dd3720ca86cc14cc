"""`design --noise-from RUN` groups the run's blocks by the ratio they were set to: a block's
measured |Omega|/omega scatters about it within the drives' settle tolerance (a loaded machine
or a real drive: 0.901 for 0.9), and must not make a ratio of its own."""

from __future__ import annotations

import numpy as np

from orbitrig.cli.design_inputs import SAME_RATIO, _set_ratios


def test_measured_ratios_are_grouped_by_the_set_ratio():
    measured = np.array([0.3, 0.2999, 0.5, 0.7, 0.9, 0.9012, 0.899, 1.2, 1.2004])
    assert _set_ratios(measured).tolist() == [0.3, 0.3, 0.5, 0.7, 0.9, 0.9, 0.9, 1.2, 1.2]


def test_ratios_further_apart_stay_apart():
    paper = np.linspace(0.2, 1.2, 10)  # 0.111 apart
    assert np.unique(_set_ratios(paper)).size == 10
    close = np.array([0.5, 0.5 * (1 + 2 * SAME_RATIO)])
    assert np.unique(_set_ratios(close)).size == 2

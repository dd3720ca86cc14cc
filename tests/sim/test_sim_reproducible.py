"""A seed draws the same numbers whatever the wall clock did: the A/D board's conversions of a slot
edge are a function of the seed and the edge (its time, angles and global index), not of how the
ticks cut the stream nor of what was converted before (sim/streams.py)."""

from __future__ import annotations

import math

import numpy as np

from sim.scenario_files import load_sim_config
from sim.rig import SimRig

SPIN, ORBIT = 1000 * 2 * math.pi / 60, 677 * 2 * math.pi / 60  # rad/s


def _edges(first: int, n: int):
    """Global slots, times (s), spin angles (rad) and orbit speeds (rad/s) of n steady slot edges."""
    g = np.arange(first, first + n)
    t = g * (2 * math.pi / 360) / ORBIT
    return g, t, SPIN * t, np.full(n, ORBIT)


def _convert(rig: SimRig, cuts: list[int], first: int = 1000, n: int = 3600) -> np.ndarray:
    """The board's counts of slot edges first .. first + n - 1, converted in ticks cut at ``cuts``."""
    g, t, phi, w = _edges(first, n)
    parts = np.split(np.arange(n), cuts)
    return np.concatenate([rig.stream.convert(g[i], t[i], phi[i], w[i], SPIN, ORBIT) for i in parts])


def _rig(seed: int, mode: str = "sequential") -> SimRig:
    cfg = load_sim_config("config/sim.toml")  # every disturbance on, slot-edge jitter included
    cfg.seed, cfg.adc.mode = seed, mode
    return SimRig(cfg)


def test_a_slot_edges_counts_do_not_depend_on_the_ticks_that_convert_it():
    """Sequential and simultaneous boards: ten revolutions in one tick, in 45-slot ticks, in
    irregular ones, and after 5000 other edges were converted: the same counts, bit for bit
    (before, one generator fed every draw in the order the ticks asked: a run's noise depended
    on how many slot edges each 10 ms of wall time converted)."""
    for mode in ("sequential", "simultaneous"):
        whole = _convert(_rig(5, mode), [])
        assert np.array_equal(_convert(_rig(5, mode), list(range(45, 3600, 45))), whole)
        assert np.array_equal(_convert(_rig(5, mode), [7, 500, 501, 2222]), whole)
        later = _rig(5, mode)
        _convert(later, [100], first=20_000, n=5000)
        assert np.array_equal(_convert(later, [3000]), whole)
        assert not np.array_equal(_convert(_rig(6, mode), []), whole)  # another seed, other noise


def test_a_seed_draws_its_rig_the_same_start_phases_and_bit_errors():
    """The board's starting slot, the disturbances' phases and a corrupted frame's flipped bits:
    one stream each from the seed, the same for two rigs of one seed, another for another seed."""
    a, b, c = _rig(3), _rig(3), _rig(4)
    assert a.stream._g_pos == b.stream._g_pos != c.stream._g_pos
    assert np.array_equal(a.physics.disturbances._res_phase, b.physics.disturbances._res_phase)
    assert not np.array_equal(a.physics.disturbances._res_phase, c.physics.disturbances._res_phase)
    draws = [r.board.rng.integers(0, 2**32, 4).tolist() for r in (a, b, c)]
    assert draws[0] == draws[1] != draws[2]

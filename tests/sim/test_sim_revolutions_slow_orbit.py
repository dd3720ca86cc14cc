"""sim.revolutions at a slow orbit: the housing resonance's envelope tables (4.1 s each, all force
channels at once, sim.disturbances) are made and gathered for a chunk of revolutions at a time, every
channel in turn, not for all the revolutions once per channel. 200 revolutions at 10 rpm (20 minutes
of simulated time, 293 tables): 5 MB of memory at its peak beyond the values, not 52 MB (all the
tables gathered per channel, each made again per force channel: 3 to 4 times the CPU)."""

from __future__ import annotations

import dataclasses
import math
import tracemalloc

import numpy as np

from sim.physics import RigPhysics
from sim.revolutions import simulate_revolutions
from sim.scenario_files import scenario

RPM = 2.0 * math.pi / 60.0


def _physics() -> RigPhysics:
    return RigPhysics(dataclasses.replace(scenario("paper"), seed=3))


def test_slow_orbit_revolutions_gather_a_chunk_of_tables_at_a_time():
    physics = _physics()
    tracemalloc.start()
    try:
        slots, values = simulate_revolutions(physics, 600 * RPM, 10 * RPM, 200)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    beyond = peak - values.nbytes
    assert beyond < 15e6, f"{beyond / 1e6:.1f} MB beyond the values"
    assert values.shape == (200, 8, 45) and np.all(np.isfinite(values))


def test_the_chunks_change_no_value(monkeypatch):
    """12 revolutions at 10 rpm (72 s) in chunks of 5: the values of all 12 converted at once."""
    import sim.revolutions

    slot_times = np.arange(12 * 360.0).reshape(12, 360) * (6.0 / 360)  # s: 6 s a revolution
    assert sim.revolutions._revolutions_per_chunk(slot_times) == 5
    chunked = simulate_revolutions(_physics(), 600 * RPM, 10 * RPM, 12)[1]
    monkeypatch.setattr(sim.revolutions, "CHUNK_S", math.inf)  # one chunk
    whole = simulate_revolutions(_physics(), 600 * RPM, 10 * RPM, 12)[1]
    assert np.array_equal(chunked, whole)

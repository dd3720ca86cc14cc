"""sim.revolutions at a slow orbit: a sequential channel's few samples per 4.1 s take the housing
resonance's envelope at their grid points alone (no table of 1024 grid points made for a handful of
samples), all the revolutions at once; where the envelope comes from tables (all force channels at
once, sim.disturbances), the revolutions are converted a chunk at a time, every channel in turn, not
all of them once per channel. 200 revolutions at 10 rpm (20 minutes of simulated time): a few MB of
memory at its peak beyond the values, not 52 MB (all the tables gathered per channel)."""

from __future__ import annotations

import dataclasses
import math
import tracemalloc

import numpy as np

from sim.physics import RigPhysics
from sim.adc_board import channel_slots
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
    """12 revolutions at 10 rpm (72 s) scanned simultaneously (360 samples a channel and revolution: the
    envelope from tables) in chunks of 5: the values of all 12 converted at once."""
    import sim.revolutions

    slot_times = np.arange(12 * 360.0).reshape(12, 360) * (6.0 / 360)  # s: 6 s a revolution
    assert sim.revolutions._revolutions_per_chunk(slot_times, 360) == 5
    chunked = simulate_revolutions(_physics(), 600 * RPM, 10 * RPM, 12, mode="simultaneous")[1]
    monkeypatch.setattr(sim.revolutions, "CHUNK_S", math.inf)  # one chunk
    whole = simulate_revolutions(_physics(), 600 * RPM, 10 * RPM, 12, mode="simultaneous")[1]
    assert np.array_equal(chunked, whole)


def test_a_slow_sequential_orbit_makes_no_envelope_table():
    """A sequential channel's 45 samples of a 10 rpm revolution (6 s) fall 31 to a 4.1 s envelope table:
    the envelope is evaluated at their grid points alone, all the revolutions at once, and no table of
    1024 grid points is made (which cost 3 to 18 times the CPU of the grid points at 1 to 10 rpm)."""
    import sim.revolutions

    physics = _physics()
    slot_times = np.arange(12 * 360.0).reshape(12, 360) * (6.0 / 360)
    assert sim.revolutions._revolutions_per_chunk(slot_times, 45) == 12
    simulate_revolutions(physics, 600 * RPM, 10 * RPM, 12)
    assert physics.disturbances._envelopes == {}
    simulate_revolutions(physics, 600 * RPM, 600 * RPM, 100)  # 0.1 s a revolution: tables
    assert len(physics.disturbances._envelopes) >= 2


def test_the_channel_slots_are_the_scan_s():
    """Sequential: slot s converts channel s mod C (docs/protocols/adc-frames.md); simultaneous: all."""
    slots = np.arange(360)
    scan = channel_slots(8, "sequential")
    assert [list(slots[cols][:3]) for cols in scan[:3]] == [[0, 8, 16], [1, 9, 17], [2, 10, 18]]
    assert all(np.array_equal(slots[cols] % 8, np.full(45, k)) for k, cols in enumerate(scan))
    assert [slots[cols].size for cols in channel_slots(4, "simultaneous")] == [360] * 4
    window = np.arange(1237, 1237 + 50)  # global slots of a live tick, from slot 1237 (channel 5)
    assert [list(window[cols][:2] % 8) for cols in channel_slots(8, "sequential", 1237)] == [[k, k] for k in range(8)]


def test_a_live_ticks_few_samples_take_the_tables_of_the_ticks_before():
    """The A/D board converts a tick (0.01 s wall) at a time: at speed-up 1 a force channel's 8 samples
    in 0.01 s are dense, not sparse, and take the envelope tables cached for the ticks before (summing
    the lines at their grid points cost 4 to 5 times the CPU, 40 % more a tick); a slow orbit's 4
    samples over 24 s do not."""
    physics = _physics()
    resonance = physics.disturbances._resonance
    k = 0  # a force channel
    for tick in range(3):
        resonance(k, 100.0 + 0.01 * tick + np.arange(8) * 1.25e-3)
    assert list(physics.disturbances._envelopes) == [24]  # 100 s / 4.096 s: the one table, made once
    resonance(k, 200.0 + np.arange(4) * 6.0)
    assert list(physics.disturbances._envelopes) == [24]

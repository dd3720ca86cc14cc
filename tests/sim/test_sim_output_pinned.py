"""What a seed makes, pinned: the A/D board's byte stream and sim.revolutions' values of fixed
seeds and configurations hash to the digests below. A change of the simulator's speed must leave
them alone; a change of what it simulates changes them (and says why where it does)."""

from __future__ import annotations

import dataclasses
import hashlib
import math

import numpy as np
import pytest

from sim.scenario_files import load_sim_config, scenario
from sim.physics import RigPhysics
from sim.revolutions import simulate_revolutions
from sim.rig import SimRig

SPIN = 1000 * 2 * math.pi / 60  # rad/s

#: sha256 of the frames of 12 revolutions (two operating points, irregular ticks), per board mode
STREAM = {
    "sequential": "129cb2337c82c4be00a4b47afcb1f88f59100f7fd423a07bf96c035ca95cf8bd",
    "simultaneous": "0a7abbb3eaf12e8ceac9fae1dec118ab08c05be187fbfb92546529081587e9d9",
}
#: sha256 of sim.revolutions' float64 values: the paper's rig, seed 3, four blocks
REVOLUTIONS = "6fbdabcd0b053b601db74528cb059efca63c0b4c26b6cdaeb6dadbf5b7eeb029"


def _stream(mode: str) -> bytes:
    """Frames of config/sim.toml's rig (every disturbance, slot-edge jitter), seed 7: 6 revolutions
    at orbit ratio 0.65 forward, then 6 at 1.2 backward, converted in ticks of 7, 500, 1, ... slots."""
    cfg = load_sim_config("config/sim.toml")
    cfg.seed, cfg.adc.mode = 7, mode
    rig = SimRig(cfg)
    out, t0, g0 = [], 0.0, 1234
    for ratio in (0.65, -1.2):
        orbit, n = ratio * SPIN, 6 * 360
        g = np.arange(g0, g0 + n)
        t = t0 + (g - g0) * (2 * math.pi / 360) / abs(orbit)
        phi = SPIN * t
        w = np.full(n, orbit) * (1 + 1e-3 * np.sin(g))  # an orbit speed that varies along the ticks
        for i in np.split(np.arange(n), [7, 507, 508, 1700]):
            counts = rig.stream.convert(g[i], t[i], phi[i], w[i], SPIN, orbit)
            out.append(rig.board.encode(int(g[i][0]), counts, t[i]))
        t0, g0 = float(t[-1]) + 1e-3, g0 + n
    return b"".join(out)


def _revolutions() -> np.ndarray:
    """sim.revolutions of the paper's rig, seed 3: ratios 0.4 and 1.5 forward, 0.8 backward, 0.4 again."""
    physics = RigPhysics(dataclasses.replace(scenario("paper"), seed=3))
    parts, t = [], 0.0
    for ratio, n in ((0.4, 5), (1.5, 7), (-0.8, 4), (0.4, 3)):
        slots, v = simulate_revolutions(physics, SPIN, ratio * SPIN, n, t0=t)
        parts.append(v.ravel())
        t += (n + 1) * 2 * math.pi / (abs(ratio) * SPIN)
    parts.append(slots.ravel().astype(float))
    return np.concatenate(parts)


@pytest.mark.parametrize("mode", ["sequential", "simultaneous"])
def test_a_seed_gives_the_a_d_board_the_same_bytes(mode):
    data = _stream(mode)
    assert len(data) > 12 * 360 * 2  # 12 revolutions of int16 samples at least
    assert hashlib.sha256(data).hexdigest() == STREAM[mode]


def test_a_seed_gives_sim_revolutions_the_same_values():
    values = _revolutions()
    assert values.size == (5 + 7 + 4 + 3) * 360 + 360 and np.all(np.isfinite(values))
    assert hashlib.sha256(values.tobytes()).hexdigest() == REVOLUTIONS


def test_a_slot_edges_value_is_the_same_bit_for_bit_whoever_is_converted_with_it():
    """A force channel's values (the housing resonance included) converted one slot edge at a time, in
    a block of 4000 and as a sparse slow-orbit handful: the same floats. Before, the resonance's
    envelope went through BLAS (zgemv), whose rounding depended on how many grid points it was
    given: values of one edge differed in their last bits between one call and another."""
    physics = RigPhysics(dataclasses.replace(scenario("paper"), seed=3))
    g = np.arange(5000, 9000)
    t = 0.37 + g * 1.3e-3  # s: 5.2 s, two of the envelope's tables
    theta, phi, w = (g % 360) * (2 * math.pi / 360), SPIN * t, np.full(g.size, 60.0)

    def values(i):
        return physics.channel_values(0, theta[i], t[i], phi[i], w[i], SPIN, 60.0, g[i])

    block = values(slice(None))
    single = np.concatenate([values(slice(i, i + 1)) for i in range(0, g.size, 97)])
    assert np.array_equal(single, block[::97])
    sparse = np.arange(0, g.size, 1000)
    assert np.array_equal(values(sparse), block[sparse])

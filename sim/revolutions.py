"""Whole revolutions of engineering samples straight from the physics (no transport).

For checks that need many revolutions fast (coherence, averaging): the same
signal path as the A/D board's conversions (chain, disturbances, slot-edge
jitter, speed ripple), sampled at the slot edges of a steady operating point,
without quantisation and framing.
"""

from __future__ import annotations

import math

import numpy as np

from sim.physics import RigPhysics

SLOTS = 360
SLOT_ANGLE = 2.0 * math.pi / SLOTS
#: simulated s of revolutions converted together (`_revolutions_per_chunk`): 8 of the resonance
#: envelope's 4.1 s tables, half of those a rig keeps (sim.disturbances.ENVELOPE_TABLES)
CHUNK_S = 32.0


def simulate_revolutions(
    physics: RigPhysics, spin: float, orbit: float, n: int, *, mode: str = "sequential", t0: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """(slots (C, S), values (n, C, S)) of n consecutive revolutions at spin, orbit (rad/s).

    Sequential scan: channel k is converted at slots k, k + C, ... (S = 360 / C);
    simultaneous: every channel at every slot (S = 360). Slot-edge times follow
    the orbit speed with the configured speed ripple, starting at t0 (s). The revolutions' random
    draws are keyed by their index: those after the ones this physics gave before
    (``physics.revolutions_drawn``), as one continuous run of the board would give them."""
    C = len(physics.channels)
    if mode == "sequential":
        slots = np.arange(SLOTS).reshape(-1, C).T  # (C, S)
    else:
        slots = np.tile(np.arange(SLOTS), (C, 1))
    first = physics.revolutions_drawn
    physics.revolutions_drawn += n
    g = np.arange(n * SLOTS)
    t_nominal = t0 + g * SLOT_ANGLE / abs(orbit)
    t = t0 + np.cumsum(np.r_[0.0, np.diff(t_nominal) / physics.ripple(t_nominal[:-1])])
    spin_angle = spin * (t - t0)
    t, spin_angle = t.reshape(n, SLOTS), spin_angle.reshape(n, SLOTS)
    theta = slots * SLOT_ANGLE
    values = np.empty((n, C, slots.shape[1]))
    revs = (first + np.arange(n))[:, None] * SLOTS  # global slot index of each revolution's slot 0
    per_chunk = _revolutions_per_chunk(t)
    for r0 in range(0, n, per_chunk):
        rows = slice(r0, min(n, r0 + per_chunk))
        m = rows.stop - r0
        orbit_inst = np.full(m * slots.shape[1], float(orbit))
        for k in range(C):
            cols = slice(k, None, C) if mode == "sequential" else slice(None)  # slots[k]
            values[rows, k, :] = physics.channel_values(
                k,
                np.tile(theta[k], m),
                t[rows, cols].ravel(),
                spin_angle[rows, cols].ravel(),
                orbit_inst,
                spin,
                orbit,
                (revs[rows] + slots[k]).ravel(),
            ).reshape(m, -1)
    return slots, values


def _revolutions_per_chunk(t: np.ndarray) -> int:
    """Revolutions converted together, every channel in turn: as many as span CHUNK_S of simulated
    time (one at least). The housing resonance's envelope tables of a chunk (4.1 s each, all force
    channels at once, sim.disturbances) stay cached while each channel takes them, and only a chunk's
    are gathered: at a slow orbit (10 rpm, 6 s a revolution) the revolutions of 100 minutes made each
    table once per force channel and gathered all of them per channel (11 times the CPU, 3 times the
    memory of the 1 s revolutions). A sample's value depends on its time alone, whoever is converted
    with it (tests/sim/test_sim_output_pinned.py): the chunks change no value."""
    n = t.shape[0]
    span = float(t[-1, -1] - t[0, 0]) if n else 0.0
    if not span > CHUNK_S:
        return max(n, 1)
    return max(1, int(CHUNK_S / (span / n)))


def revolution_phasors(slots: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Fundamental phasor of every revolution and channel, (n, C) complex:
    q_bar = (2 / S) sum_j q_j e^{-i theta_j} over a channel's S slots."""
    e = np.exp(-1j * slots * SLOT_ANGLE)  # (C, S)
    return 2.0 / slots.shape[1] * np.einsum("ncs,cs->nc", values, e)

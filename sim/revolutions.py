"""Whole revolutions of engineering samples straight from the physics (no transport).

For checks that need many revolutions fast (coherence, averaging): the same
signal path as the A/D board's conversions (chain, disturbances, slot-edge
jitter, speed ripple), sampled at the slot edges of a steady operating point,
without quantisation and framing.
"""

from __future__ import annotations

import math

import numpy as np

from sim.adc_board import channel_slots
from sim.disturbances import tabulated
from sim.physics import RigPhysics

SLOTS = 360
SLOT_ANGLE = 2.0 * math.pi / SLOTS
#: simulated s of revolutions converted together (`_revolutions_per_chunk`) when the resonance's envelope
#: comes from tables: 8 of its 4.1 s tables, half of those a rig keeps (sim.disturbances.ENVELOPE_TABLES)
CHUNK_S = 32.0


def simulate_revolutions(
    physics: RigPhysics, spin: float, orbit: float, n: int, *, mode: str = "sequential", t0: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """(slots (C, S), values (n, C, S)) of n consecutive revolutions at spin, orbit (rad/s).

    The channels' slots are `sim.adc_board.channel_slots`'s: sequential scan, S = 360 / C; simultaneous, S = 360.
    Slot-edge times follow the orbit speed with the configured speed ripple, starting at t0 (s). The
    revolutions' random draws are keyed by their index: those after the ones this physics gave before
    (``physics.revolutions_drawn``), as one continuous run of the board would give them."""
    scan = channel_slots(len(physics.channels), mode)
    slots = np.stack([np.arange(SLOTS)[cols] for cols in scan])  # (C, S)
    first = physics.revolutions_drawn
    physics.revolutions_drawn += n
    g = np.arange(n * SLOTS)
    t_nominal = t0 + g * SLOT_ANGLE / abs(orbit)
    t = t0 + np.cumsum(np.r_[0.0, np.diff(t_nominal) / physics.ripple(t_nominal[:-1])])
    spin_angle = spin * (t - t0)
    t, spin_angle = t.reshape(n, SLOTS), spin_angle.reshape(n, SLOTS)
    theta = slots * SLOT_ANGLE
    values = np.empty((n, *slots.shape))
    revs = (first + np.arange(n))[:, None] * SLOTS  # global slot index of each revolution's slot 0
    per_chunk = _revolutions_per_chunk(t, slots.shape[1])
    for r0 in range(0, n, per_chunk):
        rows = slice(r0, min(n, r0 + per_chunk))
        m = rows.stop - r0
        orbit_inst = np.full(m * slots.shape[1], float(orbit))
        for k, cols in enumerate(scan):  # t[:, cols] at slots[k]
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


def _revolutions_per_chunk(t: np.ndarray, samples: int) -> int:
    """Revolutions converted together, every channel in turn (`samples` a revolution each): all of
    them when a channel's samples are too sparse for the housing resonance's envelope tables
    (sim.disturbances.tabulated: its grid points alone are evaluated, at a slow orbit); else as many
    as span CHUNK_S of simulated time (one at least), so that a chunk's tables (4.1 s each, all force
    channels at once) stay cached while each channel takes them, and only a chunk's are gathered. A
    sample's value depends on its time alone, whoever is converted with it
    (tests/sim/test_sim_output_pinned.py): the chunks change no value."""
    n = t.shape[0]
    span = float(t[-1, -1] - t[0, 0]) if n else 0.0
    if not span > CHUNK_S or not tabulated(samples * n, span):
        return max(n, 1)
    return max(1, int(CHUNK_S / (span / n)))


def revolution_phasors(slots: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Fundamental phasor of every revolution and channel, (n, C) complex:
    q_bar = (2 / S) sum_j q_j e^{-i theta_j} over a channel's S slots."""
    e = np.exp(-1j * slots * SLOT_ANGLE)  # (C, S)
    return 2.0 / slots.shape[1] * np.einsum("ncs,cs->nc", values, e)

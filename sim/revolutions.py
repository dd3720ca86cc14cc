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
    orbit_inst = np.full(n * slots.shape[1], float(orbit))
    revs = (first + np.arange(n))[:, None] * SLOTS  # global slot index of each revolution's slot 0
    for k in range(C):
        cols = slice(k, None, C) if mode == "sequential" else slice(None)  # slots[k]
        values[:, k, :] = physics.channel_values(
            k,
            np.tile(theta[k], n),
            t[:, cols].ravel(),
            spin_angle[:, cols].ravel(),
            orbit_inst,
            spin,
            orbit,
            (revs + slots[k]).ravel(),
        ).reshape(n, -1)
    return slots, values


def revolution_phasors(slots: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Fundamental phasor of every revolution and channel, (n, C) complex:
    q_bar = (2 / S) sum_j q_j e^{-i theta_j} over a channel's S slots."""
    e = np.exp(-1j * slots * SLOT_ANGLE)  # (C, S)
    return 2.0 / slots.shape[1] * np.einsum("ncs,cs->nc", values, e)

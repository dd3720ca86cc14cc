"""The order of a matrix's operating points: the one that spends the least changeover time.

Between two points the operator changes the manual variables that differ (orbit radius,
static eccentricity, recess pressure, pressure ratio; rig.toml [changeover] states the
seconds each takes to change and settle, else every change costs [estimates]
manual_setting_s) and the spin drive ramps to the new speed. The first point is set up from
scratch ([estimates] manual_setting_s). A cheap heuristic orders the rest: nearest
neighbour from the written first point, then 2-opt reversals while they shorten the path;
the written order is kept when the heuristic does not beat it. A matrix with
`order = "written"` keeps its written order.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from orbitrig.config import RigConfig

if TYPE_CHECKING:
    from orbitrig.run.plan import OperatingPoint


def manual_change_s(rig: RigConfig, before: OperatingPoint | None, after: OperatingPoint) -> float:
    """Seconds of the manual settings going from point ``before`` (None: nothing set yet) to
    ``after`` (OperatingPoint.manual tuples are compared)."""
    if before is None:
        return rig.estimates.manual_setting_s
    per = rig.changeover.of() if rig.changeover is not None else (rig.estimates.manual_setting_s,) * 4
    return float(sum(t for t, a, b in zip(per, before.manual, after.manual) if a != b))


#: the orbit radius's place in OperatingPoint.manual (its change stops the drives: orbitrig.run.plan)
RADIUS = 0


def _costs(rig: RigConfig, points: Sequence[OperatingPoint]) -> np.ndarray:
    """(n, n) seconds from point i to point j: manual changes + the spin ramp (down to standstill
    and up again where the orbit radius changes: orbitrig.run.plan)."""
    per = np.array(rig.changeover.of() if rig.changeover is not None else (rig.estimates.manual_setting_s,) * 4)
    manual = np.array([p.manual for p in points], dtype=float).reshape(len(points), 4)
    spin = np.array([p.spin for p in points], dtype=float)
    changed = manual[:, None, :] != manual[None, :, :]
    ramp = np.where(changed[:, :, RADIUS], spin[:, None] + spin[None, :], np.abs(spin[:, None] - spin[None, :]))
    costs: np.ndarray = changed.astype(float) @ per + ramp / rig.ramp_rate
    return costs


def changeover_s(rig: RigConfig, points: Sequence[OperatingPoint], order: Sequence[int]) -> float:
    """Total seconds of manual settings and spin ramps between points, visited in ``order``
    (indices into ``points``), the first point's set-up included."""
    if not order:
        return 0.0
    c = _costs(rig, points)
    first = points[order[0]]
    return float(
        manual_change_s(rig, None, first)
        + first.spin / rig.ramp_rate
        + sum(c[a, b] for a, b in zip(order[:-1], order[1:]))
    )


def _path(c: np.ndarray, order: list[int]) -> float:
    return float(sum(c[a, b] for a, b in zip(order[:-1], order[1:])))


def _nearest(c: np.ndarray) -> list[int]:
    order, left = [0], set(range(1, c.shape[0]))
    while left:
        here = order[-1]
        nxt = min(left, key=lambda j: (c[here, j], j))  # ties: the written order
        order.append(nxt)
        left.remove(nxt)
    return order


def _two_opt(c: np.ndarray, order: list[int]) -> list[int]:
    """Reverse a stretch (the first point stays first) while that shortens the path; the
    costs are symmetric, so only the two edges at the stretch's ends change."""
    n = len(order)
    improved = True
    while improved:
        improved = False
        for i in range(1, n - 1):
            for j in range(i + 1, n):
                a, b, d = order[i - 1], order[i], order[j]
                e = order[j + 1] if j + 1 < n else None
                old = c[a, b] + (c[d, e] if e is not None else 0.0)
                new = c[a, d] + (c[b, e] if e is not None else 0.0)
                if new < old - 1e-9:
                    order = order[:i] + order[i : j + 1][::-1] + order[j + 1 :]
                    improved = True
    return order


def fastest_order(rig: RigConfig, points: Sequence[OperatingPoint]) -> list[int]:
    """Indices into ``points`` (written order) in the order that spends the least changeover
    time by the heuristic of the module doc; the written order when it is as fast."""
    n = len(points)
    if n < 3:
        return list(range(n))
    c = _costs(rig, points)
    order = _nearest(c)
    order = _two_opt(c, order)
    written = list(range(n))
    return order if _path(c, order) < _path(c, written) - 1e-9 else written

"""Is each displacement direction's excitation clear of its noise? (orbit-table contract v3)

A row's orbit is the ellipse traced by (Re(x e^{i t}), Re(y e^{i t})); its real shape matrix
[[Re x, -Im x], [Re y, -Im y]] has the semi-axes as singular values. Stacking the rows of a
group side by side gives the group's orbit-shape matrix S (2 x 2 rows): its major singular
value is the excitation along the orbits' main axis, its minor one the excitation across it
(zero for line orbits, the radius times sqrt(2 rows) for circles). Identifiability on the
design alone cannot tell a real excitation from noise: a line orbit whose other axis carries
only probe noise splits, row by row, into "forward" and "backward" whirl with their own
noise-made shapes, and column scaling hides how small they are.

So each group - the forward whirl rows, the backward whirl rows, and the whole table - is
judged on signal: the noise energy along a unit direction v of the plane is
sum_k (v_x^2 u_x,k^2 + v_y^2 u_y,k^2) (u the standard uncertainty sqrt(E|e|^2) of each
averaged displacement phasor), and the excitation ratio is the singular value over the
square root of that energy (about 1 for pure noise). A direction below ``CLEAR_REFUSE``
carries no shape: it is taken out of the design the rank is judged on (a group's minor axis
projected away, a group with no clear major axis dropped), and the model is refused when
the rest cannot identify it. Below ``CLEAR_WARN`` the fit is made and warned.

The noise u_x, u_y: the table's u_* columns, else the residual's equivalent displacement
noise (the residual as if it all came from the displacements through Z); never below
``CROSS_TALK`` of the row's own orbit size (probe cross-talk and linearity: a sub-percent
motion across the main axis is not a designed excitation). Everything SI, no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from reduction.arrays import ComplexArray, FloatArray
from reduction.table import OrbitTable

CLEAR_REFUSE = 3.0  # excitation below 3 x its noise: no shape (left out of the design)
CLEAR_WARN = 10.0  # below 10 x its noise: fitted and warned
CROSS_TALK = 0.005  # displacement noise counted as at least 0.5 % of the row's orbit size


@dataclass(frozen=True)
class GroupSignal:
    """One group's excitation ratios (singular value / noise, dimensionless) and its main
    axis (unit real 2-vector in the x-y plane)."""

    group: str
    rows: int
    major: float
    minor: float
    axis: np.ndarray


@dataclass(frozen=True)
class SignalDesign:
    """The displacements the rank is judged on (noise-made directions removed), the groups'
    ratios, and the reasons (empty when every direction is clear)."""

    x: np.ndarray
    y: np.ndarray
    groups: list[GroupSignal]
    removed: list[str]
    weak: list[str]

    @property
    def changed(self) -> bool:
        return bool(self.removed)


def displacement_noise(
    table: OrbitTable, residual: np.ndarray | None = None, Z: np.ndarray | None = None, dof: int = 0
) -> np.ndarray:
    """(n, 2) noise u_x, u_y (m) of each row's displacement phasors: the table's u_* columns,
    else the equivalent displacement noise of the real residual (4n,) through Z (n, 2, 2):
    u_d^2 = 2 s^2 / ||Z_k||_F^2 per component, s^2 = RSS / dof per real equation; never
    below ``CROSS_TALK`` times the row's orbit size sqrt(|x|^2 + |y|^2)."""
    size = np.sqrt(np.abs(table.x) ** 2 + np.abs(table.y) ** 2)
    floor = np.repeat((CROSS_TALK * size)[:, None], 2, axis=1)
    if table.u is not None:
        measured: FloatArray = np.maximum(table.u[:, :2], floor)
        return measured
    if residual is None or Z is None or dof <= 0:
        return floor
    s2 = float(residual @ residual) / dof
    zf2 = np.sum(np.abs(Z) ** 2, axis=(1, 2))
    u = np.sqrt(np.where(zf2 > 0, 2 * s2 / np.where(zf2 > 0, zf2, 1.0), 0.0))
    equivalent: FloatArray = np.maximum(u[:, None], floor)
    return equivalent


def excitation_ratios(x: ArrayLike, y: ArrayLike, u: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(major, minor, axis): the singular values of the orbit-shape matrix of rows x, y (m,
    last axis) over the square root of the noise energy along their directions (u (..., n, 2)
    the rows' u_x, u_y), and the main axis (..., 2). Leading axes are a batch of tables."""
    xc, yc = np.asarray(x, dtype=complex), np.asarray(y, dtype=complex)
    xy = np.sum((xc * np.conj(yc)).real, axis=-1)
    gram = np.stack(
        [np.stack([np.sum(np.abs(xc) ** 2, axis=-1), xy], -1), np.stack([xy, np.sum(np.abs(yc) ** 2, axis=-1)], -1)], -2
    )  # S S^T, (..., 2, 2)
    s2, U = np.linalg.eigh(gram)  # ascending: minor first
    energy = np.einsum("...ij,...i->...j", U**2, np.sum(np.asarray(u, dtype=float) ** 2, axis=-2))
    s = np.sqrt(np.clip(s2, 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio: FloatArray = np.where(energy > 0, s / np.sqrt(np.where(energy > 0, energy, 1.0)), np.inf)
    ratio = np.where(s > 0, ratio, 0.0)
    axis: FloatArray = U[..., :, 1]
    return ratio[..., 1], ratio[..., 0], axis


def _judge(name: str, x: ComplexArray, y: ComplexArray, u: FloatArray) -> GroupSignal:
    major, minor, axis = excitation_ratios(x, y, u)
    return GroupSignal(name, x.size, float(major), float(minor), axis)


def _project(x: ComplexArray, y: ComplexArray, axis: FloatArray) -> tuple[ComplexArray, ComplexArray]:
    """Rows projected onto the real axis (the orbit flattened to a line along it)."""
    along: ComplexArray = axis[0] * x + axis[1] * y
    return axis[0] * along, axis[1] * along


def signal_design(table: OrbitTable, noise: np.ndarray) -> SignalDesign:
    """The table's displacements with every direction not clear of ``noise`` (n, 2) removed:
    per whirl direction first, then over the table (see the module docstring)."""
    x, y = table.x.copy(), table.y.copy()
    forward = table.forward()
    groups, removed, weak = [], [], []
    for direction, name in ((True, "forward whirl rows"), (False, "backward whirl rows")):
        rows = np.flatnonzero(forward == direction)
        if rows.size == 0:
            continue
        g = _judge(name, x[rows], y[rows], noise[rows])
        groups.append(g)
        if g.major < CLEAR_REFUSE:
            x[rows], y[rows] = 0, 0
            removed.append(f"the {name} ({g.rows}): excitation {g.major:.2g} times its noise")
        elif g.minor < CLEAR_REFUSE:
            x[rows], y[rows] = _project(x[rows], y[rows], g.axis)
            removed.append(
                f"the {name} ({g.rows}): excitation across the orbits' main axis "
                f"({_angle(g.axis)}) {g.minor:.2g} times its noise"
            )
        elif g.minor < CLEAR_WARN:
            weak.append(f"the {name} ({g.rows}): excitation across the main axis {g.minor:.2g} times its noise")
    g = _judge("table", table.x, table.y, noise)
    groups.append(g)
    if g.major >= CLEAR_REFUSE and g.minor < CLEAR_REFUSE:
        x, y = _project(x, y, g.axis)
        if not removed:
            removed.append(
                f"the whole table ({g.rows} rows): excitation across the orbits' main axis "
                f"({_angle(g.axis)}) {g.minor:.2g} times its noise"
            )
    elif CLEAR_REFUSE <= g.minor < CLEAR_WARN and not weak:
        weak.append(f"the whole table: excitation across the main axis {g.minor:.2g} times its noise")
    return SignalDesign(x, y, groups, removed, weak)


def _angle(axis: FloatArray) -> str:
    deg = round(float(np.degrees(np.arctan2(axis[1], axis[0])))) % 180
    return f"main axis at {deg} deg from x"


def signal_warning(design: SignalDesign) -> str | None:
    """The warning for directions that are weak (below ``CLEAR_WARN``) or were left out
    without making the model unidentifiable, or None."""
    parts = design.removed + design.weak
    if not parts:
        return None
    return (
        "weak excitation: the displacement is not clear of its noise in "
        + "; ".join(parts)
        + f" (orbitrig wants at least {CLEAR_WARN:g} times; u_x, u_y, else the residual's equivalent). "
        "The coefficients this direction drives are poorly determined; a larger orbit in that "
        "direction (forward and backward circles) would determine them."
    )

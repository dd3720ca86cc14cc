"""Designs of orbit tables: the idealised design that identifiability is judged on, the
ideal two-direction reference design, and the predicted (Cramer-Rao) covariance of a design.

A design is what the rig imposes, not what the noise adds: the orbit frequencies and, per
row, the orbit's shape. The shape of an orbit (x, y) is its unit-norm phasor pair with the
phase of its dominant whirl component removed, so that orbits that differ only in size and
trigger phase have one shape. The rank of the regression does not depend on a row's size
or phase (a complex factor on a row mixes that row's Re/Im equations invertibly).

:func:`idealised_design`: each whirl direction's orbits are replaced by that direction's
common shape - the mean shape (a circle when its minor whirl component is below
``CIRCLE_TOL`` of the major, else the mean ellipse) - unless that direction's shapes differ deliberately (any shape farther than
``SHAPE_SPREAD`` from the mean), when they keep their own shapes. A fixed ellipse separates
nothing a circle cannot: with one shape s, the data give Z(Omega) s only, a complex
2-vector, 4 real numbers per power of Omega.

:func:`reference_design`: both whirl directions as unit circles at every distinct frequency
of the table - the best the same frequencies can do; its condition number is the yardstick
of the ill-conditioning warning.

:func:`yardstick_design`: the table's whirl directions as unit circles at evenly spread
frequencies up to the table's highest - the absolute yardstick of variance inflation (v3).

:func:`predicted_covariance`: the Cramer-Rao bound of the coefficients for a design, known
displacements with per-channel noise and force noise; with displacement noise it uses the
effective variance at the given coefficients (first order in the displacement noise). A
design that cannot identify the model is refused by the rank rule identification refuses a
table by (:func:`reduction.rank.determined_rank` on the column-scaled weighted regression).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from reduction.arrays import BoolArray, ComplexArray, FloatArray
from reduction.errors import ReductionError
from reduction.impedance import impedance, real_rows, regressors
from reduction.information import unidentifiable
from reduction.models import ModelSpec
from reduction.noise import equation_variances
from reduction.rank import Rank
from reduction.table import OrbitTable
from reduction.whirl import Directions
from rigunits import HZ

SHAPE_SPREAD = 0.2  # a direction's shapes farther apart than this (unit-norm distance) are kept apart
CIRCLE_TOL = 0.05  # a mean shape whose minor whirl component is below 5 % of the major is a circle
YARDSTICK_SPAN = 6.0  # the yardstick design spans highest / 6 .. highest orbit frequency
YARDSTICK_MAX = 64  # at most this many frequencies in the yardstick design
REFERENCE_MAX = 4096  # the same-frequency reference of a long table uses this many of its frequencies


def orbit_shapes(x: ArrayLike, y: ArrayLike) -> tuple[BoolArray, ComplexArray]:
    """(forward (n,) bool, shapes (n, 2) complex): each orbit's unit-norm (x, y) with the
    phase of its dominant whirl component removed; a zero orbit has shape (0, 0)."""
    xc, yc = np.asarray(x, dtype=complex), np.asarray(y, dtype=complex)
    v = np.stack([xc, yc], axis=1)
    a_f, a_b = (xc + 1j * yc) / 2, (xc - 1j * yc) / 2
    forward: BoolArray = np.imag(np.conj(xc) * yc) < 0
    dom = np.where(forward, a_f, a_b)
    size = np.linalg.norm(v, axis=1)
    ok = (size > 0) & (np.abs(dom) > 0)
    phase = np.where(ok, dom / np.where(ok, np.abs(dom), 1.0), 1.0)
    shapes: ComplexArray = np.where(ok[:, None], v / (np.where(ok, size, 1.0) * phase)[:, None], 0.0)
    return forward, shapes


def idealised_design(table: OrbitTable, spread: float = SHAPE_SPREAD) -> tuple[np.ndarray, np.ndarray, bool]:
    """(x, y, fixed): the table's rows with each whirl direction's orbits replaced by that
    direction's common shape; ``fixed`` is True when every present direction has one shape."""
    forward, shapes = orbit_shapes(table.x, table.y)
    ideal = shapes.copy()
    fixed = True
    for direction in (True, False):
        rows = np.flatnonzero(forward == direction)
        if rows.size == 0:
            continue
        mean = np.mean(shapes[rows], axis=0)
        norm = np.linalg.norm(mean)
        if norm == 0:
            fixed = False
            continue
        mean = mean / norm
        minor = abs(mean[0] - 1j * mean[1]) if direction else abs(mean[0] + 1j * mean[1])
        if minor < CIRCLE_TOL * abs(mean[0] + 1j * mean[1] if direction else mean[0] - 1j * mean[1]):
            mean = np.array([1.0, -1j if direction else 1j]) / np.sqrt(2)
        if np.max(np.linalg.norm(shapes[rows] - mean, axis=1)) > spread:
            fixed = False  # deliberately different shapes: keep them
            continue
        ideal[rows] = mean
    return ideal[:, 0], ideal[:, 1], fixed


def reference_design(orbit: ArrayLike) -> tuple[FloatArray, ComplexArray, ComplexArray]:
    """(orbit, x, y): forward and backward unit circles at every distinct frequency (a long
    table's: at ``REFERENCE_MAX`` of them, evenly picked in order)."""
    w = np.unique(np.asarray(orbit, dtype=float))
    if w.size > REFERENCE_MAX:
        w = w[np.round(np.linspace(0, w.size - 1, REFERENCE_MAX)).astype(int)]
    w2 = np.repeat(w, 2)
    x = np.ones(w2.size, dtype=complex)
    y = np.tile([-1j, 1j], w.size)
    return w2, x, y


def yardstick_design(
    orbit: ArrayLike, min_frequencies: int, directions: Directions = Directions.BOTH
) -> tuple[FloatArray, ComplexArray, ComplexArray]:
    """(orbit, x, y): unit circles in ``directions`` (the whirl directions the table has) at
    as many frequencies as the table has distinct ones
    (at least ``min_frequencies``, at most ``YARDSTICK_MAX``), spread evenly from
    1/``YARDSTICK_SPAN`` of the table's highest orbit frequency to it - the paper's
    0.2..1.2 x spin. The absolute yardstick of variance inflation: it does not share the
    table's frequencies, so near-coincident ones cannot hide behind it."""
    w = np.asarray(orbit, dtype=float)
    count = int(np.clip(np.unique(w).size, max(min_frequencies, 1), YARDSTICK_MAX))
    top = float(np.max(w))
    return design_orbits(np.linspace(top / YARDSTICK_SPAN, top, count) / HZ, directions, 1.0)


def design_orbits(
    orbit_hz: ArrayLike, directions: Directions | Sequence[Directions], radius: float
) -> tuple[FloatArray, ComplexArray, ComplexArray]:
    """(orbit rad/s, x, y m) of circular orbits of ``radius`` (m) at ``orbit_hz`` (Hz), one
    row per (frequency, direction), forward first; ``directions`` one for all frequencies or
    one per frequency (forward whirl: y = -i x)."""
    hz = np.atleast_1d(np.asarray(orbit_hz, dtype=float))
    given = [directions] * hz.size if isinstance(directions, str) else list(directions)
    if len(given) != hz.size:
        raise ReductionError("design_orbits: one direction per frequency, or one for all")
    try:
        dirs = [Directions(d) for d in given]
    except ValueError as err:
        raise ReductionError(f"design_orbits: {err}") from err
    w: list[float] = []
    y: list[complex] = []
    for f, d in zip(hz, dirs):
        for whirl in d.whirls:
            w.append(HZ * f)
            y.append(-1j * whirl.sign * radius)
    return np.array(w), np.full(len(w), complex(radius)), np.array(y)


def predicted_covariance(
    spec: ModelSpec,
    orbit: ArrayLike,
    x: ArrayLike,
    y: ArrayLike,
    u: ArrayLike,
    theta: ArrayLike | None = None,
    what: str = "the design",
) -> FloatArray:
    """Cramer-Rao bound (p, p) of the free coefficients (SI, column order of ``spec``) for a
    design: orbit (rad/s), x, y (m) per row, u the standard uncertainties sqrt(E|err|^2) of
    the averaged phasors x, y (m), fx, fy (N) - (n, 4) or (4,) for every row. theta (the
    coefficients at which displacement noise is propagated through Z) may be omitted when
    u_x = u_y = 0. Raises ReductionError on missing noise or fewer equations than coefficients,
    IdentifiabilityError (``what`` - the design in words - and the coefficients it leaves
    undetermined) when :func:`reduction.rank.determined_rank` of the design is below the
    number of coefficients."""
    w = np.asarray(orbit, dtype=float)
    noise = np.broadcast_to(np.asarray(u, dtype=float), (w.size, 4))
    if theta is None:
        if np.any(noise[:, :2] > 0):
            raise ReductionError("predicted_covariance: displacement noise needs the coefficients theta")
        theta = np.zeros(spec.n_coefficients)
    A = real_rows(regressors(spec, w, x, y))
    var = equation_variances(noise, impedance(spec, theta, w))
    if np.any(var <= 0):
        raise ReductionError("predicted_covariance: every equation needs a noise > 0")
    if A.shape[0] < A.shape[1]:
        raise ReductionError(
            f"predicted_covariance: {A.shape[0]} real equations cannot identify "
            f"{A.shape[1]} coefficients (need at least {-(-A.shape[1] // 4)} orbit frequencies)"
        )
    Aw = A / np.sqrt(var)[:, None]
    c = np.linalg.norm(Aw, axis=0)
    c = np.where(c > 0, c, 1.0)
    _, s, Vt = np.linalg.svd(Aw / c, full_matrices=False)
    rank = Rank.of(s, Vt, c)
    if rank.deficiency:
        raise unidentifiable(rank, spec, what)
    cov_s = (Vt.T / s**2) @ Vt
    cov: FloatArray = cov_s / np.outer(c, c)
    return cov

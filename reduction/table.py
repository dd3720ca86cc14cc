"""The orbit table: one row per orbit frequency at one operating point.

Units are SI inside (rad/s, m, N). Phasor convention q(t) = Re(q_bar e^{i Omega t});
the force is the fluid-film force ON THE JOURNAL, f_bar = -Z(Omega) d_bar.
Forward whirl of radius R: x_bar = R, y_bar = -i R; backward: x_bar = R, y_bar = +i R.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from reduction.columns import GAMMA2_COLUMNS, U_COLUMNS
from reduction.errors import ReductionError
from reduction.whirl import whirl_sense
from rigunits import in_hz


def _complex_1d(name: str, value: ArrayLike, n: int | None) -> np.ndarray:
    arr = np.asarray(value, dtype=complex)
    if arr.ndim != 1:
        raise ReductionError(f"OrbitTable.{name} must be one-dimensional, got shape {arr.shape}")
    if n is not None and arr.shape[0] != n:
        raise ReductionError(f"OrbitTable.{name} has {arr.shape[0]} rows, orbit has {n}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise ReductionError(f"OrbitTable.{name} is not finite at row index {bad[0]}: {complex(arr[bad[0]])}")
    return arr


def _first_bad(name: str, arr: np.ndarray, ok: np.ndarray, columns: tuple[str, ...], rule: str) -> None:
    """ReductionError naming the first (row, column) of ``arr`` (n, 4) where ``ok`` is False."""
    bad = np.argwhere(~ok)
    if bad.size:
        i, j = bad[0]
        raise ReductionError(f"OrbitTable.{name} at row index {i}, column {columns[j]}: {float(arr[i, j])} {rule}")


@dataclass(frozen=True, eq=False)
class OrbitTable:
    """Measured phasors of one operating point (validated, SI).

    spin   : journal spin speed omega, rad/s (>= 0)
    orbit  : (n,) orbit frequencies Omega, rad/s, > 0 (the whirl direction lives in the phasors)
    x, y   : (n,) complex displacement phasors, m
    fx, fy : (n,) complex force phasors, N (force on the journal)
    gamma2 : optional (n, 4) coherences in [0, 1], columns xfx, yfx, xfy, yfy
    n_records : optional (n,) number of revolutions (records) behind each row, >= 1
    u      : optional (n, 4) standard uncertainties sqrt(E|error|^2) of the averaged complex
             phasors x, y (m), fx, fy (N), >= 0 (columns ``U_COLUMNS``)
    """

    spin: float
    orbit: np.ndarray
    x: np.ndarray
    y: np.ndarray
    fx: np.ndarray
    fy: np.ndarray
    gamma2: np.ndarray | None = None
    n_records: np.ndarray | None = None
    u: np.ndarray | None = None

    def __post_init__(self) -> None:
        spin = float(self.spin)
        if not np.isfinite(spin) or spin < 0:
            raise ReductionError(f"OrbitTable.spin must be finite and >= 0 rad/s, got {self.spin!r}")
        orbit = np.asarray(self.orbit, dtype=float)
        if orbit.ndim != 1 or orbit.size == 0:
            raise ReductionError(f"OrbitTable.orbit must be a non-empty 1-D array, got shape {orbit.shape}")
        if not np.all(np.isfinite(orbit)) or np.any(orbit <= 0):
            raise ReductionError("OrbitTable.orbit must be finite and > 0 rad/s on every row")
        n = orbit.shape[0]
        object.__setattr__(self, "spin", spin)
        object.__setattr__(self, "orbit", orbit)
        for name in ("x", "y", "fx", "fy"):
            object.__setattr__(self, name, _complex_1d(name, getattr(self, name), n))
        if self.gamma2 is not None:
            g = np.asarray(self.gamma2, dtype=float)
            if g.shape != (n, 4):
                raise ReductionError(f"OrbitTable.gamma2 must have shape ({n}, 4), got {g.shape}")
            with np.errstate(invalid="ignore"):
                _first_bad("gamma2", g, (g >= 0) & (g <= 1), GAMMA2_COLUMNS, "is not in [0, 1]")
            object.__setattr__(self, "gamma2", g)
        if self.n_records is not None:
            r = np.asarray(self.n_records, dtype=float)
            if r.shape != (n,) or not np.all(np.isfinite(r)) or np.any(r < 1) or np.any(r != np.round(r)):
                raise ReductionError(f"OrbitTable.n_records must be ({n},) whole numbers >= 1")
            object.__setattr__(self, "n_records", r)
        if self.u is not None:
            u = np.asarray(self.u, dtype=float)
            if u.shape != (n, 4):
                raise ReductionError(f"OrbitTable.u must have shape ({n}, 4), got {u.shape}")
            with np.errstate(invalid="ignore"):
                _first_bad("u", u, np.isfinite(u) & (u >= 0), U_COLUMNS, "is not finite and >= 0")
            object.__setattr__(self, "u", u)
        for arr in (self.orbit, self.x, self.y, self.fx, self.fy, self.gamma2, self.n_records, self.u):
            if arr is not None:
                arr.flags.writeable = False

    @property
    def phasors(self) -> dict[str, np.ndarray]:
        """The four phasor columns by name, in ``U_COLUMNS`` order: x, y (m), fx, fy (N)."""
        return {"x": self.x, "y": self.y, "fx": self.fx, "fy": self.fy}

    @property
    def n(self) -> int:
        """Number of rows (orbit frequencies)."""
        return int(self.orbit.shape[0])

    @property
    def orbit_hz(self) -> np.ndarray:
        """Orbit frequencies Omega / (2 pi), Hz (rigunits.in_hz: to 1 nHz, no float noise)."""
        return in_hz(self.orbit)

    def whirl_components(self) -> tuple[np.ndarray, np.ndarray]:
        """Forward and backward circular components (a_f, a_b), m, of each orbit.

        x = a_f + a_b, y = -i a_f + i a_b: a forward circle of radius R has a_f = R, a_b = 0.
        """
        return (self.x + 1j * self.y) / 2, (self.x - 1j * self.y) / 2

    def forward(self) -> np.ndarray:
        """(n,) bool: the row's orbit turns from +x towards +y (whirl_sense > 0)."""
        fwd: np.ndarray = whirl_sense(self.x, self.y) > 0
        return fwd

    def subset(self, rows: np.ndarray | slice) -> OrbitTable:
        """A table of the selected rows (index array or boolean mask)."""

        def pick(a: np.ndarray | None) -> np.ndarray | None:
            return None if a is None else a[rows]

        return OrbitTable(
            self.spin,
            self.orbit[rows],
            self.x[rows],
            self.y[rows],
            self.fx[rows],
            self.fy[rows],
            pick(self.gamma2),
            pick(self.n_records),
            pick(self.u),
        )

    def with_phasors(self, x: np.ndarray, y: np.ndarray, fx: np.ndarray, fy: np.ndarray) -> OrbitTable:
        """The same table (frequencies, coherences, uncertainties) with other phasors."""
        return OrbitTable(self.spin, self.orbit, x, y, fx, fy, self.gamma2, self.n_records, self.u)

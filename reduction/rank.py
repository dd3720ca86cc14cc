"""Numerical rank of a regression after column scaling, from its R factor; the one rule of
whether a list of orbit frequencies identifies a model (:func:`determined_rank`).

The regression A theta = b is column-scaled to unit column norms; its numerical rank is the
number of singular values above ``rtol * sigma_max``. The singular values and right
singular vectors are those of the R factor of a blocked QR (:func:`reduction.regression.
triangular`), so a long table costs passes over its rows and one block of memory.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from reduction.arrays import FloatArray
from reduction.impedance import regression_rows
from reduction.memo import DESIGN_MEMO_ROWS, DesignMemo
from reduction.models import ModelSpec
from reduction.regression import CHUNK_ROWS, LONG_TABLE, triangular, triangular_blocks

RANK_RTOL = 1e-7  # relative singular-value tolerance on the column-scaled regression (cond > 1e7 = deficient)


@dataclass(frozen=True)
class Rank:
    """Numerical rank of a column-scaled regression and its null space (scaled coordinates)."""

    rank: int
    n_columns: int
    singular_values: np.ndarray
    null: np.ndarray  # (p, p - rank), orthonormal, scaled coordinates
    scale: np.ndarray  # column norms c: theta = u / c
    vt: np.ndarray  # (p, p) right singular vectors (rows), scaled coordinates

    @classmethod
    def of(cls, singular_values: np.ndarray, vt: np.ndarray, scale: np.ndarray, rtol: float = RANK_RTOL) -> "Rank":
        """The Rank of a column-scaled regression (column norms ``scale``) from its singular values
        (descending) and right singular vectors ``vt`` (rows): :func:`determined_rank` of them, the
        rows of ``vt`` past it its null space."""
        rank = determined_rank(singular_values, rtol)
        return cls(rank, vt.shape[1], singular_values, vt[rank:].T.copy(), scale, vt)

    def unscaled_covariance(self) -> np.ndarray:
        """(A_s^T A_s)^-1 of the column-scaled matrix (full rank only)."""
        s = self.singular_values
        cov: np.ndarray = (self.vt.T / s**2) @ self.vt
        return cov

    @property
    def deficiency(self) -> int:
        return self.n_columns - self.rank

    @property
    def condition_number(self) -> float:
        s = self.singular_values
        return float(s[0] / s[-1]) if s.size and s[-1] > 0 else float("inf")


def determined_rank(singular_values: ArrayLike, rtol: float = RANK_RTOL) -> int:
    """How many directions of coefficient space a regression determines: the count of the
    singular values of the column-scaled regression (unit column norms; row-weighted when the
    fit or the prediction weighs its equations) above ``rtol`` x the largest, 0 when the
    largest is 0. The regression identifies the model when this is its number of columns.

    The one rule (``RANK_RTOL`` = 1e-7: a condition number above 1e7 is rank-deficient) of
    :func:`reduction.identify.identify` (:func:`numerical_rank`, :func:`design_rank`), of the
    predicted covariance of a design (:func:`reduction.design.predicted_covariance`, hence
    :func:`reduction.frequency_list.predict`) and of a list's Fisher information
    (:mod:`reduction.information`, hence the allocation and the sequential design): for an
    information I = A^T A scaled to unit diagonal the singular values are the square roots
    of its eigenvalues, so an eigenvalue at or below ``rtol``^2 = 1e-14 of the largest is null."""
    s = np.asarray(singular_values, dtype=float)
    top = float(s.max(initial=0.0))
    if not top > 0:
        return 0
    return int(np.count_nonzero(s > rtol * top))


_DESIGN_RANKS: DesignMemo[Rank] = DesignMemo(32)  # design_rank's


def numerical_rank(A: np.ndarray, rtol: float = RANK_RTOL) -> Rank:
    """Rank of A after column scaling: singular values > rtol * sigma_max count. The
    singular values and right vectors come from the R factor of the blocked QR (those of A
    itself), so a long table costs passes over its rows and one block of memory."""
    A = np.asarray(A, dtype=float)
    return _rank_of(triangular(A)[0], A.shape[0], rtol)


def design_rank(spec: ModelSpec, orbit: ArrayLike, x: ArrayLike, y: ArrayLike, rtol: float = RANK_RTOL) -> Rank:
    """:func:`numerical_rank` of the regression of orbits (orbit rad/s, x, y m), its rows
    built block by block: a long table's design is never whole in memory. The Rank of a
    design of up to ``DESIGN_MEMO_ROWS`` orbits is memoised (read-only arrays): every table
    of a sweep or Monte Carlo on one design has the same idealised, reference and yardstick
    designs (:mod:`reduction.identifiability`)."""
    orbit = np.asarray(orbit, dtype=float)
    if orbit.size > DESIGN_MEMO_ROWS:
        return _design_rank(spec, orbit, x, y, rtol)
    xc, yc = np.asarray(x, dtype=complex), np.asarray(y, dtype=complex)
    key = (spec.terms, float(rtol), orbit.tobytes(), xc.tobytes(), yc.tobytes())
    return _DESIGN_RANKS.get(key, lambda: _read_only(_design_rank(spec, orbit, x, y, rtol)))


def _read_only(rank: Rank) -> Rank:
    """``rank`` with its arrays made read-only (it is shared from the memo)."""
    for array in (rank.singular_values, rank.null, rank.scale, rank.vt):
        array.flags.writeable = False
    return rank


def _design_rank(spec: ModelSpec, orbit: FloatArray, x: ArrayLike, y: ArrayLike, rtol: float) -> Rank:
    """:func:`design_rank` computed (no cache)."""
    n = orbit.size
    x, y = np.asarray(x), np.asarray(y)
    if 4 * n <= LONG_TABLE:
        return numerical_rank(regression_rows(spec, orbit, x, y), rtol)
    step = CHUNK_ROWS // 4

    def blocks() -> Iterator[np.ndarray]:
        for s in range(0, n, step):
            yield regression_rows(spec, orbit[s : s + step], x[s : s + step], y[s : s + step])

    return _rank_of(triangular_blocks(blocks, 4 * n, spec.n_coefficients), 4 * n, rtol)


def _rank_of(R: np.ndarray, m: int, rtol: float) -> Rank:
    """The Rank of a matrix of m rows from its R factor (column norms = those of R's columns)."""
    p = R.shape[1]
    c = np.linalg.norm(R, axis=0)
    c = np.where(c > 0, c, 1.0)
    R = R / c
    if R.shape[0] < p:  # pad so that the SVD returns the whole right singular basis
        R = np.vstack([R, np.zeros((p - R.shape[0], p))])
    _, s, Vt = np.linalg.svd(R)
    s = s if m >= p else np.concatenate([s[:m], np.zeros(p - m)])
    return Rank.of(s, Vt, c, rtol)

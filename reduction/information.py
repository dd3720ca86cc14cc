"""Predicted standard errors of a list's Fisher information, and the one test of whether it
identifies the model.

A list of blocks (orbit ratio, whirl directions, n_k revolutions) has the Fisher information
I = sum_k n_k F_k (p, p), F_k the information of one revolution
(:func:`reduction.allocation.revolution_information`), in 1/SI^2 of the coefficients. Its
Cramer-Rao standard errors are sqrt(diag(I^-1)), SI in the column order of I.

The list cannot identify a coefficient when the coefficient has a component along a null
direction of I: scaled to unit diagonal (the regression's column scaling: I = A^T A, so an
eigenvalue is a singular value of the column-scaled A squared), an eigenvalue at most
``RANK_RTOL``^2 of the largest - :func:`reduction.rank.determined_rank`, the rank test
:mod:`reduction.identifiability` refuses a table by - or a coefficient without any
information. Such a coefficient's error is np.inf (:func:`predicted_errors`: a search ranks
the list last); a list a user gave is refused by name (:func:`identified_errors`, its
refusal :func:`unidentifiable`). Pure numerics.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from reduction.arrays import BoolArray, FloatArray
from reduction.errors import IdentifiabilityError
from reduction.models import ModelSpec
from reduction.rank import Rank
from reduction.refusal import combinations

NULL_SHARE = 1e-6  # a coefficient with more than this share (unit-norm) of a null direction is undetermined


def _spectrum(information: FloatArray) -> tuple[Rank, BoolArray]:
    """(the Rank of the column-scaled regression whose Gram matrix is ``information``, which
    coefficients have a share of its null space)."""
    d = np.diag(information).copy()
    c = np.sqrt(np.where(d > 0, d, 1.0))
    lam, V = np.linalg.eigh(information / np.outer(c, c))
    lam, V = lam[::-1], V[:, ::-1]
    rank = Rank.of(np.sqrt(np.clip(lam, 0.0, None)), V.T, c)
    return rank, undetermined(rank)


def undetermined(rank: Rank) -> BoolArray:
    """(p,) True for each coefficient with more than ``NULL_SHARE`` of a null direction of
    ``rank`` (scaled coordinates): the coefficients the list cannot identify."""
    share: BoolArray = np.linalg.norm(rank.null, axis=1) > NULL_SHARE
    return share


def predicted_errors(information: ArrayLike) -> FloatArray:
    """(p,) predicted standard errors sqrt(diag(I^-1)), SI in the column order of the list's
    Fisher information I (p, p) = sum_k n_k F_k (1/SI^2); np.inf for each coefficient the list
    cannot identify (module doc), the determined ones' errors from the pseudo-inverse."""
    info = np.asarray(information, dtype=float)
    return _errors(info, *_spectrum(info))


def identified_errors(information: ArrayLike, spec: ModelSpec, what: str) -> FloatArray:
    """:func:`predicted_errors` of ``spec``'s coefficients; IdentifiabilityError when ``what``
    (the list, in words) cannot identify one of them, naming them and the combinations of
    coefficients its information leaves undetermined."""
    info = np.asarray(information, dtype=float)
    rank, undetermined = _spectrum(info)
    se = _errors(info, rank, undetermined)
    if np.all(np.isfinite(se)):
        return se
    raise unidentifiable(rank, spec, what)


def _errors(info: FloatArray, rank: Rank, undetermined: BoolArray) -> FloatArray:
    """:func:`predicted_errors` of ``info`` given its :func:`_spectrum`."""
    if not undetermined.any():
        se: FloatArray = np.sqrt(np.diag(np.linalg.inv(info)))
        return se
    kept = rank.vt[: rank.rank].T / rank.singular_values[: rank.rank]  # scaled coordinates
    out: FloatArray = np.sqrt(np.sum(kept**2, axis=1)) / rank.scale
    out[undetermined] = np.inf
    return out


def unidentifiable(rank: Rank, spec: ModelSpec, what: str) -> IdentifiabilityError:
    """The refusal of ``what`` (a list, in words) whose column-scaled regression or information
    has the deficient ``rank``: the coefficients it leaves undetermined (:func:`undetermined`)
    and the combinations of coefficients its null directions are."""
    bad = [n for n, u in zip(spec.names, undetermined(rank)) if u]
    combos = combinations(rank, spec.names)
    return IdentifiabilityError(
        f"{what} cannot identify {spec.model} {spec.freq_dep.text}: {', '.join(bad)} undetermined (the "
        f"forces do not change when the coefficients move along {'; '.join(combos)}); more distinct orbit "
        "frequencies, spread wider, or both whirl directions may separate them",
        combos,
    )

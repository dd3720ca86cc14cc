"""The least-squares estimators and solvers of the identification: their names in matrices, files
and payloads.

Its own module, free of numerics, so that the matrix configuration can type its ``method``
field with it without importing the identification."""

from __future__ import annotations

from enum import StrEnum


class Method(StrEnum):
    """Least-squares estimator: ordinary, weighted, total, instrumental variables."""

    __repr__ = str.__repr__  # messages show 'ols', as the plain string did

    OLS = "ols"
    WLS = "wls"
    TLS = "tls"
    IV = "iv"


METHODS = tuple(Method)


class Solver(StrEnum):
    """Linear least-squares solver of each step: Householder QR, SVD, or LU of the normal
    equations with iterative refinement (the paper's cross-check; they agree to rounding)."""

    __repr__ = str.__repr__

    QR = "qr"
    SVD = "svd"
    LU = "lu"


SOLVERS = tuple(Solver)

"""Linear least-squares solvers and estimators for the impedance regression A theta = b.

Every routine works on the matrix it is given; :func:`column_scale` equilibrates columns
(unit 2-norm) first so that coefficients of very different units (N/m, N s/m, kg, times
powers of Omega) do not spoil the conditioning. The solvers, as the paper cross-checks them:

- ``qr``:  Householder QR, x = R^-1 Q^T b, blocked over rows (:func:`triangular`);
- ``svd``: x = V S^-1 U^T b;
- ``lu``:  normal equations (A^T A) x = A^T b by LU, then iterative refinement on the
  least-squares residual (x += (A^T A)^-1 A^T (b - A x)), which recovers QR accuracy as
  long as cond(A)^2 * eps < 1.

Estimators: :func:`ols`, :func:`wls` (row weights = inverse variances), :func:`iv`
(instrumental variables, two-stage least squares) and :func:`structured_tls` (total least
squares for noisy displacements, maximum likelihood with isotropic phasor noise).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from reduction.arrays import FloatArray
from reduction.errors import IdentificationError, ReductionError
from reduction.methods import SOLVERS, Solver

#: a regression's rows, block by block (a callable: each call yields them again from the top)
Blocks = Callable[[], Iterator[FloatArray]]

CHUNK_ROWS = 32768  # real equations per block of the blocked QR (memory: one block, not the table)
LONG_TABLE = 8 * CHUNK_ROWS  # above this many equations the QR is taken by Cholesky QR twice
_EPS = np.finfo(float).eps


@dataclass
class Estimate:
    """A solved regression: ``x`` (p,), its covariance ``cov`` (p, p) from the residual
    (None when there are no degrees of freedom), residual sum of squares ``rss`` in the
    estimator's own metric (weighted for wls, whitened for tls) and ``dof``."""

    x: np.ndarray
    cov: np.ndarray | None
    rss: float
    dof: int
    unscaled: np.ndarray | None = None  # (A_eff^T A_eff)^-1: the covariance for unit-variance equations


def column_scale(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(A / c, c) with c the 2-norm of each column (1 for an all-zero column)."""
    c = np.linalg.norm(A, axis=0)
    c = np.where(c > 0, c, 1.0)
    return A / c, c


def condition_number(A: np.ndarray) -> float:
    """2-norm condition number sigma_max / sigma_min (inf when rank-deficient)."""
    s = np.linalg.svd(A, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else float("inf")


def _gram(blocks: Blocks, T: FloatArray | None = None) -> FloatArray:
    """The Gram matrix of the stacked row ``blocks`` (each a callable's yield, (rows, q)),
    or of the blocks times T (q, q) on the right."""
    G: FloatArray | None = None
    for block in blocks():
        q = block if T is None else block @ T
        G = q.T @ q if G is None else G + q.T @ q
    if G is None:
        raise ReductionError("a regression without rows has no Gram matrix")
    return G


def _blocks(A: FloatArray, b: FloatArray | None) -> Iterator[FloatArray]:
    """[A | b] in blocks of ``CHUNK_ROWS`` rows."""
    for s in range(0, A.shape[0], CHUNK_ROWS):
        block = A[s : s + CHUNK_ROWS]
        yield block if b is None else np.column_stack([block, b[s : s + CHUNK_ROWS]])


def _cholesky_qr2(blocks: Blocks) -> FloatArray | None:
    """R of the stacked row ``blocks`` (a callable yielding them; called twice) by Cholesky
    QR twice (the Gram matrix of the rows, then of the rows made orthonormal by the first R):
    as accurate as Householder for condition numbers up to about 1e8, at the speed of a
    matrix product. None when the Gram matrix is not positive definite (rank-deficient or
    worse conditioned)."""
    import scipy.linalg as sla  # on first use: a command that only reads a configuration does not load it

    try:
        R1 = np.linalg.cholesky(_gram(blocks)).T
        R1_inv = sla.solve_triangular(R1, np.eye(R1.shape[0]))
        R2 = np.linalg.cholesky(_gram(blocks, R1_inv)).T
    except np.linalg.LinAlgError:
        return None
    R: FloatArray = R2 @ R1
    return R if np.all(np.isfinite(R2)) else None


def triangular_blocks(blocks: Blocks, n_equations: int, p: int) -> FloatArray:
    """R (min(m, p), p) of a regression given as a callable yielding its row blocks (called
    up to three times; the matrix itself is never whole in memory): Cholesky QR twice for a
    long one (over ``LONG_TABLE`` equations), else or when that fails blocked Householder."""
    R = _cholesky_qr2(blocks) if n_equations > LONG_TABLE else None
    if R is None:
        R = np.zeros((0, p))
        for block in blocks():
            # numpy's stubs: qr(mode="r") returns R alone, not a QRResult
            R = np.linalg.qr(np.vstack([R, block]), mode="r")  # type: ignore[assignment]
    return np.triu(R[: min(R.shape[0], p)])


def triangular(A: np.ndarray, b: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """(R, Q^T b) of the QR factorisation A = Q R over blocks of ``CHUNK_ROWS`` rows
    (:func:`triangular_blocks` on [A | b]; never more than one block copied). R is
    (min(m, p), p); b (m,) or (m, k); the signs of R's rows are the factorisation's own."""
    m, p = A.shape
    k = 0 if b is None else (1 if np.ndim(b) == 1 else b.shape[1])
    R = triangular_blocks(lambda: _blocks(A, b), m, p + k)
    top = min(R.shape[0], p)
    z = None if b is None else (R[:top, p] if np.ndim(b) == 1 else R[:top, p:])
    return R[:top, :p], z


def weighted_lstsq(A: FloatArray, b: FloatArray, w: FloatArray) -> FloatArray:
    """Least-squares solution of (w A) x = w b, row weights w (m,), by the blocked QR of
    :func:`triangular_blocks`: the weighted matrix is never whole in memory (one block of
    ``CHUNK_ROWS`` rows at a time)."""
    import scipy.linalg as sla

    m, p = A.shape

    def blocks() -> Iterator[FloatArray]:
        for s in range(0, m, CHUNK_ROWS):
            ws = w[s : s + CHUNK_ROWS, None]
            yield np.column_stack([A[s : s + CHUNK_ROWS] * ws, b[s : s + CHUNK_ROWS, None] * ws])

    R = triangular_blocks(blocks, m, p + 1)
    top = min(R.shape[0], p)
    x: FloatArray = sla.solve_triangular(R[:top, :p], R[:top, p])
    return x


def lstsq(A: np.ndarray, b: np.ndarray, solver: Solver | str = Solver.QR) -> np.ndarray:
    """Least-squares solution of A x = b (A full column rank) by ``qr``, ``svd`` or ``lu``.

    b may be (m,) or (m, k) for k right-hand sides.
    """
    import scipy.linalg as sla

    solver = solver_of(solver)
    if solver is Solver.QR:
        R, z = triangular(A, b)
        x: FloatArray = sla.solve_triangular(R, z)
        return x
    if solver is Solver.SVD:
        U, s, Vt = np.linalg.svd(A, full_matrices=False)
        x = Vt.T @ ((U.T @ b) / (s if np.ndim(b) == 1 else s[:, None]))
        return x
    return _lu_refined(A, b)


def solver_of(name: Solver | str) -> Solver:
    """The solver named ``name`` (qr | svd | lu); ReductionError naming the choices otherwise."""
    try:
        return Solver(name)
    except ValueError:
        raise ReductionError(f"unknown solver {name!r}: use one of {', '.join(SOLVERS)}") from None


def _lu_refined(A: np.ndarray, b: np.ndarray, max_iter: int = 30) -> np.ndarray:
    """Normal equations by LU (Crout-like, partial pivoting) with iterative improvement."""
    import scipy.linalg as sla

    lu = sla.lu_factor(A.T @ A, check_finite=False)
    x: FloatArray = sla.lu_solve(lu, A.T @ b, check_finite=False)
    prev, step, size = np.inf, np.inf, 0.0
    for _ in range(max_iter):
        if not np.all(np.isfinite(x)):
            break
        dx = sla.lu_solve(lu, A.T @ (b - A @ x), check_finite=False)
        x = x + dx
        step, size = float(np.linalg.norm(dx)), float(np.linalg.norm(x))
        if step <= 4 * _EPS * size or step >= 0.5 * prev:
            break
        prev = step
    if not np.all(np.isfinite(x)) or not step <= 1e-6 * max(size, np.finfo(float).tiny):
        raise IdentificationError(
            "lu: iterative refinement of the normal equations did not converge "
            "(regression too ill-conditioned for the normal equations); use --solver qr or svd"
        )
    return x


def _covariance(A_eff: np.ndarray, sigma2: float) -> np.ndarray:
    """sigma2 (A^T A)^-1 via the SVD of A (full column rank)."""
    _, s, Vt = np.linalg.svd(A_eff, full_matrices=False)
    cov: FloatArray = sigma2 * (Vt.T / s**2) @ Vt
    return cov


def _finish(A_eff: np.ndarray, x: np.ndarray, r: np.ndarray, cov_matrix: np.ndarray | None = None) -> Estimate:
    m, p = A_eff.shape
    dof = m - p
    rss = float(r @ r)
    unscaled = _covariance(A_eff, 1.0) if cov_matrix is None else cov_matrix
    if dof <= 0:
        return Estimate(x, None, rss, dof, unscaled)
    return Estimate(x, rss / dof * unscaled, rss, dof, unscaled)


def ols(
    A: np.ndarray,
    b: np.ndarray,
    solver: Solver | str = Solver.QR,
    unscaled: np.ndarray | None = None,
    x: np.ndarray | None = None,
) -> Estimate:
    """Ordinary least squares; cov = s^2 (A^T A)^-1 with s^2 = rss / (m - p); ``unscaled``
    is (A^T A)^-1 when the caller has it already (else computed by SVD), ``x`` the solution
    when the caller has solved it already with ``solver``."""
    x = lstsq(A, b, solver) if x is None else x
    return _finish(A, x, b - A @ x, unscaled)


def wls(
    A: np.ndarray,
    b: np.ndarray,
    weights: np.ndarray,
    solver: Solver | str = Solver.QR,
    unscaled: np.ndarray | None = None,
) -> Estimate:
    """Weighted least squares, weights = inverse variances of b (any common scale):
    minimises sum w r^2; cov = s^2 (A^T W A)^-1, s^2 = weighted rss / (m - p); ``unscaled``
    is (A^T W A)^-1 when the caller has it already."""
    w = np.sqrt(np.asarray(weights, dtype=float))
    if w.shape != b.shape or not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise ReductionError("wls: weights must be finite, > 0 and one per equation")
    Aw, bw = A * w[:, None], b * w
    x = lstsq(Aw, bw, solver)
    return _finish(Aw, x, bw - Aw @ x, unscaled)


def iv(A: np.ndarray, Z: np.ndarray, b: np.ndarray, solver: Solver | str = Solver.QR) -> Estimate:
    """Instrumental variables by two stages: A_hat = P_Z A (projection onto span Z), then
    least squares of b on A_hat. Z (m, q >= p) must be correlated with A but not with the
    noise in A. cov = s^2 (A_hat^T A_hat)^-1 with s^2 from the structural residual b - A x."""
    Qz, _ = np.linalg.qr(Z)
    A_hat = Qz @ (Qz.T @ A)
    x = lstsq(A_hat, b, solver)
    r = b - A @ x
    m, p = A.shape
    if m - p <= 0:
        return Estimate(x, None, float(r @ r), m - p)
    _, s, Vt = np.linalg.svd(A_hat, full_matrices=False)
    return _finish(A, x, r, (Vt.T / s**2) @ Vt)


def residual_covariances(Z: np.ndarray, var_f: np.ndarray, var_d: np.ndarray) -> np.ndarray:
    """(..., n, 2, 2) covariance M_k = diag(var_f_k) + Z_k diag(var_d_k) Z_k^H of each row's complex
    residual f_k + Z_k d_k (N^2): Z (..., n, 2, 2) N/m, var_f (n, 2) N^2, var_d (n, 2) m^2."""
    Sf = np.asarray(var_f, dtype=float)[..., None] * np.eye(2)
    M: np.ndarray = Sf + (Z * np.asarray(var_d, dtype=float)[:, None, :]) @ np.conj(np.swapaxes(Z, -1, -2))
    return M


def structured_tls(
    G: np.ndarray, f: np.ndarray, E: np.ndarray, var_f: np.ndarray, var_d: np.ndarray, x0: np.ndarray
) -> Estimate:
    """Total least squares of f = -Z(x) d with noise on both the displacements d and forces f.

    Maximum likelihood for independent circular complex noise on every displacement phasor
    (E|n|^2 = var_d, (n, 2)) and force phasor (var_f, (n, 2)): the residual r_k = f_k - G_k x
    = f_k + Z_k d_k has the covariance M_k = diag(var_f_k) + Z_k diag(var_d_k) Z_k^H, and
    sum_k 2 r_k^H M_k^-1 r_k (a chi2 when the variances are absolute) is minimised
    (Levenberg-Marquardt from x0) with x in the units of G's columns. Only the ratio of the
    variances matters for x; ``Estimate.unscaled`` is the covariance for absolute variances.

    G (n, 2, p) complex regressors, f (n, 2) forces, E (n, p, 2, 2) impedance basis
    (Z_k = sum_j x_j E[k, j]); G = -E d carries the displacements.
    """
    from scipy.optimize import least_squares

    n, _, p = G.shape
    if n * 4 <= p:
        raise IdentificationError("tls needs more equations than coefficients")

    def whitened(X: FloatArray) -> FloatArray:  # X (m, p) -> (m, 4n): every candidate at once
        L = np.linalg.cholesky(residual_covariances(np.einsum("kpil,mp->mkil", E, X), var_f, var_d))
        r = f[None] - np.einsum("kip,mp->mki", G, X)
        e = np.sqrt(2) * np.linalg.solve(L, r[..., None])[..., 0]
        return np.concatenate([e.real.reshape(len(X), -1), e.imag.reshape(len(X), -1)], axis=1)

    def jacobian(x: FloatArray) -> FloatArray:  # forward differences, all p columns in one batched evaluation
        h: FloatArray = np.sqrt(_EPS) * np.maximum(1.0, np.abs(x))
        F = whitened(np.vstack([x, x + np.diag(h)]))
        J: FloatArray = (F[1:] - F[0]) / h[:, None]
        return J.T

    sol = least_squares(
        lambda x: whitened(x[None])[0],
        x0,
        jac=jacobian,
        method="lm",
        xtol=1e-14,
        ftol=1e-14,
        gtol=1e-14,
        max_nfev=200 * (p + 1),
    )
    if not np.all(np.isfinite(sol.x)):
        raise IdentificationError("tls: the total least squares iteration did not converge")
    return _finish(sol.jac, sol.x, sol.fun)

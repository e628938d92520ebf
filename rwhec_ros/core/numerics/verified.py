"""Eigenvalue bounds that hold in floating point: the numbers behind a certificate.

A certificate needs a *lower* bound on the smallest eigenvalue of a symmetric matrix ``A``
(the certificate matrix ``Z(lambda)`` or the translation block of ``Q``) that is true for the
matrix as stored, whatever the rounding in the computation. An eigensolver's answer is only an
estimate; this module turns it into a proof with a Cholesky factorisation of a shifted matrix:

* if the floating-point Cholesky factorisation of ``fl(A - mu I)`` runs to completion with
  computed factor ``R``, then ``R^T R = fl(A - mu I) + dA`` with ``|dA| <= gamma_{n+1} |R^T||R|``
  entrywise (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., Thm. 10.3), so
  ``fl(A - mu I) + dA`` is positive semidefinite and, with ``||dA||_2 <= gamma_{n+1}
  rho(|R|^T |R|)`` and the rounding of the shift ``|fl(a_ii - mu) - (a_ii - mu)| <= u |fl(a_ii -
  mu)|``::

      lambda_min(A) >= mu - gamma_{n+1} rho(|R|^T |R|) - u max_i |fl(a_ii - mu)|.

  ``rho(|R|^T |R|)`` (the spectral radius of a nonnegative matrix) is bounded from above by the
  Collatz-Wielandt inequality ``rho(B) <= max_i (B x)_i / x_i`` for any positive ``x``, evaluated
  with its own rounding (sums of nonnegative terms: relative error ``<= gamma_{2n}``).

``u`` is the unit roundoff of IEEE double (2^-53) and ``gamma_k = k u / (1 - k u)``. The same
module holds :func:`smallest_eigenvalues`, the estimate that chooses the shift.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse.linalg

from .cholesky import upper_cholesky

__all__ = [
    "UNIT_ROUNDOFF",
    "gamma",
    "nonnegative_spectral_radius_bound",
    "VerifiedBound",
    "verified_min_eigenvalue",
    "smallest_eigenvalues",
    "lanczos_start",
]

#: Unit roundoff ``u`` of IEEE double precision.
UNIT_ROUNDOFF = float(np.finfo(float).eps) / 2.0


def gamma(k: int) -> float:
    """``gamma_k = k u / (1 - k u)``: the relative error bound of ``k`` rounded operations."""
    ku = k * UNIT_ROUNDOFF
    if ku >= 1.0:
        return float("inf")
    return ku / (1.0 - ku)


def nonnegative_spectral_radius_bound(R: np.ndarray, iterations: int = 4) -> float:
    """Upper bound on ``rho(|R|^T |R|) = || |R| ||_2^2`` for a square or rectangular ``R``.

    Collatz-Wielandt: for the nonnegative symmetric ``B = |R|^T |R|`` and any positive ``x``,
    ``rho(B) <= max_i (B x)_i / x_i``; ``x`` is improved by a few power iterations from the all-ones
    vector (floored at a tiny positive value so the ratio exists). The products are sums of
    nonnegative terms, whose computed value exceeds the exact one by at most a factor
    ``1 + gamma_{2n}``; the division adds one rounding. Never smaller than the exact radius.
    """
    A = np.abs(np.asarray(R, dtype=float))
    n = A.shape[1]
    if n == 0:
        return 0.0
    # (a zero A needs no test of its own: the first product is zero, the loop stops and the
    # ratio below is 0 / 1 = 0)
    x = np.ones(n)
    for _ in range(iterations):
        y = A.T @ (A @ x)
        top = float(y.max())
        if not np.isfinite(top) or top <= 0.0:
            break
        x = np.maximum(y / top, 1e-30)
    y = A.T @ (A @ x)
    ratio = float(np.max(y / x))
    # rounding of the two products (2n terms per entry at most) and of the division
    return ratio * (1.0 + gamma(2 * max(A.shape))) * (1.0 + 2.0 * UNIT_ROUNDOFF)


@dataclass(frozen=True)
class VerifiedBound:
    """Result of :func:`verified_min_eigenvalue`.

    Attributes
    ----------
    lower : float
        A proven lower bound on ``lambda_min(A)`` (``-inf`` when no shift could be verified).
    shift : float
        The shift ``mu`` whose factorisation succeeded (``nan`` if none did).
    margin : float
        ``estimate - lower``: what the shift and the rounding analysis cost.
    attempts : int
        Factorisations tried.
    """

    lower: float
    shift: float
    margin: float
    attempts: int

    @property
    def verified(self) -> bool:
        return bool(np.isfinite(self.lower))


def _shifted_cholesky_bound(A: np.ndarray, mu: float) -> float | None:
    """The lower bound proven by a successful Cholesky factorisation of ``fl(A - mu I)``, or
    ``None`` when the factorisation breaks down (see the module docstring)."""
    n = A.shape[0]
    # fl(A - mu I), Fortran-ordered so that LAPACK factors it in place (the same values and
    # layout as scipy.linalg.cholesky's own copy: the same factor, bit for bit)
    B = np.array(A, dtype=float, order="F", copy=True)
    shifted = np.diag(B) - mu
    np.fill_diagonal(B, shifted)
    shift_rounding = UNIT_ROUNDOFF * float(np.max(np.abs(shifted))) if n else 0.0
    R = upper_cholesky(B, overwrite=True)
    if R is None or not np.all(np.isfinite(R)):
        return None
    backward = gamma(n + 1) * nonnegative_spectral_radius_bound(R)
    return float(mu - backward - shift_rounding)


def verified_min_eigenvalue(
    A: np.ndarray,
    estimate: float | None = None,
    *,
    max_attempts: int = 8,
) -> VerifiedBound:
    """A lower bound on ``lambda_min(A)`` that holds in floating point (module docstring).

    Parameters
    ----------
    A : ndarray, shape (n, n)
        Symmetric matrix, as stored (``A`` and ``A.T`` must agree; symmetrise first).
    estimate : float, optional
        An estimate of ``lambda_min(A)`` (e.g. from :func:`smallest_eigenvalues`); computed when
        not given.
    max_attempts : int
        Factorisations tried; the gap below the estimate grows 8-fold after each failure,
        starting from the size of the expected rounding error.

    Returns
    -------
    VerifiedBound
        ``lower == -inf`` when no shifted factorisation succeeded (e.g. a NaN in ``A``).
    """
    A = np.asarray(A, dtype=float)
    n = A.shape[0]
    if A.ndim != 2 or A.shape != (n, n):
        raise ValueError(f"A: expected a square matrix, got shape {A.shape}")
    if n == 0:
        return VerifiedBound(float("inf"), 0.0, 0.0, 0)
    if not np.all(np.isfinite(A)):
        return VerifiedBound(float("-inf"), float("nan"), float("inf"), 0)
    if estimate is None:
        estimate = float(smallest_eigenvalues(A, 1)[0])
    # first gap: the typical size of the backward error, gamma_{n+1} times the largest diagonal
    # entry (|R^T||R| has entries <= sqrt(a_ii a_jj)); grown 8-fold after each failure
    gap = max(gamma(n + 1) * float(np.max(np.abs(np.diag(A)))), 1e-300)
    for attempt in range(1, max_attempts + 1):
        mu = float(estimate) - gap
        lower = _shifted_cholesky_bound(A, mu)
        if lower is not None:
            return VerifiedBound(lower, mu, float(estimate) - lower, attempt)
        gap *= 8.0
    return VerifiedBound(float("-inf"), float("nan"), float("inf"), max_attempts)


def lanczos_start(m: int) -> np.ndarray:
    """A fixed start vector (m,) with mixed components for ARPACK, so that Lanczos runs are
    reproducible (ARPACK's own start is random)."""
    return 1.0 + 0.5 * np.sin(np.arange(m) * 1.7)


#: Above this size the smallest eigenvalues come from shift-invert Lanczos on a Cholesky factor.
LANCZOS_MIN_SIZE = 3000
#: Up to this size all eigenvalues are computed (LAPACK ``syevd``); above it an index range
#: (``syevr``), which is faster from about 120 for the few eigenvalues a certificate asks for
#: (one thread, 6 of them: 0.65 vs 0.68 ms at 100, 3.6 vs 2.7 ms at 217, 5.9 vs 4.8 ms at 300;
#: 2.6x slower at 19). Both are estimates (see :func:`verified_min_eigenvalue`).
FULL_EIGH_MAX_SIZE = 120


def smallest_eigenvalues(Z: np.ndarray, k: int, shift: float = 1e-8) -> np.ndarray:
    """The ``k`` smallest eigenvalues (ascending) of symmetric ``Z`` -- an *estimate*.

    Three paths by size ``d``: up to :data:`FULL_EIGH_MAX_SIZE` all eigenvalues
    (``numpy.linalg.eigvalsh``); up to :data:`LANCZOS_MIN_SIZE` an index-range eigensolve (LAPACK
    ``syevr``, indices ``0 .. k-1``); above, ``Z + shift I`` is Cholesky-factored -- which succeeds
    exactly when ``lambda_min(Z) > -shift``, the case of a valid certificate -- and shift-invert
    Lanczos (ARPACK) around ``-shift`` returns the eigenvalues nearest to it, i.e. the smallest (one
    factorisation instead of a tridiagonal reduction: 9,010 x 9,010 in ~5 s instead of ~50 s). A
    failed factorisation (an indefinite ``Z``) falls back to the index-range eigensolve.
    Certificates never rely on these values alone: see :func:`verified_min_eigenvalue`.
    """
    Z = np.asarray(Z, dtype=float)
    d = Z.shape[0]
    k = int(min(k, d))
    if k <= 0:
        return np.zeros(0)
    if d <= FULL_EIGH_MAX_SIZE or k >= d:
        return np.linalg.eigvalsh(Z)[:k]
    if d >= LANCZOS_MIN_SIZE:
        try:
            factor = scipy.linalg.cho_factor(Z + shift * np.eye(d), lower=True,
                                              check_finite=False)
        except np.linalg.LinAlgError:
            factor = None
        if factor is not None:
            op = scipy.sparse.linalg.LinearOperator(
                (d, d), matvec=lambda b: scipy.linalg.cho_solve(factor, b, check_finite=False),
                dtype=float)
            w = scipy.sparse.linalg.eigsh(Z, k=k, sigma=-shift, which="LM", OPinv=op,
                                          return_eigenvectors=False, v0=lanczos_start(d))
            return np.sort(w)
    return scipy.linalg.eigh(Z, eigvals_only=True, subset_by_index=[0, k - 1], driver="evr")

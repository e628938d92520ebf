"""Certification of a candidate solution from a dual certificate matrix ``Z(lambda)``.

Weak duality (paper eq. (71)): for every feasible ``z`` (rotations in SO(3)^n, ``s = 1``),
``z^T Q z = lambda_s + z^T Z(lambda) z >= lambda_s + lambda_min(Z) |z|^2`` and ``|z|^2 = 3 n + 1``.
Hence the rigorous lower bound on the optimum used here is::

    d = lambda_s + min(0, lambda_min(Z)) (3 n + 1)

(which guards against a slightly infeasible dual), and the relative suboptimality bound of the
returned solution with cost ``p`` is ``rho_hat = (p - d) / d`` (eq. (73)).

The status is CERTIFIED_OPTIMAL only when ``rho_hat <= rho_tol`` AND ``Z`` has a one-dimensional
(numerical) null space, i.e. the relaxation is tight with a unique rank-one solution.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse.linalg

from .result import Certificate, Status

__all__ = ["CertificateOptions", "certify_from_Z"]


@dataclass
class CertificateOptions:
    """Tolerances of the certificate (all in the units of the SCALED problem, where the data
    matrix is divided by an upper bound on the optimal cost so that the optimum is O(1)).

    Attributes
    ----------
    rho_tol : float
        Largest relative suboptimality bound ``rho_hat`` accepted as certified (1e-6: a
        millionth of the cost, three orders above the ~1e-9 solver accuracy).
    null_tol : float
        Eigenvalues of the scaled ``Z`` at or below this count towards its null space (1e-6).
    n_eigenvalues : int
        How many of the smallest eigenvalues to report (6).
    """

    rho_tol: float = 1e-6
    null_tol: float = 1e-6
    n_eigenvalues: int = 6


#: Above this size the smallest eigenvalues come from shift-invert Lanczos on a Cholesky factor.
_LANCZOS_MIN_SIZE = 3000


def _smallest_eigenvalues(Z: np.ndarray, k: int, shift: float = 1e-8) -> np.ndarray:
    """The ``k`` smallest eigenvalues (ascending) of symmetric ``Z``.

    Small matrices: a full (or index-range, LAPACK ``syevr``) eigensolve. Large ones: ``Z +
    shift I`` is Cholesky-factored -- which succeeds exactly when ``lambda_min(Z) > -shift``, the
    case of a valid certificate -- and shift-invert Lanczos (ARPACK) around ``-shift`` returns
    the eigenvalues nearest to it, i.e. the smallest; this costs one factorisation instead of a
    tridiagonal reduction (9,010 x 9,010: ~5 s instead of ~50 s). A failed factorisation falls
    back to the index-range eigensolve.
    """
    d = Z.shape[0]
    if d <= 300 or k >= d:
        return np.linalg.eigvalsh(Z)[:k]
    if d >= _LANCZOS_MIN_SIZE:
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
                                          return_eigenvectors=False)
            return np.sort(w)
    return scipy.linalg.eigh(Z, eigvals_only=True, subset_by_index=[0, k - 1], driver="evr")


def certify_from_Z(
    Z_scaled: np.ndarray,
    lambda_s_scaled: float,
    primal_cost: float,
    scale: float,
    n_rotations: int,
    *,
    solver_ok: bool = True,
    solver_status: str = "",
    homogeneous: bool = False,
    cost_floor: float = 0.0,
    options: CertificateOptions | None = None,
) -> Certificate:
    """Build a :class:`Certificate` from a (scaled) certificate matrix.

    Parameters
    ----------
    Z_scaled : ndarray, shape (9 n + 1, 9 n + 1)
        ``Z(lambda)`` on the reduced variables ``[vec R; s]`` of the scaled problem.
    lambda_s_scaled : float
        Multiplier of ``s^2 = 1`` (scaled units).
    primal_cost : float
        Cost ``p`` of the returned feasible solution (unscaled).
    scale : float
        Factor by which the data matrix was divided.
    n_rotations : int
        Number of rotation variables ``n = M + P``.
    solver_ok : bool
        Whether the numerical solver that produced ``lambda`` reported success.
    homogeneous : bool
        The objective does not involve ``s`` (unknown scale, Problem 6: ``alpha`` is eliminated
        and the last row/column of ``Q'`` is zero). Then ``(r, s)`` and ``(r, -s)`` have the same
        cost, and when ``Z`` does not couple ``s`` to the rotations (the orthogonality-only
        multipliers of the fast certificate) ``e_s`` is a trivial null vector of ``Z``; it carries
        no information about the rotations, so uniqueness is judged on the rotation block.
    cost_floor : float
        A cost regarded as zero at the scale of the data (noise-free problems have optimum 0, where
        eq. (73) is undefined): ``rho_hat = (p - d) / max(d, cost_floor)``.
    """
    opts = options or CertificateOptions()
    w = _smallest_eigenvalues(0.5 * (Z_scaled + Z_scaled.T), opts.n_eigenvalues)
    lam_min = float(w[0])
    null_dim = int(np.sum(w <= opts.null_tol))
    trivial_s = False
    if homogeneous and np.linalg.norm(Z_scaled[:-1, -1]) <= opts.null_tol and \
            abs(Z_scaled[-1, -1]) <= opts.null_tol:
        w_r = _smallest_eigenvalues(0.5 * (Z_scaled[:-1, :-1] + Z_scaled[:-1, :-1].T),
                                    opts.n_eigenvalues)
        null_dim = int(np.sum(w_r <= opts.null_tol))
        trivial_s = True
    bound_scaled = lambda_s_scaled + min(0.0, lam_min) * (3 * n_rotations + 1)
    d = float(bound_scaled * scale)
    p = float(primal_cost)
    denom = max(d, cost_floor)
    rho = (p - d) / denom if np.isfinite(d) else float("nan")
    eigs = w[: opts.n_eigenvalues].copy()
    if not solver_ok or not np.isfinite(rho):
        status = Status.SOLVER_INACCURATE
        msg = (f"solver status '{solver_status}': the dual solution is not reliable "
               f"(rho_hat={rho:.3g}, lambda_min={lam_min:.3g})")
    elif rho <= opts.rho_tol and null_dim == 1:
        status = Status.CERTIFIED_OPTIMAL
        msg = (f"certified globally optimal: rho_hat={rho:.3g} <= {opts.rho_tol:g}, Z has a "
               f"one-dimensional null space (eigenvalues {eigs[0]:.2g}, {eigs[1]:.2g}, ...)"
               if len(eigs) > 1 else "certified globally optimal")
        if trivial_s:
            msg += " on the rotation block (the sign of s is free for unknown scale)"
    else:
        status = Status.NOT_TIGHT
        why = []
        if rho > opts.rho_tol:
            why.append(f"rho_hat={rho:.3g} > {opts.rho_tol:g}")
        if null_dim != 1:
            why.append(f"Z has {null_dim} eigenvalues <= {opts.null_tol:g} "
                       f"(smallest {np.array2string(eigs, precision=3)})")
        msg = "not certified: " + "; ".join(why)
    return Certificate(
        status=status,
        primal_cost=p,
        dual_bound=d,
        suboptimality_bound=float(rho),
        lambda_min=lam_min,
        eigenvalues=eigs,
        null_space_dim=null_dim,
        tolerance=opts.rho_tol,
        message=msg,
    )

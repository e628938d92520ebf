"""The Schur reduction of the cost onto the rotations (paper eq. (47)-(48)), with proven error
terms.

The translations (and, for unknown scale, ``alpha``) enter the cost ``x^T Q x`` of
:mod:`rwhec_ros.core.model.cost` quadratically, so for given rotations their optimum is linear in
``z = [vec R; s]`` (eq. (47)) and the cost of the rotations alone is ``z^T Q' z`` with the Schur
complement ``Q'`` of eq. (48): the dense path's objective. :func:`reduce_cost` forms ``Q'`` and
the recovery map with a Cholesky factorisation of the eliminated block, and bounds what the
floating-point reduction may differ from the exact one (:class:`ReducedCost`), which the
certificate adds to its margins.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..numerics.cholesky import upper_cholesky, upper_cholesky_solve
from .cost import StateLayout

__all__ = ["ReducedCost", "reduce_cost"]


@dataclass(frozen=True)
class ReducedCost:
    """The Schur reduction of ``Q`` onto the rotations (eq. (47)-(48)) and its error bounds.

    Attributes
    ----------
    Qr : ndarray, shape (9 (M + P) + 1, 9 (M + P) + 1)
        Reduced objective on ``z = [vec(R_X), vec(R_Y), s]`` (the homogenising ``s`` last). For
        known scale the last row/column carry the terms of ``s = alpha``; for unknown scale
        ``alpha`` is eliminated too and they are zero (paper Fig. 4 caption).
    recover : ndarray, shape (3 (M + P) + 1, 9 (M + P) + 1)
        Linear map ``[t_alpha; alpha] = recover @ z`` (eq. (47)); for known scale the ``alpha``
        row simply copies ``s``.
    unknown_scale : bool
    verified : bool
        The eliminated block ``Q_ee`` was Cholesky-factored and the bounds below hold. ``False``
        when it is singular (unidentifiable translations): ``Qr`` then comes from the
        pseudo-inverse (minimum-norm recovery) and proves nothing.
    block_lower : float
        Proven lower bound on ``lambda_min(Q_ee)`` (:func:`~rwhec_ros.core.numerics.verified.
        verified_min_eigenvalue`).
    residual_norm : float
        Upper bound on ``||Q_ee G + Q_ey||_2`` for the recovery ``t = G y`` actually used (the
        backward error of the Cholesky solve, Higham Thm. 10.4; or, with ``residual=
        "extended"``, the Frobenius norm of the extended-precision bound of
        :mod:`rwhec_ros.core.numerics.extended_residual`).
    err_rows : ndarray, shape (9 (M + P) + 1,)
        Row sums of an entrywise bound ``E`` on ``|Qr - S_G|``, where ``S_G = Q_yy + G^T Q_ee G +
        G^T Q_ey + Q_ey^T G`` is the exact reduced cost *for this G* (for any ``G`` and ``u``,
        ``x^T Q x = u^T Q_ee u + 2 u^T F y + y^T S_G y`` with ``t = u + G y`` and ``F = Q_ee G +
        Q_ey``). ``E`` covers the rounding of ``Q_yy + Q_ey^T G``, the term ``G^T F`` and the
        symmetrisation. Its sum and largest row sum bound ``y^T (Qr - S_G) y`` for ``|y_i| <= 1``.
    """

    Qr: np.ndarray
    recover: np.ndarray
    unknown_scale: bool
    verified: bool = False
    block_lower: float = float("nan")
    residual_norm: float = float("nan")
    err_rows: np.ndarray | None = None


def _abs_rowsums(A) -> np.ndarray:
    """Row sums of ``|A|`` (dense or sparse)."""
    if sp.issparse(A):
        return np.asarray(abs(A).sum(axis=1)).ravel()
    return np.abs(A).sum(axis=1)


def _dense_blocks(Qd: np.ndarray, layout: StateLayout, unknown_scale: bool
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``Q_ee``, ``Q_ek`` and ``Q_kk`` of the dense ``Qd`` (size, size) for :func:`reduce_cost`:
    eliminated ``e`` = translations (and ``alpha`` for unknown scale), kept ``k`` = rotations
    (then ``s`` = ``alpha`` for known scale). The same entries as ``Qd[np.ix_(elim, keep)]``
    etc., copied from contiguous slices (a tenth of the time of the fancy index)."""
    a, r0 = layout.alpha, layout.r0
    if unknown_scale:  # e = [0, r0), k = [r0, size): plain slices
        return (Qd[:r0, :r0].copy(), np.ascontiguousarray(Qd[:r0, r0:]),
                np.ascontiguousarray(Qd[r0:, r0:]))
    nr = layout.size - r0  # e = [0, a), k = [r0, size) then a
    Qek = np.empty((a, nr + 1))
    Qek[:, :nr] = Qd[:a, r0:]
    Qek[:, nr] = Qd[:a, a]
    Qkk = np.empty((nr + 1, nr + 1))
    Qkk[:nr, :nr] = Qd[r0:, r0:]
    Qkk[:nr, nr] = Qd[r0:, a]
    Qkk[nr, :nr] = Qd[a, r0:]
    Qkk[nr, nr] = Qd[a, a]
    return Qd[:a, :a].copy(), Qek, Qkk


def reduce_cost(Q: sp.spmatrix, layout: StateLayout, unknown_scale: bool, *,
                residual: str = "cholesky") -> ReducedCost:
    """Eliminate translations (and ``alpha`` for unknown scale) from ``Q`` (eq. (47)-(48)).

    The eliminated block ``Q_ee`` is Cholesky-factored (after the unobservable directions have
    been fixed, see :mod:`rwhec_ros.core.model.gauge`, it is positive definite); the reduced matrix
    is ``Qr = Q_yy + Q_ey^T G`` with ``G = -Q_ee^{-1} Q_ey`` and comes with the bounds of
    :class:`ReducedCost` that the certificate needs. A singular block falls back to the
    pseudo-inverse, as the paper's generalized Schur complement, flagged ``verified=False``.

    ``residual`` chooses the bound on the residual ``F = Q_ee G + Q_ey`` of the recovery:
    ``"cholesky"`` (default), the backward error of the solve, computed with matrix-vector
    products only; ``"extended"``, ``F`` evaluated in extended precision with a proven bound
    (:func:`~rwhec_ros.core.numerics.extended_residual.residual_bound`: a few matrix products,
    usually hundreds of times tighter). ``Qr``, ``recover``, the block bound and the product terms
    are the same either way (bit for bit); only ``err_rows`` and ``residual_norm`` differ.
    """
    if residual not in ("cholesky", "extended"):
        raise ValueError(f"residual: expected 'cholesky' or 'extended', got {residual!r}")
    from ..numerics.extended_residual import residual_bound
    from ..numerics.verified import (
        gamma,
        nonnegative_spectral_radius_bound,
        verified_min_eigenvalue,
    )

    nt = layout.n_t
    a = layout.alpha
    r = np.arange(layout.r0, layout.size)
    if unknown_scale:
        elim = np.arange(0, nt + 1)  # t and alpha
        keep = r
    else:
        elim = np.arange(0, nt)
        keep = np.concatenate([r, [a]])  # rotations then s
    if sp.issparse(Q):  # large problems: keep the sparse coupling block sparse
        Qc = sp.csr_matrix(Q)
        Qee = Qc[elim][:, elim].toarray()
        Qek = Qc[elim][:, keep].tocsc()
        Qkk = Qc[keep][:, keep].toarray()
    else:
        Qee, Qek, Qkk = _dense_blocks(np.asarray(Q, dtype=float), layout, unknown_scale)
    Qee = 0.5 * (Qee + Qee.T)
    m = Qee.shape[0]
    verified = False
    block_lower = float("nan")
    residual_norm = float("nan")
    err = None
    # the upper factor as scipy.linalg.cho_factor computes it (the lower triangle left as is)
    factor = upper_cholesky(Qee, clean=False)
    if factor is not None:
        Qek_d = Qek.toarray() if sp.issparse(Qek) else Qek
        G = -upper_cholesky_solve(factor, Qek_d)
        Qr_keep = Qkk + np.asarray(Qek.T @ G)
        Rf = np.triu(factor)
        # lower bound on lambda_min(Q_ee): half an inverse-iteration estimate, verified by a
        # shifted factorisation (only a crude bound is needed: it divides ||F||^2, ~u^2 small)
        vb = verified_min_eigenvalue(Qee, 0.5 * _inverse_iteration_min(factor, m))
        if vb.verified and vb.lower > 0:
            verified = True
            block_lower = vb.lower
            absG = np.abs(G)
            g1 = absG.sum(axis=1)  # |G| 1        (m,)
            if residual == "extended":  # |F| <= Fb, F evaluated in extended precision
                Fb = residual_bound(Qee, G, Qek)
                F_rows = Fb.sum(axis=1) * (1.0 + gamma(Fb.shape[1]))  # row sums of |F| bound
                F_cols = (Fb.T @ g1) * (1.0 + gamma(m))  # |F|^T |G| 1 bound   (k,)
                residual_norm = float(np.linalg.norm(Fb, "fro")) * (1.0 + gamma(Fb.size))
            else:  # |F| <= gamma_{3m+1} |R^T||R| |G| (backward error of the Cholesky solve)
                gam_s = gamma(3 * m + 1)
                absR = np.abs(Rf)
                F_rows = gam_s * (absR.T @ (absR @ g1))  # row sums of the bound on |F|   (m,)
                F_cols = gam_s * (absG.T @ (absR.T @ (absR @ g1)))
                residual_norm = gam_s * nonnegative_spectral_radius_bound(Rf) * float(
                    np.linalg.norm(G, "fro"))
            gk = gamma(m + 1)
            Qkk_abs_rows = _abs_rowsums(Qkk)
            Qek_abs = abs(Qek) if sp.issparse(Qek) else np.abs(Qek)
            # E1 = gamma (|Q_yy| + |Q_ey|^T |G|): row and column sums
            e1_rows = gk * (Qkk_abs_rows + np.asarray(Qek_abs.T @ g1).ravel())
            e1_cols = gk * (Qkk_abs_rows + absG.T @ np.asarray(Qek_abs @ np.ones(len(keep))
                                                                  ).ravel())
            # E2 = |G|^T |F|: rows |G|^T(|F| 1), cols |F|^T(|G| 1)
            e2_rows = absG.T @ F_rows
            e2_cols = F_cols
            E_rows = 0.5 * (e1_rows + e1_cols + e2_rows + e2_cols)
            E_rows += UNIT_ROUNDOFF_COST * _abs_rowsums(Qr_keep)  # symmetrisation
            err = E_rows * (1.0 + gamma(2 * len(keep)))
            G_full = G
        else:
            factor = None
    if factor is None:
        Qek_d = Qek.toarray() if sp.issparse(Qek) else Qek
        Qee_pinv = np.linalg.pinv(Qee, rcond=1e-12, hermitian=True)
        G_full = -Qee_pinv @ Qek_d
        Qr_keep = Qkk + np.asarray(Qek.T @ G_full)
    G = G_full
    Qr_keep = 0.5 * (Qr_keep + Qr_keep.T)
    nr = 9 * layout.n_frames
    Qr = np.zeros((nr + 1, nr + 1))
    recover = np.zeros((nt + 1, nr + 1))
    err_rows = None
    if unknown_scale:
        Qr[:nr, :nr] = Qr_keep
        recover[:, :nr] = G
        if err is not None:
            err_rows = np.concatenate([err, [0.0]])
    else:
        Qr[:, :] = Qr_keep
        recover[:nt, :] = G
        recover[nt, nr] = 1.0
        err_rows = err
    return ReducedCost(Qr=Qr, recover=recover, unknown_scale=unknown_scale, verified=verified,
                       block_lower=block_lower, residual_norm=residual_norm, err_rows=err_rows)


def _inverse_iteration_min(factor: np.ndarray, m: int, iterations: int = 6) -> float:
    """Estimate of ``lambda_min`` of the matrix whose upper Cholesky factor is ``factor``
    (:func:`~rwhec_ros.core.numerics.cholesky.upper_cholesky`) by inverse iteration."""
    x = 1.0 + 0.5 * np.sin(np.arange(m) * 1.7)  # deterministic start with mixed components
    x /= np.linalg.norm(x)
    est = float("inf")
    for _ in range(iterations):
        y = upper_cholesky_solve(factor, x)
        ny = float(np.linalg.norm(y))
        if not np.isfinite(ny) or ny == 0.0:
            break
        est = 1.0 / ny
        x = y / ny
    return est


#: Unit roundoff of double precision (one rounding per entry of the symmetrisation).
UNIT_ROUNDOFF_COST = float(np.finfo(float).eps) / 2.0

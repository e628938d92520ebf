"""Sparse ``L D L^T`` factorisations with a floating-point backward-error bound.

A thin layer over QDLDL (``qdldl``, the factorisation of OSQP; an AMD fill-reducing ordering and
an up-looking ``L D L^T`` without pivoting): ``P^T A P = (I + L) D (I + L)^T`` for a symmetric
``A`` given by its upper triangle (the matrix factored is the symmetric matrix that triangle
defines). Used by the large-problem path of ``fast`` (:mod:`rwhec_ros.core.local.sparse`,
:mod:`rwhec_ros.core.certify.sparse`) and by the sparse analysis of unobservable translations
(:mod:`rwhec_ros.core.model.gauge`).

**Backward error.** QDLDL computes row ``k`` of ``L`` by a sparse triangular solve
``y_c = a_kc - sum_j l_cj y_j`` (over the ``j`` with ``l_cj != 0`` and ``l_kj != 0``), then
``l_kc = y_c * fl(1 / d_c)`` and ``d_k = a_kk - sum_c y_c l_kc``. With ``r_i`` the number of
off-diagonal nonzeros of row ``i`` of ``L``, the usual inner-product analysis (Higham, *Accuracy
and Stability of Numerical Algorithms*, 2nd ed., Lemma 8.4, with ``y_c = l_kc d_c (1 + theta_2)``
for the reciprocal and the product) gives, for a factorisation that runs to completion with
nonzero pivots, ``(I + L) D (I + L)^T = P^T (A + dA) P`` with::

    |dA_ij| <= gamma_{min(r_i, r_j) + 4} (|I + L| |D| |I + L|^T)_ij       (permuted indices),

whatever the order of the sums (and with or without fused multiply-adds). Per-coordinate weights
of this bound -- :meth:`SparseLDL.backward_error_rows` -- are evaluated with sparse products of
nonnegative numbers and rounded up; one more unit is added to the ``gamma`` index for safety.
``gamma_k = k u / (1 - k u)``, ``u = 2^-53`` (:mod:`rwhec_ros.core.numerics.verified`). For a
symmetric nonnegative ``W`` and any ``x``, ``|x|^T W |x| <= sum_i x_i^2 (W 1)_i``: row sums bound
the quadratic form coordinate by coordinate, which is what the certificate needs.
"""

from __future__ import annotations

import numpy as np
import qdldl
import scipy.sparse as sp

from .verified import UNIT_ROUNDOFF, gamma

__all__ = ["FactorizationError", "gamma_array", "upper_with_diagonal", "SparseLDL"]


class FactorizationError(np.linalg.LinAlgError):
    """The ``L D L^T`` factorisation broke down (a zero pivot or a non-finite number)."""


def gamma_array(k: np.ndarray) -> np.ndarray:
    """:func:`.verified.gamma` of an integer array (``inf`` where ``k u >= 1``)."""
    ku = np.asarray(k, dtype=float) * UNIT_ROUNDOFF
    with np.errstate(divide="ignore"):
        return np.where(ku < 1.0, ku / (1.0 - ku), np.inf)


def upper_with_diagonal(A: sp.spmatrix, extra_rows: np.ndarray | None = None,
                        extra_cols: np.ndarray | None = None) -> sp.csc_matrix:
    """The upper triangle of ``A`` (CSC, sorted indices) with every diagonal entry stored (an
    explicit zero where ``A`` has none) and explicit zeros at the further upper positions
    ``(extra_rows, extra_cols)``: the input format of :class:`SparseLDL`, whose pattern then
    stays fixed when the values change."""
    n = A.shape[0]
    U = sp.triu(sp.csr_matrix(A), format="coo")
    er = np.zeros(0, int) if extra_rows is None else np.asarray(extra_rows)
    ec = np.zeros(0, int) if extra_cols is None else np.asarray(extra_cols)
    rows = np.concatenate([U.row, np.arange(n), er])
    cols = np.concatenate([U.col, np.arange(n), ec])
    vals = np.concatenate([U.data, np.zeros(n + er.size)])
    out = sp.csc_matrix((vals, (rows, cols)), shape=(n, n))  # duplicates summed, zeros kept
    out.sort_indices()
    return out


def diagonal_positions(U: sp.csc_matrix) -> np.ndarray:
    """Positions in ``U.data`` of the diagonal entries of a matrix from
    :func:`upper_with_diagonal` (the last stored entry of each column)."""
    return U.indptr[1:] - 1


class SparseLDL:
    """``P^T A P = (I + L) D (I + L)^T`` of a symmetric sparse ``A`` (module docstring).

    Parameters
    ----------
    U : scipy.sparse.csc_matrix, shape (n, n)
        Upper triangle of ``A`` with the full diagonal stored (:func:`upper_with_diagonal`).

    Raises
    ------
    FactorizationError
        When a pivot is zero or a number is not finite.
    """

    def __init__(self, U: sp.csc_matrix) -> None:
        U = sp.csc_matrix(U)
        if U.shape[0] != U.shape[1] or U.shape[0] == 0:
            raise ValueError(f"U: expected a non-empty square matrix, got shape {U.shape}")
        if not np.all(np.isfinite(U.data)):
            raise FactorizationError("non-finite entry in the matrix to factorise")
        self.n = U.shape[0]
        self._indptr = U.indptr.copy()
        self._indices = U.indices.copy()
        try:
            self._solver = qdldl.Solver(U, upper=True)
        except RuntimeError as exc:  # QDLDL reports a zero pivot this way
            raise FactorizationError(f"LDL^T factorisation failed: {exc}") from None
        self._load()

    def refactor(self, data: np.ndarray) -> None:
        """Factorise the matrix with the same pattern and new values ``data`` (reusing the
        ordering and the symbolic analysis)."""
        data = np.asarray(data, dtype=float)
        if data.shape != self._indices.shape:
            raise ValueError(f"data: expected {self._indices.shape[0]} values, got {data.shape}")
        if not np.all(np.isfinite(data)):
            raise FactorizationError("non-finite entry in the matrix to factorise")
        self._solver.update(sp.csc_matrix((data, self._indices, self._indptr),
                                          shape=(self.n, self.n)), upper=True)
        self._load()

    def _load(self) -> None:
        L, D, p = self._solver.factors()
        # QDLDL stops at a zero pivot (leaving D[k] == 0); a NaN pivot does not stop it
        if not (np.all(np.isfinite(D)) and np.all(D != 0.0) and np.all(np.isfinite(L.data))):
            raise FactorizationError("LDL^T factorisation failed: zero or non-finite pivot")
        self.L = sp.csc_matrix(L)
        self.D = np.asarray(D, dtype=float)
        self.perm = np.asarray(p, dtype=np.int64)

    @property
    def n_negative(self) -> int:
        """Negative pivots: the number of negative eigenvalues of the factored matrix (Sylvester's
        law of inertia; of the matrix plus its backward error, strictly)."""
        return int(np.sum(self.D < 0.0))

    @property
    def positive_definite(self) -> bool:
        """All pivots positive: ``A + dA`` (module docstring) is positive definite."""
        return bool(np.all(self.D > 0.0))

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A^{-1} b`` for a vector ``b`` (n,)."""
        return np.asarray(self._solver.solve(np.ascontiguousarray(b, dtype=float)))

    def backward_error_rows(self) -> np.ndarray:
        """Per-coordinate weights ``c`` (original order, shape (n,)) with ``|x|^T |dA| |x| <=
        sum_i c_i x_i^2`` for every ``x``, where ``(I + L) D (I + L)^T = P^T (A + dA) P`` (module
        docstring), rounded up.

        With ``B = |I + L| |D| |I + L|^T`` and ``g_i = gamma_{r_i + 5}``, ``|dA_ij| <= min(g_i,
        g_j) B_ij``, and ``2 |x_i x_j| <= x_i^2 + x_j^2`` gives ``c_i = sum_j min(g_i, g_j)
        B_ij``, bounded by both ``g_i (B 1)_i`` and ``(B g)_i``: the smaller is taken. (A hub
        row -- a target every camera sees, eliminated last -- has a long row of ``L``, but its
        products with the short rows carry the short rows' ``gamma``.)
        """
        Labs = abs(self.L)
        r = np.bincount(Labs.indices, minlength=self.n)  # off-diagonal nonzeros per row of L
        g = gamma_array(r + 5)
        col_terms = np.diff(Labs.indptr)
        absD = np.abs(self.D)

        def B_times(x: np.ndarray) -> np.ndarray:  # |I + L| |D| |I + L|^T x
            w = absD * (x + np.asarray(Labs.T @ x).ravel())
            return w + np.asarray(Labs @ w).ravel()

        c_perm = np.minimum(g * B_times(np.ones(self.n)), B_times(g))
        terms = int(r.max(initial=0) + col_terms.max(initial=0) + 3)
        c_perm *= 1.0 + gamma(terms)  # the products of nonnegative numbers, rounded up
        rows = np.empty(self.n)
        rows[self.perm] = c_perm
        return rows

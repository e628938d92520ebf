"""The MLE objective of generalized RWHEC as a quadratic form (paper Sections 4.4-4.6).

State vector (eq. (44)-(46))::

    x = [t_X1 .. t_XM, t_Y1 .. t_YP, alpha, vec(R_X1) .. vec(R_XM), vec(R_Y1) .. vec(R_YP)]

of length ``12 (M + P) + 1``; for known scale ``alpha`` plays the homogenising variable ``s``
(``s^2 = 1``). ``vec`` is column-major, so with eq. (26)::

    vec(R_A R_X) = (I (x) R_A) vec(R_X),   vec(R_Y R_B) = (R_B^T (x) I) vec(R_Y),
    R_Y t_B = (t_B^T (x) I) vec(R_Y).

(The Kronecker factors printed in eqs. (25) and (36) are the transposes of these; the tests check
``x^T Q x`` against the direct sum of eq. (33), which is what counts.)

The objective ``x^T Q x`` equals ``1/2 sum_e sum_i J_ijk`` of eq. (33)::

    J = 1/sigma^2 |R_A t_X + alpha t_A - t_Y - R_Y t_B|^2 + kappa |R_A R_X - R_Y R_B|_F^2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .lie import vec
from .problem import Problem

__all__ = [
    "StateLayout",
    "build_cost_matrix",
    "build_cost_matrices",
    "direct_cost",
    "ReducedCost",
    "reduce_cost",
    "pack_state",
]


@dataclass(frozen=True)
class StateLayout:
    """Index layout of the state vector ``x`` of eq. (44) for ``M`` X- and ``P`` Y-frames."""

    M: int
    P: int

    @property
    def n_frames(self) -> int:
        return self.M + self.P

    @property
    def n_t(self) -> int:
        """Number of translation entries, ``3 (M + P)``."""
        return 3 * self.n_frames

    @property
    def alpha(self) -> int:
        """Index of ``alpha`` / ``s``."""
        return self.n_t

    @property
    def r0(self) -> int:
        """Index of the first rotation entry."""
        return self.n_t + 1

    @property
    def size(self) -> int:
        return 12 * self.n_frames + 1

    def t_slice(self, frame: int) -> slice:
        """Translation of global frame ``frame`` (X: ``j``, Y: ``M + k``)."""
        return slice(3 * frame, 3 * frame + 3)

    def r_slice(self, frame: int) -> slice:
        """``vec(R)`` of global frame ``frame``."""
        return slice(self.r0 + 9 * frame, self.r0 + 9 * frame + 9)


def _edge_blocks(
    A: np.ndarray, B: np.ndarray, sigma: np.ndarray, kappa: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Summed 25x25 blocks of one edge: ``1/2 sum_i (M_t^T M_t / sigma_i^2 + kappa_i M_R^T M_R)``
    and its rotation-only part ``1/2 sum_i kappa_i M_R^T M_R``.

    Local variable order: ``[t_X (3), t_Y (3), alpha (1), r_X (9), r_Y (9)]``. With
    ``M_R = [I (x) R_A, -(R_B^T (x) I)]`` on ``(r_X, r_Y)``, ``M_R^T M_R`` has identity diagonal
    blocks and off-diagonal ``-(R_B^T (x) R_A^T)`` (cf. eq. (36)); the translation rows
    ``M_t = [R_A, -I, t_A, 0, -(t_B^T (x) I)]`` (cf. eq. (28)) are weighted and reduced by one
    matrix product.
    """
    N = A.shape[0]
    RA, tA = A[:, :3, :3], A[:, :3, 3]
    RB, tB = B[:, :3, :3], B[:, :3, 3]
    rot = np.zeros((25, 25))
    half_k = 0.5 * kappa
    ksum = float(half_k.sum())
    C = np.einsum("n,nba,nji->aibj", half_k, RB, RA).reshape(9, 9)  # sum k/2 R_B^T (x) R_A^T
    rot[7:16, 7:16] = ksum * np.eye(9)
    rot[16:25, 16:25] = ksum * np.eye(9)
    rot[7:16, 16:25] = -C
    rot[16:25, 7:16] = -C.T
    # translation rows on the 16 columns [t_X, t_Y, alpha, r_Y]
    Mt = np.zeros((N, 3, 16))
    Mt[:, :, 0:3] = RA
    Mt[:, 0, 3] = Mt[:, 1, 4] = Mt[:, 2, 5] = -1.0
    Mt[:, :, 6] = tA
    for c in range(3):  # -(t_B^T (x) I): column block c of vec(R_Y) multiplies t_B[c]
        Mt[:, 0, 7 + 3 * c] = -tB[:, c]
        Mt[:, 1, 8 + 3 * c] = -tB[:, c]
        Mt[:, 2, 9 + 3 * c] = -tB[:, c]
    Mt *= np.sqrt(0.5 / sigma**2)[:, None, None]
    Mt2 = Mt.reshape(3 * N, 16)
    G = Mt2.T @ Mt2
    cols = np.r_[0:7, 16:25]
    full = rot.copy()
    full[np.ix_(cols, cols)] += G
    return full, rot


def _local_to_global(layout: StateLayout, xi: np.ndarray, yi: np.ndarray) -> np.ndarray:
    """Global indices (E, 25) of the local variables of edges with X ``xi`` and Y ``yi``."""
    M = layout.M
    E = xi.shape[0]
    idx = np.empty((E, 25), dtype=int)
    three = np.arange(3)
    nine = np.arange(9)
    idx[:, 0:3] = 3 * xi[:, None] + three
    idx[:, 3:6] = 3 * (M + yi[:, None]) + three
    idx[:, 6] = layout.alpha
    idx[:, 7:16] = layout.r0 + 9 * xi[:, None] + nine
    idx[:, 16:25] = layout.r0 + 9 * (M + yi[:, None]) + nine
    return idx


#: Problems whose state has at most this many entries get dense cost matrices (faster to build
#: and use than scipy.sparse at that size); larger ones sparse CSR.
DENSE_MAX_SIZE = 601


def build_cost_matrices(
    problem: Problem, *, dense: bool | None = None
) -> tuple[np.ndarray | sp.csr_matrix, np.ndarray | sp.csr_matrix]:
    """``Q`` of Problem 5 (eq. (42)) and its rotation-only part, size ``12 (M + P) + 1``.

    Built in time linear in the number of pairs: per-pair rows are weighted and reduced by one
    matrix product per edge, and the 25x25 edge blocks are scattered once. The rotation-only
    part keeps the ``J_R`` terms alone (the kappa-weighted rotation-only Problem 8).
    ``dense=None`` chooses dense arrays up to :data:`DENSE_MAX_SIZE` and sparse CSR above.
    """
    layout = StateLayout(problem.M, problem.P)
    pairs = [_edge_blocks(e.A, e.B, e.sigma, e.kappa) for e in problem.edges]
    full = np.stack([p[0] for p in pairs])  # (E, 25, 25)
    rot = np.stack([p[1] for p in pairs])
    full = 0.5 * (full + np.swapaxes(full, 1, 2))  # exact symmetry
    rot = 0.5 * (rot + np.swapaxes(rot, 1, 2))
    idx = _local_to_global(layout, problem.edge_x, problem.edge_y)
    if dense is None:
        dense = layout.size <= DENSE_MAX_SIZE
    n = layout.size
    if dense:
        Q = np.zeros((n, n))
        Qr = np.zeros((n, n))
        for e_idx in range(idx.shape[0]):
            ix = np.ix_(idx[e_idx], idx[e_idx])
            Q[ix] += full[e_idx]
            Qr[ix] += rot[e_idx]
        return Q, Qr
    rows = np.repeat(idx[:, :, None], 25, axis=2).ravel()
    cols = np.repeat(idx[:, None, :], 25, axis=1).ravel()
    Q = sp.coo_matrix((full.ravel(), (rows, cols)), shape=(n, n)).tocsr()
    Qr = sp.coo_matrix((rot.ravel(), (rows, cols)), shape=(n, n)).tocsr()
    return Q, Qr


def build_cost_matrix(problem: Problem, *, with_translation: bool = True) -> sp.csr_matrix:
    """Sparse symmetric ``Q`` of Problem 5 (eq. (42)), size ``12 (M + P) + 1``; with
    ``with_translation=False`` only its rotation terms (see :func:`build_cost_matrices`)."""
    Q, Q_rot = build_cost_matrices(problem, dense=False)
    return Q if with_translation else Q_rot


def pack_state(
    layout: StateLayout, X: np.ndarray, Y: np.ndarray, alpha: float = 1.0
) -> np.ndarray:
    """State vector of eq. (44) from transforms ``X`` (M, 4, 4), ``Y`` (P, 4, 4) and ``alpha``.

    For unknown scale the translations enter as ``alpha t`` (eq. (22)).
    """
    T = np.concatenate([np.asarray(X, float), np.asarray(Y, float)])
    x = np.empty(layout.size)
    x[: layout.n_t] = alpha * T[:, :3, 3].ravel()
    x[layout.alpha] = alpha
    x[layout.r0 :] = vec(T[:, :3, :3]).ravel()
    return x


def direct_cost(problem: Problem, X: np.ndarray, Y: np.ndarray, alpha: float = 1.0) -> float:
    """``1/2 sum J_ijk`` of eq. (33) evaluated directly, with metric translations of ``X, Y``.

    ``X`` (M, 4, 4), ``Y`` (P, 4, 4); for unknown scale the residual uses ``alpha t_X``,
    ``alpha t_A`` and ``alpha t_Y`` (eq. (22)).
    """
    X = np.asarray(X, float)
    Y = np.asarray(Y, float)
    total = 0.0
    for e, j, k in zip(problem.edges, problem.edge_x, problem.edge_y, strict=False):
        RA, tA = e.A[:, :3, :3], e.A[:, :3, 3]
        RB, tB = e.B[:, :3, :3], e.B[:, :3, 3]
        RX, tX = X[j, :3, :3], X[j, :3, 3]
        RY, tY = Y[k, :3, :3], Y[k, :3, 3]
        rt = alpha * (RA @ tX + tA - tY) - tB @ RY.T
        rR = RA @ RX - RY @ RB
        total += 0.5 * np.sum((rt**2).sum(axis=1) / e.sigma**2)
        total += 0.5 * np.sum(e.kappa * (rR**2).sum(axis=(1, 2)))
    return float(total)


@dataclass(frozen=True)
class ReducedCost:
    """The Schur reduction of ``Q`` onto the rotations (eq. (47)-(48)).

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
    """

    Qr: np.ndarray
    recover: np.ndarray
    unknown_scale: bool


def reduce_cost(Q: sp.spmatrix, layout: StateLayout, unknown_scale: bool) -> ReducedCost:
    """Eliminate translations (and ``alpha`` for unknown scale) from ``Q`` (eq. (47)-(48)).

    Uses the pseudo-inverse of the eliminated block, as the paper does (generalized Schur
    complement), so rank-deficient translation blocks (unidentifiable translations) still give
    the minimum-norm recovery.
    """
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
        Qee_pinv = np.linalg.pinv(Qee, rcond=1e-12, hermitian=True)
        G = -np.asarray((Qek.T @ Qee_pinv).T)  # -pinv(Qee) Qek, pinv symmetric
        Qr_keep = Qkk + np.asarray(Qek.T @ G)
    else:
        Qd = np.asarray(Q, dtype=float)
        Qee = Qd[np.ix_(elim, elim)]
        Qek = Qd[np.ix_(elim, keep)]
        Qkk = Qd[np.ix_(keep, keep)]
        Qee_pinv = np.linalg.pinv(Qee, rcond=1e-12, hermitian=True)
        G = -Qee_pinv @ Qek
        Qr_keep = Qkk + Qek.T @ G
    Qr_keep = 0.5 * (Qr_keep + Qr_keep.T)
    nr = 9 * layout.n_frames
    Qr = np.zeros((nr + 1, nr + 1))
    recover = np.zeros((nt + 1, nr + 1))
    if unknown_scale:
        Qr[:nr, :nr] = Qr_keep
        recover[:, :nr] = G
    else:
        Qr[:, :] = Qr_keep
        recover[:nt, :] = G
        recover[nt, nr] = 1.0
    return ReducedCost(Qr=Qr, recover=recover, unknown_scale=unknown_scale)

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

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..lie import vec
from ..problem import Problem

__all__ = [
    "StateLayout",
    "build_cost_matrix",
    "build_cost_matrices",
    "edge_blocks",
    "direct_cost",
    "direct_cost_error",
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


def _translation_rows(A: np.ndarray, B: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """The weighted translation rows ``M_t / (sqrt(2) sigma_i)`` (N, 3, 16) of ``N`` pairs on the
    16 columns ``[t_X, t_Y, alpha, r_Y]`` (see :func:`_edge_blocks`)."""
    N = A.shape[0]
    tA, tB = A[:, :3, 3], B[:, :3, 3]
    Mt = np.zeros((N, 3, 16))
    Mt[:, :, 0:3] = A[:, :3, :3]
    Mt[:, 0, 3] = Mt[:, 1, 4] = Mt[:, 2, 5] = -1.0
    Mt[:, :, 6] = tA
    for c in range(3):  # -(t_B^T (x) I): column block c of vec(R_Y) multiplies t_B[c]
        Mt[:, 0, 7 + 3 * c] = -tB[:, c]
        Mt[:, 1, 8 + 3 * c] = -tB[:, c]
        Mt[:, 2, 9 + 3 * c] = -tB[:, c]
    Mt *= np.sqrt(0.5 / np.asarray(sigma, dtype=float) ** 2)[:, None, None]
    return Mt


def _edge_sums(
    A: np.ndarray, B: np.ndarray, sigma: np.ndarray, kappa: np.ndarray,
    counts: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The per-edge sums behind :func:`_edge_blocks`: ``G`` (E, 16, 16), ``sum_i M_t^T M_t /
    (2 sigma_i^2)`` on the columns ``[t_X, t_Y, alpha, r_Y]``; ``K`` (E, 9, 9), ``sum_i
    kappa_i/2 R_B^T (x) R_A^T`` with ``K[b a, j i] = sum k/2 RB[b, a] RA[j, i]``; ``ksum`` (E,),
    ``sum_i kappa_i / 2``. Sums over pairs: those of two runs of an edge's pairs add up to the
    sums of both (:class:`EdgeBlockCache`). ``counts`` (E,) may hold zeros."""
    N = A.shape[0]
    counts = np.array([N]) if counts is None else np.asarray(counts, dtype=int)
    E = counts.shape[0]
    ends = np.cumsum(counts)
    starts = ends - counts
    RA, RB = A[:, :3, :3], B[:, :3, :3]
    half_k = 0.5 * np.asarray(kappa, dtype=float)
    Mt2 = _translation_rows(A, B, sigma).reshape(3 * N, 16)
    # sum k/2 R_B^T (x) R_A^T per edge: K[b a, j i] = sum k/2 RB[b, a] RA[j, i]
    U = (RB * half_k[:, None, None]).reshape(N, 9)
    V = RA.reshape(N, 9)
    G = np.empty((E, 16, 16))
    K = np.empty((E, 9, 9))
    ksum = np.empty(E)
    for e in range(E):
        a, b = starts[e], ends[e]
        m = Mt2[3 * a: 3 * b]
        np.dot(m.T, m, out=G[e])
        np.dot(U[a:b].T, V[a:b], out=K[e])
        ksum[e] = half_k[a:b].sum()
    return G, K, ksum


def _edge_sums_few(
    A: np.ndarray, B: np.ndarray, sigma: np.ndarray, kappa: np.ndarray, counts: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_edge_sums` for few pairs over many edges (``counts`` (E,) all >= 1): per-pair
    products summed per edge by ``reduceat`` instead of one matrix product per edge (the
    Python loop over the edges costs more than the sums then). Temporaries of ~2.7 kB per pair:
    meant for the new pairs of :class:`~rwhec_ros.core.model.edge_cache.EdgeBlockCache`."""
    counts = np.asarray(counts, dtype=int)
    starts = np.cumsum(counts) - counts
    N = A.shape[0]
    RA, RB = A[:, :3, :3], B[:, :3, :3]
    half_k = 0.5 * np.asarray(kappa, dtype=float)
    Mt = _translation_rows(A, B, sigma)
    G = np.add.reduceat(np.swapaxes(Mt, 1, 2) @ Mt, starts, axis=0)
    U = (RB * half_k[:, None, None]).reshape(N, 9)
    K = np.add.reduceat(U[:, :, None] * RA.reshape(N, 1, 9), starts, axis=0)
    return G, K, np.add.reduceat(half_k, starts)


def _blocks_from_sums(G: np.ndarray, K: np.ndarray, ksum: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The 25x25 blocks ``(full, rot)`` (E, 25, 25) of :func:`_edge_blocks` from the sums of
    :func:`_edge_sums`."""
    E = G.shape[0]
    C = K.reshape(E, 3, 3, 3, 3).transpose(0, 2, 4, 1, 3).reshape(E, 9, 9)  # [a i, b j]
    rot = np.zeros((E, 25, 25))
    rot.reshape(E, 625)[:, _ROT_DIAG] = ksum[:, None]
    rot[:, 7:16, 16:25] = -C
    rot[:, 16:25, 7:16] = -np.swapaxes(C, 1, 2)
    full = rot.copy()  # G lives on the columns [t_X, t_Y, alpha] (0:7) and r_Y (16:25)
    full[:, 0:7, 0:7] += G[:, :7, :7]
    full[:, 0:7, 16:25] += G[:, :7, 7:]
    full[:, 16:25, 0:7] += G[:, 7:, :7]
    full[:, 16:25, 16:25] += G[:, 7:, 7:]
    return full, rot


def _edge_blocks(
    A: np.ndarray, B: np.ndarray, sigma: np.ndarray, kappa: np.ndarray,
    counts: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Summed 25x25 blocks of ``E`` edges: ``1/2 sum_i (M_t^T M_t / sigma_i^2 + kappa_i M_R^T
    M_R)`` and its rotation-only part ``1/2 sum_i kappa_i M_R^T M_R``.

    ``A, B`` (N, 4, 4) and ``sigma, kappa`` (N,): the pairs of all edges concatenated edge by
    edge, ``counts`` (E,) the pairs of each edge (default: one edge); returns two arrays (E, 25,
    25). Local variable order: ``[t_X (3), t_Y (3), alpha (1), r_X (9), r_Y (9)]``. With ``M_R =
    [I (x) R_A, -(R_B^T (x) I)]`` on ``(r_X, r_Y)``, ``M_R^T M_R`` has identity diagonal blocks
    and off-diagonal ``-(R_B^T (x) R_A^T)`` (cf. eq. (36)); the translation rows ``M_t = [R_A,
    -I, t_A, 0, -(t_B^T (x) I)]`` (cf. eq. (28)) are weighted once for all pairs, then each
    edge's stacked rows and its kappa-weighted rotations are reduced by one matrix product each
    (the per-pair arrays are formed once, whatever the number of edges).
    """
    return _blocks_from_sums(*_edge_sums(A, B, sigma, kappa, counts))


#: Flat indices of the rotation diagonal (local variables 7..24) of a 25 x 25 edge block.
_ROT_DIAG = np.arange(7, 25) * 26


def _all_edge_blocks(problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_edge_blocks` of every edge of ``problem`` (E, 25, 25), in edge order."""
    if not problem.edges:
        return np.zeros((0, 25, 25)), np.zeros((0, 25, 25))
    counts = np.array([e.n for e in problem.edges])
    cat = np.concatenate
    return _edge_blocks(cat([e.A for e in problem.edges]), cat([e.B for e in problem.edges]),
                        cat([e.sigma for e in problem.edges]),
                        cat([e.kappa for e in problem.edges]), counts)


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


def edge_blocks(problem: Problem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The summed 25x25 blocks of every edge, exactly symmetric: ``(full, rot, idx)`` with
    ``full`` and its rotation-only part ``rot`` (E, 25, 25) and ``idx`` (E, 25) the indices of
    the local variables ``[t_X, t_Y, alpha, r_X, r_Y]`` in the state of eq. (44): ``Q`` is the sum
    of ``full[e]`` scattered to ``idx[e] x idx[e]`` (see :func:`build_cost_matrices`).

    ``problem.precomputed_blocks`` (e.g. from
    :class:`~rwhec_ros.core.model.edge_cache.EdgeBlockCache`)
    is returned as it is when set (after a check of its shapes and indices)."""
    pre = problem.precomputed_blocks
    if pre is not None:
        return _checked_blocks(problem, StateLayout(problem.M, problem.P), pre)
    return _finished_blocks(problem, *_all_edge_blocks(problem))


def _edge_indices(problem: Problem) -> np.ndarray:
    """:func:`_local_to_global` of ``problem``'s edges (E, 25), formed once per problem (its
    edges never change) and read-only."""
    idx = problem.__dict__.get("_edge_state_indices")
    if idx is None:
        idx = _local_to_global(StateLayout(problem.M, problem.P), problem.edge_x,
                               problem.edge_y)
        idx.flags.writeable = False
        problem.__dict__["_edge_state_indices"] = idx
    return idx


def _finished_blocks(problem: Problem, full: np.ndarray, rot: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(full, rot, idx)`` as :func:`edge_blocks` returns them from summed blocks ``full`` and
    ``rot`` (E, 25, 25) of ``problem``'s edges (from :func:`_blocks_from_sums`): ``full`` made
    exactly symmetric (``rot`` is: its diagonal and its two off-diagonal blocks ``-C``,
    ``-C^T`` are placed symmetrically), and the edges' state indices ``idx`` (E, 25)."""
    full = 0.5 * (full + np.swapaxes(full, 1, 2))  # exact symmetry
    return full, rot, _edge_indices(problem)


def _checked_blocks(problem: Problem, layout: StateLayout, blocks: tuple) -> tuple:
    """``blocks`` ``(full, rot, idx)`` if their shapes and indices are those of ``problem``'s
    edges, else ``ValueError`` naming ``precomputed_blocks``."""
    full, rot, idx = blocks
    E = len(problem.edges)
    if full.shape != (E, 25, 25) or rot.shape != (E, 25, 25) or idx.shape != (E, 25) or \
            not (idx is _edge_indices(problem) or np.array_equal(idx, _edge_indices(problem))):
        raise ValueError(f"precomputed_blocks: shapes {full.shape}, {rot.shape}, {idx.shape} or "
                         f"indices do not match the problem's {E} edges")
    return full, rot, idx


#: Problems whose state has at most this many entries get dense cost matrices (faster to build
#: and use than scipy.sparse at that size); larger ones sparse CSR.
DENSE_MAX_SIZE = 601


def build_cost_matrices(
    problem: Problem, *, dense: bool | None = None, with_rotation: bool = True
) -> tuple[np.ndarray | sp.csr_matrix, np.ndarray | sp.csr_matrix | None]:
    """``Q`` of Problem 5 (eq. (42)) and its rotation-only part, size ``12 (M + P) + 1``.

    Built in time linear in the number of pairs: per-pair rows are weighted and reduced by one
    matrix product per edge, and the 25x25 edge blocks are scattered once. The rotation-only
    part keeps the ``J_R`` terms alone (the kappa-weighted rotation-only Problem 8);
    ``with_rotation=False`` returns ``None`` instead (only the closed-form start needs it).
    ``dense=None`` chooses dense arrays up to :data:`DENSE_MAX_SIZE` and sparse CSR above.
    """
    layout = StateLayout(problem.M, problem.P)
    full, rot, idx = edge_blocks(problem)
    if dense is None:
        dense = layout.size <= DENSE_MAX_SIZE
    n = layout.size
    if dense:
        # one scatter-add in edge order (each block's 25 indices are distinct): the same sums
        # as adding the blocks one after the other
        flat = (idx[:, :, None] * n + idx[:, None, :]).ravel()
        Q = np.bincount(flat, weights=full.ravel(), minlength=n * n).reshape(n, n)
        Qr = np.bincount(flat, weights=rot.ravel(), minlength=n * n).reshape(n, n) \
            if with_rotation else None
        return Q, Qr
    rows = np.repeat(idx[:, :, None], 25, axis=2).ravel()
    cols = np.repeat(idx[:, None, :], 25, axis=1).ravel()
    Q = sp.coo_matrix((full.ravel(), (rows, cols)), shape=(n, n)).tocsr()
    Qr = sp.coo_matrix((rot.ravel(), (rows, cols)), shape=(n, n)).tocsr() \
        if with_rotation else None
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
    ``alpha t_A`` and ``alpha t_Y`` (eq. (22)). Every pair's residuals are formed in double
    precision, each pair's term (translation and rotation part together) rounded once more, and
    the pairs' terms summed exactly rounded (``math.fsum``), so the result is accurate to about
    ``u L / r`` relative (translations ``L``, residuals ``r``); :func:`direct_cost_error` gives
    a proven bound, and the certificate's ``p`` is the sum of the two
    (:func:`~rwhec_ros.core.initial.closed_form.primal_cost`).

    The residuals of pair ``i`` are the top three rows of ``A_i X - Y B_i``: ``[R_A R_X -
    R_Y R_B | R_A t_X + t_A - R_Y t_B - t_Y]`` (translations scaled by ``alpha``), formed as
    two batched products ``[R_A | t_A] [X; 0 0 0 1]`` and ``R_Y [R_B | t_B]`` (the measured
    transforms' last rows are not used) and ``t_Y`` subtracted.
    """
    return direct_cost_error(problem, X, Y, alpha, error=False)[0]


def direct_cost_error(problem: Problem, X: np.ndarray, Y: np.ndarray, alpha: float = 1.0, *,
                      error: bool = True) -> tuple[float, float]:
    """``(p, err)``: :func:`direct_cost` ``p`` and a proven bound ``err`` on its rounding,
    ``|p - p_exact| <= err``, where ``p_exact`` is eq. (33) in exact arithmetic on the stored
    ``X``, ``Y``, ``alpha`` and pairs (``err = nan`` with ``error=False``).

    Every residual entry is a dot product of at most four terms followed by one or two
    subtractions, each product operand exact or one rounding (``alpha t``) from its exact
    value, so entry ``(a, b)`` of pair ``i`` is off by at most ``gamma_10`` times
    ``sum_c |[R_A|alpha t_A]_ac| |X_cb| + sum_c |R_Y,ac| |[R_B|t_B]_cb| (+ |alpha t_Y,a|)``.
    By Cauchy-Schwarz the Frobenius norm of those bounds is at most ``gamma_10 (|R_A| |R_X| +
    |R_Y| |R_B|)`` for the rotation residual and ``gamma_10 (|R_A| |alpha t_X| + |alpha t_A| +
    |R_Y| |t_B| + |alpha t_Y|)`` for the translation one (Frobenius and Euclidean norms; a
    pair's ``|[R_A | alpha t_A]|`` stands for both ``|R_A|`` and ``|alpha t_A|``, and
    ``|[R_B | t_B]|`` for both of its parts). With computed residual norms ``rho`` and bounds
    ``e``, the exact term lies within ``1/2 w (2 rho e + e^2)`` of the one from the computed
    residuals (``w`` the weight: ``1 / sigma^2`` or ``kappa``); squaring, the weights and the
    exactly rounded sum add ``gamma_20 p``. The bound's own evaluation (positive terms, a few
    roundings each) is covered by a factor ``1 + 1e-6``. A few array operations per pair: no
    second pass over the products.
    """
    from ..numerics.verified import gamma

    X = np.asarray(X, float)
    Y = np.asarray(Y, float)
    edges = problem.edges
    if not edges:
        return 0.0, 0.0
    a = float(alpha)
    counts = [e.n for e in edges]
    A3 = np.concatenate([e.A[:, :3, :] for e in edges])  # [R_A | t_A] (N, 3, 4)
    RBt = np.concatenate([e.B[:, :3, :] for e in edges])  # [R_B | t_B] (N, 3, 4)
    if a != 1.0:
        A3[:, :, 3] *= a
    Xh = np.zeros((X.shape[0], 4, 4))  # exact homogeneous X with alpha t_X
    Xh[:, :3, :3] = X[:, :3, :3]
    Xh[:, :3, 3] = a * X[:, :3, 3]
    Xh[:, 3, 3] = 1.0
    tY = a * Y[problem.edge_y, :3, 3]  # (E, 3)
    D = (np.matmul(A3, np.repeat(Xh[problem.edge_x], counts, axis=0))
         - np.matmul(np.repeat(Y[problem.edge_y, :3, :3], counts, axis=0), RBt))
    D[:, :, 3] -= np.repeat(tY, counts, axis=0)
    rt, rR = D[:, :, 3], D[:, :, :3]
    sigma = np.concatenate([e.sigma for e in edges])
    kappa = np.concatenate([e.kappa for e in edges])
    qt = np.einsum("ni,ni->n", rt, rt)
    qR = np.einsum("nij,nij->n", rR, rR)
    w = 1.0 / sigma**2
    terms = 0.5 * (qt * w + kappa * qR)
    p = float(math.fsum(terms.tolist()))  # Python floats: the same sum, faster
    if not error:
        return p, float("nan")
    # per pair |[R_A | alpha t_A]| and |[R_B | t_B]| (Frobenius), each bounding both of its
    # parts; per edge |R_X|, |alpha t_X|, |R_Y|, |alpha t_Y|, repeated to the edge's pairs
    nA = np.sqrt(np.einsum("nij,nij->n", A3, A3))
    nB = np.sqrt(np.einsum("nij,nij->n", RBt, RBt))
    Xe = Xh[problem.edge_x, :3, :]
    frames = np.empty((len(edges), 4))
    frames[:, 0] = np.sqrt(np.einsum("eij,eij->e", Xe[:, :, :3], Xe[:, :, :3]))
    frames[:, 1] = np.sqrt(np.einsum("ei,ei->e", Xe[:, :, 3], Xe[:, :, 3]))
    Ye = Y[problem.edge_y, :3, :3]
    frames[:, 2] = np.sqrt(np.einsum("eij,eij->e", Ye, Ye))
    frames[:, 3] = np.sqrt(np.einsum("ei,ei->e", tY, tY))
    nX, ntX, nY, ntY = np.repeat(frames, counts, axis=0).T
    g = gamma(10)
    eR = g * (nA * nX + nY * nB)
    et = g * (nA * (ntX + 1.0) + nY * nB + ntY)
    spread = 0.5 * (w * et * (2.0 * np.sqrt(qt) + et) + kappa * eR * (2.0 * np.sqrt(qR) + eR))
    # (a pairwise sum of positive terms: its rounding is far inside the factor 1 + 1e-6)
    err = (float(spread.sum()) + gamma(20) * abs(p)) * (1.0 + 1e-6)
    if not np.isfinite(err):
        err = float("inf")
    return p, err

"""The MLE cost of large problems on the unreduced variables: sparse, never a dense ``Q'``.

The reduced cost ``Q'`` of eq. (48) couples every pair of cameras that share a target (one target
seen by 1,000 cameras: a dense 9,001 x 9,001 matrix), while ``Q`` of eq. (42) has one 25 x 25
block per edge. The large-problem path of ``fast`` therefore works on

    z = [f; y],   f = [t (3 n); alpha (unknown scale only); u (gauge, see below)],
                  y = [vec R_1 .. vec R_n; s],

with the cost ``z^T Q_z z`` (``Q`` of eq. (42) with its indices permuted; for unknown scale ``s``
is a new variable with zero cost, as in the ``full`` SDP form of
:mod:`rwhec_ros.core.solve`). The *free* variables ``f`` are unconstrained; the translations are
recovered from the rotations by a sparse ``L D L^T`` solve, ``f = -Q_ff^{-1} Q_fy y``
(:class:`FullForm`), the sparse counterpart of eq. (47).

**Gauge penalty without fill.** Unobservable translation directions are fixed as on the dense
path (:mod:`rwhec_ros.core.model.gauge`) by the penalty ``rho |G t - b h|^2``, whose matrix is dense
over the translations of every frame the direction involves. Here it is represented exactly by
auxiliary free variables ``u`` on a 4-ary tree over the frames (:func:`penalty_tree`): a node
``v`` carries ``u_v`` (``k``-vector) and the spring ``rho_v |u_v - sum_{child nodes c} u_c -
sum_{child frames f} G_f t_f|^2``, the root the spring ``rho_end |u_root - b h|^2``. Minimising
over ``u`` leaves ``rho_eff |G t - b h|^2`` with ``1 / rho_eff = sum_v 1 / rho_v + 1 / rho_end``
(springs in series: the slacks of all springs add up to ``G t - b h``), and weights with
``sum 1 / rho = 1 / rho`` give ``rho_eff = rho``: the same problem as the dense path, with ``O(n)``
nonzeros. (Weights inversely proportional to the expected size of ``u_v`` keep the rounding
analysis of the certificate, which grows with ``sum_v rho_v |u_v|^2``, within a ``log^2 n``
factor of that of the translations themselves; see :func:`penalty_tree`.) ``u_v`` is stored
scaled by ``sqrt(rho_v / rho)`` so that every entry is of the order of ``rho``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..numerics.sparse_ldl import FactorizationError, SparseLDL, upper_with_diagonal
from ..numerics.verified import lanczos_start
from ..problem import Problem
from .cost import StateLayout, edge_blocks
from .estimate import Estimate, rotations_from_vector
from .gauge import GaugeFix

__all__ = ["TREE_ARITY", "PRUNE_REL", "pruned_gauge", "penalty_tree", "translation_block",
           "FullForm", "build_full_form"]

#: Children per node of the gauge penalty's tree.
TREE_ARITY = 4


#: Frames whose part of ``G`` is below this fraction of the largest are left out of the tree (and
#: of the penalty, see :func:`pruned_gauge`): with a prior on one frame, ``G`` is that frame's row
#: plus rounding noise elsewhere.
PRUNE_REL = 1e-12


def pruned_gauge(gauge: GaugeFix, n: int) -> GaugeFix:
    """``gauge`` with the columns of ``G`` of negligible frames set to zero (:data:`PRUNE_REL`);
    the sparse path certifies, and evaluates ``p`` with, this penalty."""
    if not gauge.has_penalty:
        return gauge
    mass = np.linalg.norm(gauge.G.reshape(-1, n, 3), axis=(0, 2))
    drop = mass <= PRUNE_REL * mass.max(initial=0.0)
    G = gauge.G.reshape(-1, n, 3).copy()
    G[:, drop, :] = 0.0
    return replace(gauge, G=G.reshape(gauge.G.shape))


def _tree(gauge: GaugeFix, n: int) -> tuple[list, np.ndarray]:
    """The springs ``(node, child nodes, child frames)`` of the 4-ary tree over the frames with
    a non-zero part of ``G``, and the masses ``m_v`` of the nodes (sum of ``|G_f|`` below)."""
    mass_f = np.linalg.norm(gauge.G.reshape(-1, n, 3), axis=(0, 2))
    level = [("f", int(f)) for f in np.flatnonzero(mass_f > 0)]
    springs, mass = [], []
    while level:
        parents = []
        for start in range(0, len(level), TREE_ARITY):
            kids = level[start:start + TREE_ARITY]
            frames = [i for kind, i in kids if kind == "f"]
            nodes = [i for kind, i in kids if kind == "n"]
            parents.append(("n", len(mass)))
            springs.append((len(mass), nodes, frames))
            mass.append(float(mass_f[frames].sum()) + sum(mass[c] for c in nodes))
        level = parents if len(parents) > 1 else []
    return springs, np.array(mass)


def penalty_tree(gauge: GaugeFix, n: int, t_index: np.ndarray, h_index: int, aux_offset: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """The penalty ``rho |G t - b h|^2`` as springs on a tree of auxiliary variables (module
    docstring), as COO triplets ``(rows, cols, values)`` in ``z`` and the number of auxiliary
    variables.

    The spring of node ``v`` gets ``rho_v = rho M / m_v`` and the root's end spring ``rho M /
    m_root`` (``m`` the masses of :func:`_tree`, ``M`` their sum with ``m_root`` once more), so
    that ``sum 1 / rho_v = 1 / rho``: weights inversely proportional to the expected size of the
    partial sums ``u_v``, the choice that minimises ``sum_v rho_v |u_v|^2`` (the size of the
    rounding analysis' terms) for that size.

    Parameters
    ----------
    gauge : GaugeFix
        ``G`` (k, 3 n), ``b`` (k,), ``rho``.
    n : int
        Frames.
    t_index : ndarray of int, shape (3 n,)
        Position in ``z`` of each translation entry (``alpha t`` for unknown scale).
    h_index : int
        Position of the homogenising variable ``h`` (``s``, or ``alpha`` for unknown scale).
    aux_offset : int
        Position of the first auxiliary variable.
    """
    k = gauge.G.shape[0]
    springs, mass = _tree(gauge, n) if k else ([], np.zeros(0))
    if not springs:
        return np.zeros(0, int), np.zeros(0, int), np.zeros(0), 0
    root = len(mass) - 1
    M = float(mass.sum() + mass[root])
    rho_v = gauge.rho * M / mass
    rho_end = gauge.rho * M / mass[root]
    scal = np.sqrt(gauge.rho / rho_v)  # u_v = scal_v * (stored variable)
    rows, cols, vals = [], [], []

    def add(weight: float, idx: list[np.ndarray], coef: list[np.ndarray]) -> None:
        ii = np.concatenate(idx)
        cc = np.concatenate(coef)
        rows.append(np.repeat(ii, ii.size))
        cols.append(np.tile(ii, ii.size))
        vals.append(weight * np.outer(cc, cc).ravel())

    for v, nodes, frames in springs:
        for j in range(k):
            idx = [np.array([aux_offset + k * v + j])]
            coef = [np.array([scal[v]])]
            for c in nodes:
                idx.append(np.array([aux_offset + k * c + j]))
                coef.append(np.array([-scal[c]]))
            for f in frames:
                idx.append(t_index[3 * f: 3 * f + 3])
                coef.append(-gauge.G[j, 3 * f: 3 * f + 3])
            add(rho_v[v], idx, coef)
    for j in range(k):
        add(rho_end, [np.array([aux_offset + k * root + j, h_index])],
            [np.array([scal[root], -gauge.b[j]])])
    return (np.concatenate(rows), np.concatenate(cols), np.concatenate(vals), k * len(mass))


def translation_block(problem: Problem, blocks: tuple | None = None) -> sp.csr_matrix:
    """``Q`` of eq. (42) (state order, unscaled) with only its translation-and-``alpha`` block
    filled: what :func:`~rwhec_ros.core.model.gauge.find_unobservable_directions` reads, without
    assembling the rest."""
    full, _, idx = blocks if blocks is not None else edge_blocks(problem)
    layout = StateLayout(problem.M, problem.P)
    loc = idx[:, :7]
    rows = np.repeat(loc[:, :, None], 7, axis=2).ravel()
    cols = np.repeat(loc[:, None, :], 7, axis=1).ravel()
    return sp.csr_matrix((full[:, :7, :7].ravel(), (rows, cols)),
                         shape=(layout.size, layout.size))


@dataclass
class FullForm:
    """The cost ``z^T Q z`` on the unreduced ``z = [f; y]`` (module docstring), unscaled.

    Attributes
    ----------
    problem : Problem
    Q : scipy.sparse.csr_matrix, shape (size, size)
        Exactly symmetric (the symmetric matrix its upper triangle defines).
    L_rot : scipy.sparse.csr_matrix, shape (9 n, 9 n)
        The kappa-weighted rotation-only cost on ``vec R`` (closed-form start).
    n_free : int
        Free variables ``f`` (translations, ``alpha`` for unknown scale, gauge auxiliaries).
    n_aux : int
        Gauge auxiliaries (0 without unobservable directions).
    t_shift : ndarray, shape (3 n,), optional
        ``t0`` of the change of variables ``t = t' + t0 h`` (``h = s``, or ``alpha`` for unknown
        scale) with ``G t0 = b`` that removes the prior's constant from the gauge penalty: ``z``
        holds ``t'`` (see :func:`build_full_form`).
    """

    problem: Problem
    Q: sp.csr_matrix
    L_rot: sp.csr_matrix
    n_free: int
    n_aux: int
    t_shift: np.ndarray | None = None
    _ff: SparseLDL | None = field(default=None, repr=False)
    _Qfy: sp.csr_matrix | None = field(default=None, repr=False)

    @property
    def n(self) -> int:
        return self.problem.n_frames

    @property
    def size(self) -> int:
        return self.Q.shape[0]

    @property
    def n_y(self) -> int:
        """``9 n + 1``: the constrained variables (rotations and ``s``)."""
        return 9 * self.n + 1

    def factor_free(self) -> SparseLDL:
        """The ``L D L^T`` factorisation of ``Q_ff`` (built once). Raises
        :class:`~rwhec_ros.core.numerics.sparse_ldl.FactorizationError` when ``Q_ff`` is not
        positive
        definite (translations the gauge analysis did not catch)."""
        if self._ff is None:
            nf = self.n_free
            factor = SparseLDL(upper_with_diagonal(self.Q[:nf, :nf]))
            if not factor.positive_definite:
                raise FactorizationError(f"the translation block has {factor.n_negative} "
                                         "negative pivots (translations not determined)")
            self._ff = factor
            self._Qfy = self.Q[:nf, nf:].tocsr()
        return self._ff

    def y_of(self, R: np.ndarray) -> np.ndarray:
        """``y = [vec R_1 .. vec R_n; 1]`` for rotations ``R`` (n, 3, 3) (``vec`` column-major)."""
        return np.concatenate([np.swapaxes(R, 1, 2).reshape(-1), [1.0]])

    def free_part(self, y: np.ndarray) -> np.ndarray:
        """The optimal free variables for ``y``: ``-Q_ff^{-1} Q_fy y`` (eq. (47))."""
        factor = self.factor_free()
        return -factor.solve(self._Qfy @ y)

    def state(self, R: np.ndarray) -> np.ndarray:
        """``z`` with optimal free variables for rotations ``R``."""
        y = self.y_of(R)
        return np.concatenate([self.free_part(y), y])

    def estimate(self, R: np.ndarray) -> Estimate:
        """Translations and scale for rotations ``R`` and the cost ``z^T Q z`` (the counterpart of
        :func:`~rwhec_ros.core.initial.closed_form.estimate_from_rotations`)."""
        n = self.n
        z = self.state(R)
        cost = float(z @ (self.Q @ z))
        alpha = float(z[3 * n]) if self.problem.unknown_scale else 1.0
        t_alpha = z[: 3 * n] + (0.0 if self.t_shift is None else self.t_shift * alpha)
        t_alpha = t_alpha.reshape(n, 3)
        t = t_alpha / alpha if abs(alpha) > 1e-12 else t_alpha
        return Estimate(R=np.asarray(R, float), t=t, alpha=alpha, cost=cost)

    def closed_form_rotations(self) -> np.ndarray:
        """Rotations from the null vector of the rotation-only cost (cf.
        :func:`~rwhec_ros.core.initial.closed_form.closed_form_estimate`), by shift-invert Lanczos
        on a sparse factorisation. When the smallest eigenvalues are nearly equal (within 10 times
        the smallest: rotations about one axis leave the rotation-only cost with a near-degenerate
        null space, whose Lanczos vector is then arbitrary), each of their eigenvectors is
        tried and the one with the lowest cost (translations at their optimum) is kept."""
        L = self.L_rot
        d = L.shape[0]
        shift = 1e-9 * float(abs(L).max())
        factor = SparseLDL(upper_with_diagonal(L + shift * sp.eye(d)))
        op = spla.LinearOperator((d, d), matvec=factor.solve, dtype=float)
        w, V = spla.eigsh(L, k=min(4, d - 1), sigma=-shift, which="LM", OPinv=op,
                          v0=lanczos_start(d))
        order = np.argsort(w)
        w, V = w[order], V[:, order]
        near = np.flatnonzero(w <= 10.0 * max(w[0], 0.0) + shift)
        best, best_cost = None, np.inf
        for i in near if near.size > 1 else [0]:
            R, _ = rotations_from_vector(V[:, i], self.n)
            cost = self.estimate(R).cost if near.size > 1 else 0.0
            if cost < best_cost:
                best, best_cost = R, cost
        return best


def build_full_form(problem: Problem, gauge: GaugeFix, blocks: tuple | None = None) -> FullForm:
    """Assemble :class:`FullForm` from the edge blocks
    (:func:`~rwhec_ros.core.model.cost.edge_blocks`) and the gauge penalty (:func:`penalty_tree`).

    With priors the penalty ``rho |G t - b h|^2`` has ``b != 0``; the translations are then
    shifted, ``t = t' + t0 h`` with ``G t0 = b``, an invertible change of the free variables for
    each ``h`` (the same problem), so that the penalty on ``t'`` is ``rho |G t'|^2`` and the
    homogenising variable, eliminated last with the longest row of ``L``, does not carry the
    large ``rho |b|^2`` into the rounding bound of the certificate. ``Q`` becomes ``T^T Q T``.
    """
    full, rot, idx = blocks if blocks is not None else edge_blocks(problem)
    layout = StateLayout(problem.M, problem.P)
    n, n_t = problem.n_frames, layout.n_t
    unknown = problem.unknown_scale
    k = gauge.G.shape[0]
    aux_offset = n_t + (1 if unknown else 0)
    # the auxiliaries' count is known before their triplets: one k-vector per tree node
    n_aux = k * len(_tree(gauge, n)[1]) if k else 0
    n_free = aux_offset + n_aux
    size = n_free + 9 * n + 1
    zmap = np.empty(layout.size, dtype=np.int64)  # state index -> z index
    zmap[:n_t] = np.arange(n_t)
    zmap[layout.r0:] = n_free + np.arange(9 * n)
    zmap[layout.alpha] = n_t if unknown else size - 1
    zi = zmap[idx]
    rows = [np.repeat(zi[:, :, None], 25, axis=2).ravel()]
    cols = [np.repeat(zi[:, None, :], 25, axis=1).ravel()]
    vals = [full.ravel()]
    h = n_t if unknown else size - 1
    Q = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(size, size))
    t_shift = np.zeros(n_t)
    if k and np.any(gauge.b != 0.0):
        # t = t' + t0 h with G t0 = b (least norm): the penalty becomes rho |G t'|^2, without the
        # large rho b^2 on the homogenising variable, whose pivot is the last and longest
        t_shift = gauge.G.T @ np.linalg.solve(gauge.G @ gauge.G.T, gauge.b)
        T = sp.identity(size, format="csr") + sp.csr_matrix(
            (t_shift, (np.arange(n_t), np.full(n_t, h))), shape=(size, size))
        Q = (T.T @ Q @ T).tocsr()
        gauge = replace(gauge, b=np.zeros_like(gauge.b))
    if k:
        r_, c_, v_, n_aux_built = penalty_tree(gauge, n, np.arange(n_t), h, aux_offset)
        assert n_aux_built == n_aux
        Q = Q + sp.csr_matrix((v_, (r_, c_)), shape=(size, size))
    U = sp.triu(Q, format="csr")
    Q = (U + sp.triu(U, k=1, format="csr").T).tocsr()  # exactly symmetric
    ri = zi[:, 7:] - n_free
    L_rot = sp.csr_matrix((rot[:, 7:, 7:].ravel(),
                           (np.repeat(ri[:, :, None], 18, axis=2).ravel(),
                            np.repeat(ri[:, None, :], 18, axis=1).ravel())),
                          shape=(9 * n, 9 * n))
    return FullForm(problem, Q, L_rot, n_free, n_aux, t_shift)

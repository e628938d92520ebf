"""Sparsity of the dual certificate ``Z(lambda)`` and the cheapest exact form of the SDP.

Clarabel handles a PSD cone of size ``n`` with a dense ``n(n+1)/2``-square block in its KKT
system, so an interior-point iteration costs about ``sum_c (n_c (n_c + 1) / 2)^3`` over the cones
``c`` (after its chordal decomposition). This module

* splits the frames of the reduced cost ``Q'`` (eq. (48)) into a *hub* and *leaves*
  (:func:`arrow_split`): a leaf is a rotation coupled to no other leaf, only to hub rotations
  and ``s``, which is the case of every X (target) frame, because ``vec(R_X)`` does not enter the
  translation residual (eq. (28)) and so is not coupled by the Schur complement of eq. (48);
* estimates the per-iteration cost of each exact form of Problem 7 -- ``reduced``, ``full`` and
  ``arrow`` -- from the cliques of a chordal extension of its sparsity graph
  (:func:`estimate_form_costs`), so that ``form="auto"`` can pick the cheapest.

Why the arrow form is exact (see :func:`rwhec_ros.core.certify.relaxation.solve_dual_sdp_arrow`):
with ``H`` the hub indices (hub rotations and ``s``), ``Z`` is block-arrow, ``Z = [[D, B], [B^T,
Z_HH]]`` with ``D = blockdiag(D_j)`` over the leaves, and ``Z >= 0`` iff ``D_j >= 0`` and ``Z_HH
- sum_j B_j^T D_j^+ B_j >= 0``. The rows of ``B_j`` (9 x |H|) lie in a space of dimension at most
10 (the row space of the constant coupling ``Q'[leaf j, hub rotations]``, rank <= 9, plus the
``s`` column, the only one that depends on the multipliers), spanned by the orthonormal columns of
``Pi_j``. Hence ``Z >= 0`` iff there are symmetric ``S_j`` ((k_j + 1)^2, k_j <= 9) with::

    [[D_j, B_j Pi_j], [Pi_j^T B_j^T, S_j]] >= 0      and      Z_HH - sum_j Pi_j S_j Pi_j^T >= 0,

(``=>``: take ``S_j = Pi_j^T B_j^T D_j^+ B_j Pi_j``; ``<=``: ``Z`` is the sum of these PSD
matrices embedded). Each leaf cone has size ``9 + k_j + 1 <= 19`` whatever the number of hub
frames the leaf sees, instead of ``9 + 9 deg_j + 1`` in a chordal decomposition.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

__all__ = [
    "ArrowSplit",
    "arrow_split",
    "clique_weights",
    "cone_cost",
    "estimate_form_costs",
    "group_adjacency",
    "elimination_front",
]


@dataclass(frozen=True)
class ArrowSplit:
    """Hub/leaf split of the reduced variable ``z = [vec R_1, ..., vec R_n, s]`` (size ``d``).

    Attributes
    ----------
    hub : ndarray of int, shape (h,)
        Indices of ``z`` in the hub block: the hub rotations, then ``s`` last.
    leaves : tuple of ndarray of int, each shape (9,)
        Indices of ``z`` of each leaf rotation.
    bases : tuple of ndarray, each shape (h, k_j + 1)
        ``Pi_j``: orthonormal columns spanning the hub coordinates leaf ``j`` is coupled to (its
        last column is ``e_s``).
    leaf_frames : ndarray of int
        Frame numbers of the leaves (``vec R_f`` at ``9 f``).
    """

    hub: np.ndarray
    leaves: tuple[np.ndarray, ...]
    bases: tuple[np.ndarray, ...]
    leaf_frames: np.ndarray

    @property
    def cone_sizes(self) -> list[int]:
        """Sizes of the PSD cones of the arrow form: the leaves', then the hub's."""
        return [9 + b.shape[1] for b in self.bases] + [len(self.hub)]


def _frame_blocks(Q: np.ndarray, n: int) -> np.ndarray:
    """(n, n) bool: rotation blocks ``Q[9a:9a+9, 9b:9b+9]`` with a nonzero entry (a != b)."""
    R = (np.asarray(Q)[: 9 * n, : 9 * n] != 0.0).reshape(n, 9, n, 9).any(axis=(1, 3))
    np.fill_diagonal(R, False)
    return R


def arrow_split(Q: np.ndarray, n: int) -> ArrowSplit | None:
    """Split the ``n`` rotations of the reduced cost ``Q`` (``(9n+1)^2``, ``s`` last) into leaves
    and a hub (see the module docstring).

    Leaves are a maximal set of mutually uncoupled rotations, chosen greedily by fewest couplings
    (in a target/camera graph: the targets, whose blocks of ``Q'`` couple only to cameras). Only
    exact zeros count as uncoupled, so the form is exact for the given ``Q``. Returns ``None``
    when no rotation qualifies (``n < 2``).
    """
    Q = np.asarray(Q, float)
    d = 9 * n + 1
    if Q.shape != (d, d):
        raise ValueError(f"Q: expected shape ({d}, {d}) for {n} rotations, got {Q.shape}")
    if n < 2:
        return None
    adj = _frame_blocks(Q, n)
    degree = adj.sum(axis=1)
    is_leaf = np.zeros(n, bool)
    blocked = np.zeros(n, bool)
    for f in np.argsort(degree, kind="stable"):
        if not blocked[f]:
            is_leaf[f] = True
            blocked |= adj[f]
            blocked[f] = True
    if is_leaf.all():  # no coupling at all: keep one frame in the hub
        is_leaf[n - 1] = False
    hub_frames = np.flatnonzero(~is_leaf)
    hub_rot = (9 * hub_frames[:, None] + np.arange(9)).ravel()
    hub = np.concatenate([hub_rot, [d - 1]])
    leaves, bases = [], []
    for f in np.flatnonzero(is_leaf):
        rows = np.arange(9 * f, 9 * f + 9)
        U = Q[np.ix_(rows, hub_rot)]
        cols = np.flatnonzero(np.abs(U).max(axis=0) > 0.0)
        if cols.size <= 9:  # coordinate selection: exact and sparse
            V = np.zeros((hub_rot.size, cols.size))
            V[cols, np.arange(cols.size)] = 1.0
        else:  # rank(U) <= 9: its row space is spanned by the first 9 right singular vectors
            _, _, Vt = np.linalg.svd(U[:, cols], full_matrices=False)
            V = np.zeros((hub_rot.size, 9))
            V[cols] = Vt[:9].T
        Pi = np.zeros((hub.size, V.shape[1] + 1))
        Pi[:-1, :-1] = V
        Pi[-1, -1] = 1.0
        leaves.append(rows)
        bases.append(Pi)
    return ArrowSplit(hub=hub, leaves=tuple(leaves), bases=tuple(bases),
                      leaf_frames=np.flatnonzero(is_leaf))


def group_adjacency(Q: np.ndarray | sp.spmatrix, groups: list[np.ndarray]) -> np.ndarray:
    """(g, g) bool: which variable groups (index arrays into ``Q``) share a nonzero of ``Q``."""
    d = Q.shape[0]
    rows = np.concatenate(groups)
    cols = np.concatenate([np.full(len(ix), k) for k, ix in enumerate(groups)])
    G = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(d, len(groups)))
    P = abs(sp.csr_matrix(Q))
    P.data = np.ones_like(P.data)
    return np.asarray((G.T @ P @ G).toarray() > 0)


def clique_weights(adjacency: np.ndarray, weights: np.ndarray) -> list[int]:
    """Sizes of the maximal cliques of a chordal extension of a graph of variable groups.

    Greedy elimination of the group whose clique (itself and its remaining neighbours) is the
    smallest, a weighted minimum-degree ordering like the AMD orderings solvers use; the clique
    of a group's parent (the neighbour eliminated next) is dropped when it is contained in it.

    Parameters
    ----------
    adjacency : (g, g) bool
        Symmetric coupling of the groups (the diagonal is ignored).
    weights : (g,) int
        Number of scalar variables in each group.

    Returns
    -------
    list of int
        Number of scalar variables in each maximal clique.
    """
    A = np.array(adjacency, dtype=bool)
    A |= A.T
    np.fill_diagonal(A, False)
    w = np.asarray(weights, dtype=np.int64)
    g = w.size
    alive = np.ones(g, bool)
    big = np.iinfo(np.int64).max
    wdeg = A.astype(np.int64) @ w
    size = np.zeros(g, np.int64)
    later: list[np.ndarray] = [np.zeros(0, np.int64)] * g
    pos = np.zeros(g, np.int64)
    for step in range(g):
        v = int(np.argmin(np.where(alive, wdeg + w, big)))  # smallest clique next
        pos[v] = step
        N = np.flatnonzero(A[v] & alive)
        if N.size == g - step - 1 and A[np.ix_(N, N)].sum() == N.size * (N.size - 1):
            # the remaining groups are a clique: it is the last maximal clique
            pos[N] = step + 1 + np.arange(N.size)
            later[v] = N
            size[v] = w[v] + w[N].sum()
            for k, u in enumerate(N):
                later[u] = N[k + 1:]
                size[u] = w[N[k:]].sum()
            break
        later[v] = N
        size[v] = w[v] + w[N].sum()
        alive[v] = False
        wdeg[N] -= w[v]
        if N.size > 1:
            missing = ~A[np.ix_(N, N)]
            np.fill_diagonal(missing, False)
            wdeg[N] += missing.astype(np.int64) @ w[N]
            block = np.ones((N.size, N.size), bool)
            np.fill_diagonal(block, False)
            A[np.ix_(N, N)] = block
        A[v, :] = False
        A[:, v] = False
    maximal = np.ones(g, bool)
    for v in range(g):
        N = later[v]
        if N.size:
            p = int(N[np.argmin(pos[N])])
            if later[p].size == N.size - 1:  # C_p = C_v minus v
                maximal[p] = False
    return [int(s) for s in size[maximal]]


def cone_cost(n: int) -> float:
    """Relative cost of one Clarabel iteration for a dense PSD cone of size ``n``: the cube of
    its vectorised dimension (its dense block in the KKT factorisation)."""
    m = n * (n + 1) / 2
    return m**3


def _cliques_cost(adjacency: np.ndarray, weights: np.ndarray) -> float:
    return float(sum(cone_cost(c) for c in clique_weights(adjacency, weights)))


def estimate_form_costs(Q_reduced: np.ndarray, n: int, Q_full: sp.spmatrix | None = None,
                        full_groups: list[np.ndarray] | None = None,
                        split: ArrowSplit | None = None) -> dict[str, float]:
    """Estimated relative cost of one interior-point iteration of each form of Problem 7.

    Parameters
    ----------
    Q_reduced : (9n+1, 9n+1)
        ``Q'`` of eq. (48), ``s`` last.
    n : int
        Number of rotations.
    Q_full, full_groups : optional
        The unreduced ``Q`` of the ``full`` form and its variable groups (each translation,
        ``alpha``, each rotation, ``s``); ``s`` (last group) is coupled to every rotation by the
        handedness constraints (50c), which is added here.
    split : ArrowSplit, optional
        The hub/leaf split for the ``arrow`` form.

    Returns
    -------
    dict
        ``{"reduced": c, "full": c, "arrow": c}`` for the forms whose data were given; ``c`` is
        the sum of :func:`cone_cost` over the cliques (the cones after chordal decomposition).
    """
    adj = np.ones((n + 1, n + 1), bool)  # s (last) is coupled to every rotation by (50c)
    adj[:n, :n] = _frame_blocks(Q_reduced, n)
    weights = np.array([9] * n + [1])
    costs = {"reduced": _cliques_cost(adj, weights)}
    if Q_full is not None and full_groups is not None:
        fadj = group_adjacency(Q_full, full_groups)
        fw = np.array([len(gr) for gr in full_groups])
        fadj[-1, fw == 9] = fadj[fw == 9, -1] = True
        costs["full"] = _cliques_cost(fadj, fw)
    if split is not None:
        hub_frames = split.hub[:-1:9] // 9
        hadj = adj[np.ix_(np.r_[hub_frames, n], np.r_[hub_frames, n])].copy()
        for Pi in split.bases:
            ks = np.unique(np.flatnonzero(np.abs(Pi[:-1]).max(axis=1) > 0) // 9)
            hadj[np.ix_(ks, ks)] = True
        hw = np.array([9] * hub_frames.size + [1])
        costs["arrow"] = (_cliques_cost(hadj, hw)
                          + float(sum(cone_cost(c) for c in split.cone_sizes[:-1])))
    return costs


def elimination_front(M: int, P: int, edge_x: np.ndarray, edge_y: np.ndarray,
                      max_work: float | None = None) -> tuple[int, float]:
    """The largest front of a minimum-degree elimination of the frame graph (X-Y edges) -- the
    most frames adjacent to a frame when it is eliminated, fill included -- and the sum of the
    squared fronts (proportional to the work of the factorisation).

    A sparse factorisation of ``Q`` (eq. (42)) or of the unreduced certificate matrix eliminates
    whole frames (their translation and rotation, plus the shared ``alpha``/``s``); its dense
    fronts hold about 12 times this many variables, so the number says whether a sparse
    factorisation stays sparse. One target seen by every camera: 1 (each camera touches only
    the target). The elimination stops as soon as the work exceeds ``max_work`` (both numbers are
    then lower bounds).
    """
    import heapq

    n = M + P
    adj: list[set[int]] = [set() for _ in range(n)]
    for j, k in zip(np.asarray(edge_x, int), np.asarray(edge_y, int), strict=True):
        adj[j].add(M + k)
        adj[M + k].add(j)
    heap = [(len(a), v) for v, a in enumerate(adj)]
    heapq.heapify(heap)
    alive = np.ones(n, dtype=bool)
    front = 0
    work = 0.0
    while heap:
        deg, v = heapq.heappop(heap)
        if not alive[v] or deg != len(adj[v]):
            continue  # a stale entry
        front = max(front, deg)
        work += float(deg + 1) ** 2
        if max_work is not None and work > max_work:
            return front, work
        alive[v] = False
        nb = adj[v]
        for u in nb:
            adj[u].discard(v)
            adj[u] |= nb
            adj[u].discard(u)
            heapq.heappush(heap, (len(adj[u]), u))
        adj[v] = set()
    return front, work

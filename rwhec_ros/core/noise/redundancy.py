"""Each noise group's chi-square and redundancy at a solution: the numbers of a variance-component
estimate.

For a least-squares problem with observation groups ``g`` (weights ``W_g``, design ``A_g``,
normal matrix ``N = sum_g A_g^T W_g A_g``) the **redundancy** of a group is ``r_g = n_g -
tr(N^-1 A_g^T W_g A_g)``: its share of the degrees of freedom ``n - rank``. Helmert's / Foerstner's
estimate of the group's variance factor is then ``s_g^2 = v_g^T W_g v_g / r_g`` (Foerstner 1979;
Koch, *Parameter Estimation and Hypothesis Testing in Linear Models*, Section 3.6).

Here the groups are a camera's (or an edge's, or all) translation terms and rotation terms of eq.
(33), ``n_g = 3 N_g`` each (a translation residual has 3 components, a rotation residual 3
angles), ``v_g^T W_g v_g`` their part ``sum |r_t|^2 / sigma^2`` or ``sum 2 kappa (3 - tr D)`` of
the chi-square at the solution, and ``N`` the exact Hessian of the negative log-likelihood on the
manifold (:mod:`rwhec_ros.core.analysis.information`). That Hessian is linear in the cost matrix
``Q = sum_e (Q_e,t + Q_e,R)``, the edge blocks split into their translation and rotation parts
(:func:`~rwhec_ros.core.model.cost.edge_blocks`), both in the Gauss-Newton part ``2 J^T Q J`` and
in the curvature terms of the gradient ``2 Q x``; so ``H = sum_(g, c) H_(g, c)`` exactly and the
redundancies of all groups and both components add up to ``6 N - rank``, the degrees of freedom of
:class:`~rwhec_ros.core.analysis.uncertainty.Uncertainty` (``test/core/noise`` checks it).
``N^-1`` is the covariance on the observable directions
(:func:`~rwhec_ros.core.analysis.uncertainty.covariance_of`, the same gauge as the solve).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..analysis.information import (
    TangentLayout,
    edge_tangent_jacobians,
    information_from_edge_blocks,
    information_matrix,
    pair_residuals,
)
from ..analysis.uncertainty import UncertaintyOptions, covariance_of
from ..model.cost import StateLayout, edge_blocks, pack_state
from ..model.gauge import GaugeOptions
from ..model.recentre import recentred_analysis
from ..numerics.blas import blas_threads
from ..problem import Problem
from .groups import NoiseGroups

__all__ = ["GroupSums", "group_sums", "pair_chi2"]

_I3 = np.eye(3)
#: The local tangent columns of a known-scale edge (``d alpha`` dropped).
_KNOWN = np.r_[0:6, 7:13]


@dataclass(frozen=True)
class GroupSums:
    """Per noise group (G,) and component, at one solution.

    Attributes
    ----------
    pairs : ndarray of int
    chi2_translation, chi2_rotation : ndarray
        ``sum |r_t|^2 / sigma^2`` and ``sum 2 kappa (3 - tr D)`` over the group's pairs.
    redundancy_translation, redundancy_rotation : ndarray
        ``3 N_g - tr(N^-1 H_(g, c))`` (module docstring).
    rank : int
        Directions the data determine (as the uncertainty's).
    edge_chi2_translation, edge_chi2_rotation : ndarray, shape (E,)
        The same chi-squares per edge.
    edge_redundancy_translation, edge_redundancy_rotation : ndarray, shape (E,)
        The redundancies per edge: its Gauss-Newton part exactly, the curvature terms (known per
        group only) shared among the group's edges in proportion to that part, so that they add
        up to the group's.
    """

    pairs: np.ndarray
    chi2_translation: np.ndarray
    chi2_rotation: np.ndarray
    redundancy_translation: np.ndarray
    redundancy_rotation: np.ndarray
    rank: int
    edge_chi2_translation: np.ndarray
    edge_chi2_rotation: np.ndarray
    edge_redundancy_translation: np.ndarray
    edge_redundancy_rotation: np.ndarray

    def without(self, edge_group: np.ndarray, left_out: np.ndarray) -> GroupSums:
        """The group sums over the edges not in ``left_out`` (E,) bool (``edge_group`` (E,)
        their groups); the per-edge arrays unchanged."""
        keep = ~np.asarray(left_out, bool)
        G = self.pairs.shape[0]

        def total(v):
            return np.bincount(edge_group[keep], weights=v[keep], minlength=G)

        return GroupSums(self.pairs, total(self.edge_chi2_translation),
                         total(self.edge_chi2_rotation), total(self.edge_redundancy_translation),
                         total(self.edge_redundancy_rotation), self.rank,
                         self.edge_chi2_translation, self.edge_chi2_rotation,
                         self.edge_redundancy_translation, self.edge_redundancy_rotation)


def pair_chi2(problem: Problem, X: np.ndarray, Y: np.ndarray, alpha: float
              ) -> tuple[np.ndarray, np.ndarray]:
    """Per pair (N,), pairs stacked edge by edge: the translation term ``|r_t|^2 / sigma^2``
    (``r_t`` in the units of ``B``: ``alpha`` times metric) and the rotation term ``2 kappa
    (3 - tr D) = 8 kappa sin^2(theta / 2)`` of eq. (33), from the residuals (not the quadratic
    form)."""
    st = problem.stacked()
    T = np.concatenate([X, Y])
    r, angle = pair_residuals(st["A"], st["B"], T[st["xi"]], T[problem.M + st["yi"]], alpha)
    chi_t = (alpha * alpha) * np.einsum("ni,ni->n", r, r) / st["sigma"] ** 2
    chi_r = 8.0 * st["kappa"] * np.sin(0.5 * angle) ** 2
    return chi_t, chi_r


def group_sums(problem: Problem, result, groups: NoiseGroups, *,
               gauge: GaugeOptions | None = None, information: str = "pairs") -> GroupSums:
    """The chi-squares and redundancies of ``groups`` at ``result`` (``X``, ``Y``, ``scale``, in
    ``problem``'s frame order) for ``problem``'s weights (module docstring).

    ``gauge``: the solve's :class:`~rwhec_ros.core.model.gauge.GaugeOptions` (priors);
    ``information``: ``"pairs"`` or ``"edge_blocks"`` as
    :class:`~rwhec_ros.core.analysis.uncertainty.UncertaintyOptions`. Raises ``ValueError`` for a
    malformed result."""
    gauge = gauge or GaugeOptions()
    counts = np.array([e.n for e in problem.edges])
    G = groups.size
    eg = groups.edge_group
    pairs = np.bincount(eg, weights=counts, minlength=G).astype(int)
    # the analysis about a nearby point when the data are far from the origin (exact)
    prob, res = recentred_analysis(problem, result, priors=bool(gauge.priors))
    with blas_threads(1):
        trace_t, trace_r, rank, block_chi2 = _traces(prob, res, groups, gauge, information)
    if information == "edge_blocks" and prob is problem:
        et, er = block_chi2  # from the quadratic form (the live path's; as its uncertainty)
    else:
        alpha = float(result.scale) if problem.unknown_scale else 1.0
        chi_t, chi_r = pair_chi2(problem, np.asarray(result.X, float),
                                 np.asarray(result.Y, float), alpha)
        starts = np.r_[0, np.cumsum(counts)[:-1]]
        et, er = np.add.reduceat(chi_t, starts), np.add.reduceat(chi_r, starts)
    ret, rer = 3.0 * counts - trace_t, 3.0 * counts - trace_r
    return GroupSums(
        pairs=pairs,
        chi2_translation=np.bincount(eg, weights=et, minlength=G),
        chi2_rotation=np.bincount(eg, weights=er, minlength=G),
        redundancy_translation=np.bincount(eg, weights=ret, minlength=G),
        redundancy_rotation=np.bincount(eg, weights=rer, minlength=G),
        rank=rank, edge_chi2_translation=et, edge_chi2_rotation=er,
        edge_redundancy_translation=ret, edge_redundancy_rotation=rer)


def _traces(problem: Problem, result, groups: NoiseGroups, gauge: GaugeOptions,
            information: str) -> tuple[np.ndarray, np.ndarray, int]:
    """``tr(N^-1 H_(g, c))`` per edge (E,) for the translation and the rotation part (the
    curvature terms of a group shared among its edges, :class:`GroupSums`), the rank, and the
    edges' chi-squares ``2 x_e^T Q_e,c x_e`` of both parts from the quadratic form."""
    assemble = information_from_edge_blocks if information == "edge_blocks" else \
        information_matrix
    info = assemble(problem, result.X, result.Y, result.scale)
    cov = covariance_of(info, problem, UncertaintyOptions(gauge=gauge, blas_threads=None))
    S = cov.sigma
    lay: TangentLayout = info.layout
    F, M = lay.n_frames, problem.M
    st = StateLayout(M, problem.P)
    R, t, a = info.R, info.t, info.alpha
    full, rot, idx = edge_blocks(problem)
    trans = full - rot
    # Gauss-Newton part per edge: 2 tr(Q_e,c J_e S_e J_e^T)
    J = edge_tangent_jacobians(problem, R, t, a)
    loc = lay.pair_indices(problem.edge_x, problem.edge_y)  # (E, 13 or 12)
    if not problem.unknown_scale:
        J = J[:, :, _KNOWN]
    S_e = S[loc[:, :, None], loc[:, None, :]]
    P = J @ S_e @ np.swapaxes(J, 1, 2)  # (E, 25, 25)
    gn_t = 2.0 * np.einsum("eij,eij->e", P, trans)
    gn_r = 2.0 * np.einsum("eij,eij->e", P, rot)
    Gn = groups.size
    eg = groups.edge_group
    out = []
    x = pack_state(st, _transforms(R[:M], t[:M]), _transforms(R[M:], t[M:]), a)
    xe = x[idx]
    rot_idx = lay.r0 + 3 * np.arange(F)[:, None] + np.arange(3)
    S_rot = S[rot_idx[:, :, None], rot_idx[:, None, :]]  # (F, 3, 3)
    tr_S = np.trace(S_rot, axis1=1, axis2=2)
    chi2 = []
    for Qc, gn in ((trans, gn_t), (rot, gn_r)):
        per_group = np.zeros(Gn)
        # curvature terms of the gradient 2 Q_(g, c) x, group by group (linear in it)
        Qx = np.einsum("eij,ej->ei", Qc, xe)
        chi2.append(np.maximum(2.0 * np.einsum("ei,ei->e", xe, Qx), 0.0))
        flat = (eg[:, None] * st.size + idx).ravel()
        g = 2.0 * np.bincount(flat, weights=Qx.ravel(), minlength=Gn * st.size).reshape(
            Gn, st.size)
        Gm = np.swapaxes(g[:, st.r0:].reshape(Gn, F, 3, 3), 2, 3)  # unvec per frame
        GtR = np.swapaxes(Gm, 2, 3) @ R[None]  # (Gn, F, 3, 3)
        # tr(S (sym(M) - tr(M) I)) = sum(S * M) - tr(M) tr(S) for symmetric S
        curv = (np.einsum("fij,gfij->g", S_rot, GtR)
                - np.einsum("gfii,f->g", GtR, tr_S))
        per_group = per_group + curv
        if lay.alpha is not None:  # the alpha-translation cross terms, both triangles
            per_group = per_group + 2.0 * g[:, : 3 * F] @ S[lay.alpha, : 3 * F]
        # shared among the group's edges in proportion to their Gauss-Newton part
        gsum = np.bincount(eg, weights=gn, minlength=Gn)
        count = np.bincount(eg, minlength=Gn)
        share = np.where(gsum[eg] != 0, gn / np.where(gsum[eg] != 0, gsum[eg], 1.0),
                         1.0 / count[eg])
        out.append(gn + per_group[eg] * share)
    return out[0], out[1], int(cov.rank), (chi2[0], chi2[1])


def _transforms(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Transforms (K, 4, 4) from rotations (K, 3, 3) and translations (K, 3)."""
    T = np.zeros((R.shape[0], 4, 4))
    T[:, :3, :3] = R
    T[:, :3, 3] = t
    T[:, 3, 3] = 1.0
    return T

"""The information matrix of the MLE: the Hessian of the negative log-likelihood on the manifold.

Under the paper's noise model (Section 4.2: ``t_B`` with isotropic Gaussian noise of standard
deviation ``sigma_i``, ``R_B`` right-perturbed by ``Lang(I, kappa_i)``), the negative
log-likelihood of the data is, up to a constant, ``f = x^T Q x = 1/2 sum_i J_i`` of eq. (33)::

    J_i = |r_t|^2 / sigma_i^2 + kappa_i |R_A R_X - R_Y R_B|_F^2,
    r_t = alpha (R_A t_X + t_A - t_Y) - R_Y t_B        (metric t_X, t_Y; alpha = 1 known scale)

(eq. (14)-(16); for small rotation noise ``Lang(I, kappa)`` is ``N(0, I / (2 kappa))`` on the
rotation vector, and ``sum_i J_i`` is chi-square distributed with ``6 N`` degrees of freedom at the
true values). The (observed) information of the MLE is therefore the Hessian of ``f`` on the
manifold at the estimate, assembled here pair by pair in ``O(N)`` without forming ``Q``.

Tangent coordinates ``xi`` (:class:`TangentLayout`), size ``6 F`` (+1 for unknown scale),
``F = M + P`` frames in problem order (X frames then Y frames)::

    xi = [dt_1 .. dt_F, (d alpha), w_1 .. w_F]

with metric translations ``t_f <- t_f + dt_f`` (in the frame's parent) and *right* rotation
perturbations ``R_f <- R_f exp(w_f^)`` (as the local solver, :mod:`rwhec_ros.core.local.dense`).
The Hessian is exact: the Gauss-Newton term plus the second-order terms of the residuals (the
curvature of ``exp`` contracted with the residuals, and the ``alpha``-translation cross terms), so
that at a minimiser the flat directions of exact symmetries have zero eigenvalues.

Per pair, with ``P = R_X^T R_A^T R_Y``, ``D = P R_B`` (= I for exact data) and ``D' = R_B P``, the
rotation term ``kappa (3 - tr D)`` has the Hessian blocks
``H_ww(X) = kappa (tr D I - sym D)``, ``H_ww(Y) = kappa (tr D I - sym D')`` and
``H_ww(X, Y) = kappa (D - tr D I) P``; the translation term has Jacobian
``[alpha R_A, -alpha I, R_A t_X + t_A - t_Y, 0, R_Y t_B^]`` on ``[dt_X, dt_Y, d alpha, w_X, w_Y]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..lie import hat
from ..problem import Problem, check_transforms

__all__ = [
    "TangentLayout",
    "PairTerms",
    "Information",
    "pair_terms",
    "pair_residuals",
    "information_matrix",
    "information_from_edge_blocks",
    "edge_tangent_jacobians",
    "scatter_information",
    "information_from_cost_matrix",
    "check_result_frames",
    "frame_of_coordinate",
]

_I3 = np.eye(3)
#: Local variable order of one pair's 13 x 13 block: ``[dt_X, dt_Y, d alpha, w_X, w_Y]``.
_LOCAL_KNOWN = np.r_[0:6, 7:13]


@dataclass(frozen=True)
class TangentLayout:
    """Index layout of the tangent coordinates ``xi`` (module docstring)."""

    M: int
    P: int
    unknown_scale: bool

    @property
    def n_frames(self) -> int:
        return self.M + self.P

    @property
    def alpha(self) -> int | None:
        """Index of ``d alpha`` (unknown scale), else ``None``."""
        return 3 * self.n_frames if self.unknown_scale else None

    @property
    def r0(self) -> int:
        """Index of the first rotation coordinate."""
        return 3 * self.n_frames + (1 if self.unknown_scale else 0)

    @property
    def size(self) -> int:
        return 6 * self.n_frames + (1 if self.unknown_scale else 0)

    def frame_indices(self, frame: int | np.ndarray) -> np.ndarray:
        """The 6 coordinates ``[dt (3), w (3)]`` of global frame(s) ``frame``, shape (..., 6)."""
        f = np.asarray(frame)[..., None]
        three = np.arange(3)
        return np.concatenate([3 * f + three, self.r0 + 3 * f + three], axis=-1)

    def pair_indices(self, xi: np.ndarray, yi: np.ndarray) -> np.ndarray:
        """Global indices (N, 13 or 12) of the local block of pairs joining X ``xi``, Y ``yi``
        (``d alpha`` dropped for known scale)."""
        xi = np.asarray(xi, int)[:, None]
        yi = np.asarray(yi, int)[:, None] + self.M
        three = np.arange(3)
        a = np.full_like(xi, -1) if self.alpha is None else np.full_like(xi, self.alpha)
        idx = np.concatenate([3 * xi + three, 3 * yi + three, a, self.r0 + 3 * xi + three,
                              self.r0 + 3 * yi + three], axis=1)
        return idx if self.unknown_scale else idx[:, _LOCAL_KNOWN]


def frame_of_coordinate(problem: Problem, index: int) -> str:
    """The frame a coordinate of the tangent (:class:`TangentLayout`) belongs to; ``"the
    scale"`` for ``d alpha``."""
    layout = TangentLayout(problem.M, problem.P, problem.unknown_scale)
    names = list(problem.x_names) + list(problem.y_names)
    for base in (0, layout.r0):
        if base <= index < base + 3 * len(names):
            return names[(index - base) // 3]
    return "the scale"


@dataclass
class PairTerms:
    """Per-pair residuals and per-group sums of the information of ``N`` pairs in ``G`` groups
    (consecutive runs of pairs, e.g. the edges).

    Attributes
    ----------
    residual_t : ndarray, shape (N, 3)
        ``r_t / alpha`` [m]: the metric translation residual of eq. (33), in the Y frame's
        parent (e.g. the camera carrier).
    residual_angle : ndarray, shape (N,)
        Geodesic angle [rad] between ``R_A R_X`` and ``R_Y R_B``.
    chi2 : ndarray, shape (N,)
        ``J_i`` of eq. (33): ``|r_t|^2 / sigma^2 + 2 kappa (3 - tr D)``.
    hessian : ndarray, shape (G, 13, 13)
        Per group, the Hessian of ``sum_i J_i / 2`` on ``[dt_X, dt_Y, d alpha, w_X, w_Y]``
        (module docstring).
    translation_block : ndarray, shape (G, 7, 7)
        Per group, the part of the translation block ``Q_ee`` of ``Q`` on ``[alpha t_X,
        alpha t_Y, alpha]`` (what :mod:`rwhec_ros.core.model.gauge` analyses).
    """

    residual_t: np.ndarray
    residual_angle: np.ndarray
    chi2: np.ndarray
    hessian: np.ndarray
    translation_block: np.ndarray


def _split(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return T[..., :3, :3], T[..., :3, 3]


def _angle_of(D: np.ndarray) -> np.ndarray:
    """Rotation angle of rotation matrices ``D`` (N, 3, 3), accurate near 0 and pi."""
    s = np.linalg.norm(np.stack([D[:, 2, 1] - D[:, 1, 2], D[:, 0, 2] - D[:, 2, 0],
                                 D[:, 1, 0] - D[:, 0, 1]], axis=1), axis=1)
    return np.arctan2(s, np.trace(D, axis1=1, axis2=2) - 1.0)


def pair_residuals(
    A: np.ndarray, B: np.ndarray, X: np.ndarray, Y: np.ndarray, alpha: float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """Metric translation residuals (N, 3) [m] and rotation residual angles (N,) [rad] of pairs
    ``A, B`` (N, 4, 4) for the frames ``X, Y`` (N, 4, 4 or 4, 4): ``(alpha (R_A t_X + t_A - t_Y)
    - R_Y t_B) / alpha`` (eq. (33), in Y's parent) and the angle of
    ``(R_A R_X)^T R_Y R_B``."""
    RA, tA = _split(np.asarray(A, float))
    RB, tB = _split(np.asarray(B, float))
    RX, tX = _split(np.broadcast_to(np.asarray(X, float), np.shape(A)))
    RY, tY = _split(np.broadcast_to(np.asarray(Y, float), np.shape(A)))
    p = np.einsum("nij,nj->ni", RA, tX) + tA - tY
    r = p - np.einsum("nij,nj->ni", RY, tB) / alpha
    D = np.swapaxes(RA @ RX, 1, 2) @ RY @ RB
    return r, _angle_of(D)


def _times_hat(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``R @ hat(t)`` for ``R`` (N, 3, 3) and ``t`` (N, 3), column by column (no (N, 3, 3)
    ``hat`` and no batched product)."""
    out = np.empty(R.shape)
    out[:, :, 0] = R[:, :, 1] * t[:, 2, None] - R[:, :, 2] * t[:, 1, None]
    out[:, :, 1] = R[:, :, 2] * t[:, 0, None] - R[:, :, 0] * t[:, 2, None]
    out[:, :, 2] = R[:, :, 0] * t[:, 1, None] - R[:, :, 1] * t[:, 0, None]
    return out


def _sym(S: np.ndarray) -> np.ndarray:
    return 0.5 * (S + np.swapaxes(S, -1, -2))


def pair_terms(
    A: np.ndarray,
    B: np.ndarray,
    sigma: np.ndarray,
    kappa: np.ndarray,
    X: np.ndarray,
    Y: np.ndarray,
    alpha: float = 1.0,
    starts: np.ndarray | None = None,
) -> PairTerms:
    """Residuals, ``J_i`` and the exact Hessian of ``N`` pairs, summed per group.

    ``A, B`` (N, 4, 4); ``sigma, kappa`` (N,); ``X, Y`` (N, 4, 4): each pair's X and Y frame
    (metric translations); ``alpha`` the scale (1 for known scale); ``starts`` (G,) the first
    pair of each group (default: one group). The Gauss-Newton part is one matrix product per
    group on the stacked weighted Jacobians; the second-order terms are sums of per-pair 3x3
    quantities (module docstring), so no per-pair 13x13 block is formed.
    """
    RA, tA = _split(A)
    RB, tB = _split(B)
    RX, tX = _split(X)
    RY, tY = _split(Y)
    N = RA.shape[0]
    starts = np.zeros(1, int) if starts is None else np.asarray(starts, int)
    ends = np.r_[starts[1:], N]
    w = 1.0 / np.asarray(sigma, float) ** 2
    k = np.asarray(kappa, float)
    p = np.einsum("nij,nj->ni", RA, tX) + tA - tY
    r = alpha * p - np.einsum("nij,nj->ni", RY, tB)
    # Gauss-Newton part of the translation term, with a 14th column t_A for Q_ee:
    # sqrt(w) [alpha R_A, -alpha I, p, 0, R_Y t_B^, t_A]
    J = np.zeros((N, 3, 14))
    J[:, :, 0:3] = alpha * RA
    J[:, 0, 3] = J[:, 1, 4] = J[:, 2, 5] = -alpha
    J[:, :, 6] = p
    J[:, :, 10:13] = _times_hat(RY, tB)
    J[:, :, 13] = tA
    J *= np.sqrt(w)[:, None, None]
    J2 = J.reshape(3 * N, 14)
    # per-pair 3x3 quantities of the second-order terms, written into one (N, 53) array
    rw = r * w[:, None]
    u = np.einsum("nki,nk->ni", RY, rw)  # R_Y^T r w
    Pm = np.swapaxes(RA @ RX, 1, 2) @ RY  # P = R_X^T R_A^T R_Y
    D = Pm @ RB
    trD = np.trace(D, axis1=1, axis2=2)
    kk = k[:, None, None]
    parts = np.empty((N, 53))
    parts[:, 0:3] = (rw[:, :, None] * RA).sum(axis=1)  # (d alpha, dt_X): r w . R_A
    parts[:, 3:6] = rw  # (d alpha, dt_Y): -r w
    parts[:, 6:15] = (u[:, :, None] * tB[:, None, :]).reshape(N, 9)  # (w_Y, w_Y)
    parts[:, 15] = np.einsum("ni,ni->n", u, tB)
    parts[:, 16:25] = (kk * D).reshape(N, 9)  # rotation term kappa (3 - tr D)
    parts[:, 25:34] = (kk * (RB @ Pm)).reshape(N, 9)  # kappa D'
    parts[:, 34:43] = (kk * (D @ Pm)).reshape(N, 9)
    parts[:, 43:52] = ((k * trD)[:, None, None] * Pm).reshape(N, 9)
    parts[:, 52] = k * trD
    # per group: the Gauss-Newton product and the sums of the parts
    G = len(starts)
    Mg = np.empty((G, 14, 14))
    S = np.empty((G, 53))
    for g in range(G):
        Jg = J2[3 * starts[g]: 3 * ends[g]]
        np.dot(Jg.T, Jg, out=Mg[g])
    np.add.reduceat(parts, starts, axis=0, out=S)
    H = Mg[:, :13, :13].copy()
    sel = np.r_[0:6, 13]
    scale = np.r_[np.full(6, 1.0 / alpha), 1.0]
    Qee = 0.5 * Mg[:, sel][:, :, sel] * np.outer(scale, scale)
    c, rs = S[:, 0:3], S[:, 3:6]
    utb, udot = S[:, 6:15].reshape(G, 3, 3), S[:, 15]
    kD, kDp = S[:, 16:25].reshape(G, 3, 3), S[:, 25:34].reshape(G, 3, 3)
    kDP, ktP = S[:, 34:43].reshape(G, 3, 3), S[:, 43:52].reshape(G, 3, 3)
    ktr = S[:, 52][:, None, None] * _I3
    H[:, 6, 0:3] += c
    H[:, 0:3, 6] += c
    H[:, 6, 3:6] -= rs
    H[:, 3:6, 6] -= rs
    H[:, 10:13, 10:13] += -_sym(utb) + udot[:, None, None] * _I3
    H[:, 7:10, 7:10] += ktr - _sym(kD)
    H[:, 10:13, 10:13] += ktr - _sym(kDp)
    Hab = kDP - ktP  # sum kappa (D - tr D I) P
    H[:, 7:10, 10:13] += Hab
    H[:, 10:13, 7:10] += np.swapaxes(Hab, 1, 2)
    chi2 = (r * r).sum(axis=1) * w + 2.0 * k * (3.0 - trD)
    return PairTerms(residual_t=r / alpha, residual_angle=_angle_of(D), chi2=chi2,
                     hessian=_sym(H), translation_block=_sym(Qee))


@dataclass
class Information:
    """The information matrix of the data at an estimate (module docstring).

    Attributes
    ----------
    layout : TangentLayout
    names : tuple of str
        Frame names in state order (X frames, then Y frames).
    R : ndarray, shape (F, 3, 3)
        Rotations of the estimate.
    t : ndarray, shape (F, 3)
        Metric translations of the estimate.
    alpha : float
        Scale of the estimate (1 for known scale).
    H : ndarray, shape (n, n)
        Hessian of ``f = 1/2 sum J_i`` on ``xi`` (``n = layout.size``).
    Q_ee : ndarray, shape (m, m)
        Translation block of ``Q`` (eq. (42)) on ``[alpha t]`` (+ ``alpha`` for unknown scale),
        ``m = 3 F`` (+1): what the Schur reduction eliminates.
    chi2 : float
        ``sum_i J_i`` at the estimate (``2 f``).
    n_pairs : int
    edge_chi2 : ndarray, shape (E,)
        ``sum_i J_i`` per edge.
    """

    layout: TangentLayout
    names: tuple[str, ...]
    R: np.ndarray
    t: np.ndarray
    alpha: float
    H: np.ndarray
    Q_ee: np.ndarray
    chi2: float
    n_pairs: int
    edge_chi2: np.ndarray


def check_result_frames(problem: Problem, result) -> None:
    """``ValueError`` unless ``result`` (a CalibrationResult) has ``problem``'s X and Y frames in
    the same order."""
    if tuple(result.x_names) != problem.x_names or tuple(result.y_names) != problem.y_names:
        raise ValueError(f"result frames {list(result.x_names)} / {list(result.y_names)} do not "
                         f"match the problem's {list(problem.x_names)} / {list(problem.y_names)}")


def _check_estimate(problem: Problem, X, Y, alpha: float) -> tuple[np.ndarray, float]:
    """``(T, alpha)``: ``X`` (M, 4, 4) and ``Y`` (P, 4, 4) checked as transforms and stacked,
    ``alpha`` (1 for known scale) checked; ``ValueError`` naming the first offender."""
    X, Y = np.asarray(X, dtype=float), np.asarray(Y, dtype=float)
    T = None
    if X.ndim == 3 and Y.ndim == 3 and X.shape[1:] == Y.shape[1:] == (4, 4):
        try:  # both stacks in one check (the usual case: every transform valid)
            T = check_transforms(np.concatenate([X, Y]), what="estimate", rotation_tol=1e-5)
        except ValueError:
            T = None  # checked one by one below, for the message naming X[i] or Y[i]
    if T is None:
        X = check_transforms(X, what="X", rotation_tol=1e-5)
        Y = check_transforms(Y, what="Y", rotation_tol=1e-5)
        T = np.concatenate([X, Y])
    if X.shape[0] != problem.M or Y.shape[0] != problem.P:
        raise ValueError(f"estimate: expected {problem.M} X and {problem.P} Y transforms, got "
                         f"{X.shape[0]} and {Y.shape[0]}")
    a = float(alpha) if problem.unknown_scale else 1.0
    if not (np.isfinite(a) and a > 0):
        raise ValueError(f"alpha: must be finite and > 0, got {alpha!r}")
    return T, a


def _scatter_add(n: int, idx: np.ndarray, blocks: np.ndarray) -> np.ndarray:
    """``sum_g`` of ``blocks[g]`` (G, b, b) added at ``idx[g] x idx[g]`` ((G, b) indices, distinct
    within a group) of an ``n x n`` zero matrix: one ``bincount`` (the sums in group order, as
    ``np.add.at`` forms them)."""
    flat = (idx[:, :, None] * n + idx[:, None, :]).ravel()
    return np.bincount(flat, weights=blocks.ravel(), minlength=n * n).reshape(n, n)


def scatter_information(
    layout: TangentLayout,
    xi: np.ndarray,
    yi: np.ndarray,
    terms: PairTerms,
) -> tuple[np.ndarray, np.ndarray]:
    """Scatter the per-group blocks of ``terms`` (group ``g`` joining X frame ``xi[g]`` and Y
    frame ``yi[g]``, (G,)) into ``(H (n, n), Q_ee (m, m))`` of ``layout``, ``m = 3 F`` (+1)."""
    return _scatter_blocks(layout, xi, yi, terms.hessian, terms.translation_block)


def _scatter_blocks(layout: TangentLayout, xi: np.ndarray, yi: np.ndarray, hessian: np.ndarray,
                    translation_block: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`scatter_information` of per-group ``hessian`` (G, 13, 13) and
    ``translation_block`` (G, 7, 7). For known scale the blocks' ``d alpha`` row and column go
    to one extra bin that is dropped (each real entry gets the same terms in the same order
    as from the blocks without them: the same bits, without copying the blocks)."""
    n = layout.size
    F = layout.n_frames
    xi = np.asarray(xi, dtype=int)
    yi = np.asarray(yi, dtype=int) + layout.M
    three = np.arange(3)
    idx = np.empty((len(xi), 13), dtype=int)  # [dt_X, dt_Y, d alpha, w_X, w_Y], as pair_indices
    idx[:, 0:3] = 3 * xi[:, None] + three
    idx[:, 3:6] = 3 * yi[:, None] + three
    idx[:, 6] = 3 * F if layout.unknown_scale else n  # d alpha (known scale: the extra bin)
    idx[:, 7:10] = layout.r0 + idx[:, 0:3]
    idx[:, 10:13] = layout.r0 + idx[:, 3:6]
    H = _scatter_add(n + (0 if layout.unknown_scale else 1), idx, hessian)[:n, :n]
    m = 3 * F + (1 if layout.unknown_scale else 0)
    qidx = idx[:, :7].copy()
    qidx[:, 6] = 3 * F  # alpha in Q_ee (known scale: the extra bin)
    Qee = _scatter_add(3 * F + 1, qidx, translation_block)[:m, :m]
    return 0.5 * (H + H.T), 0.5 * (Qee + Qee.T)


def information_matrix(
    problem: Problem, X: np.ndarray, Y: np.ndarray, alpha: float = 1.0
) -> Information:
    """The information matrix of ``problem``'s data at the estimate ``X`` (M, 4, 4), ``Y``
    (P, 4, 4) (metric translations) and ``alpha`` (ignored for known scale).

    The pairs' terms are summed per edge (pairs are stored edge by edge), then scattered:
    ``O(N)`` work with small dense products (:func:`pair_terms`). Raises ``ValueError`` for a
    malformed estimate.
    """
    T, a = _check_estimate(problem, X, Y, alpha)
    layout = TangentLayout(problem.M, problem.P, problem.unknown_scale)
    st = problem.stacked()
    Xp = T[st["xi"]]
    Yp = T[problem.M + st["yi"]]
    starts = np.r_[0, np.cumsum([e.n for e in problem.edges])[:-1]]
    terms = pair_terms(st["A"], st["B"], st["sigma"], st["kappa"], Xp, Yp, a, starts)
    H, Qee = scatter_information(layout, problem.edge_x, problem.edge_y, terms)
    return Information(
        layout=layout, names=problem.frame_names, R=T[:, :3, :3].copy(), t=T[:, :3, 3].copy(),
        alpha=a, H=H, Q_ee=Qee, chi2=float(terms.chi2.sum()), n_pairs=int(terms.chi2.size),
        edge_chi2=np.add.reduceat(terms.chi2, starts))


def edge_tangent_jacobians(problem: Problem, R: np.ndarray, t: np.ndarray, alpha: float
                           ) -> np.ndarray:
    """Per edge, the Jacobian (E, 25, 13) of its local state ``x_e = [alpha t_X, alpha t_Y,
    alpha, vec R_X, vec R_Y]`` (eq. (44)) on its tangent coordinates ``[dt_X, dt_Y, d alpha, w_X,
    w_Y]`` at the rotations ``R`` (F, 3, 3), metric translations ``t`` (F, 3) and scale
    ``alpha`` (the ``d alpha`` column is zero for known scale)."""
    F = R.shape[0]
    fx, fy = problem.edge_x, problem.M + problem.edge_y
    basis = np.swapaxes(R[:, None] @ hat(np.eye(3))[None], -1, -2).reshape(F, 3, 9)  # vec(R e_k^)
    J = np.zeros((len(problem.edges), 25, 13))
    J[:, 0:3, 0:3] = J[:, 3:6, 3:6] = alpha * _I3
    if problem.unknown_scale:
        J[:, 0:3, 6] = t[fx]
        J[:, 3:6, 6] = t[fy]
        J[:, 6, 6] = 1.0
    J[:, 7:16, 7:10] = np.swapaxes(basis[fx], 1, 2)
    J[:, 16:25, 10:13] = np.swapaxes(basis[fy], 1, 2)
    return J


def information_from_edge_blocks(
    problem: Problem, X: np.ndarray, Y: np.ndarray, alpha: float = 1.0
) -> Information:
    """The same :class:`Information` from the cost's 25x25 edge blocks
    (:func:`~rwhec_ros.core.model.cost.edge_blocks`, ``problem.precomputed_blocks`` when set: the
    live re-solve's, so nothing is summed over the pairs here): per edge ``2 J_e^T Q_e J_e`` on
    ``[dt_X, dt_Y, d alpha, w_X, w_Y]`` plus, per frame, the curvature terms of the gradient
    ``2 Q x`` (as :func:`information_from_cost_matrix`, ``J = dx / d xi``).

    ``chi2`` and ``edge_chi2`` are ``2 x_e^T Q_e x_e`` per edge (rounding of order ``u |x_e|^T
    |Q_e| |x_e|``, where :func:`information_matrix` sums the residuals directly); ``H`` and
    ``Q_ee`` agree with :func:`information_matrix` to rounding.
    """
    from ..model.cost import StateLayout, edge_blocks, pack_state

    T, a = _check_estimate(problem, X, Y, alpha)
    F = T.shape[0]
    M = problem.M
    layout = TangentLayout(M, problem.P, problem.unknown_scale)
    st = StateLayout(M, problem.P)
    R, t = T[:, :3, :3], T[:, :3, 3]
    full, _, idx = edge_blocks(problem)
    x = pack_state(st, T[:M], T[M:], a)
    xe = x[idx]  # (E, 25) on [alpha t_X, alpha t_Y, alpha, vec R_X, vec R_Y]
    Qx = np.einsum("eij,ej->ei", full, xe)
    edge_chi2 = 2.0 * np.einsum("ei,ei->e", xe, Qx)
    g = 2.0 * np.bincount(idx.ravel(), weights=Qx.ravel(), minlength=st.size)  # 2 Q x
    J = edge_tangent_jacobians(problem, R, t, a)
    Jt = np.swapaxes(J, 1, 2)
    hess = 2.0 * (Jt @ (full @ J))
    H, Qee = _scatter_blocks(layout, problem.edge_x, problem.edge_y, hess, full[:, :7, :7])
    G = np.swapaxes(g[st.r0:].reshape(F, 3, 3), 1, 2)  # unvec of the rotation gradient blocks
    GtR = np.swapaxes(G, 1, 2) @ R
    curv = _sym(GtR) - np.trace(GtR, axis1=1, axis2=2)[:, None, None] * _I3
    rot = layout.r0 + 3 * np.arange(F)[:, None] + np.arange(3)
    H[rot[:, :, None], rot[:, None, :]] += curv
    if layout.alpha is not None:  # d2 (alpha t) / (dt d alpha) = I, contracted with g_t
        H[: 3 * F, layout.alpha] += g[: 3 * F]
        H[layout.alpha, : 3 * F] += g[: 3 * F]
    # H stays exactly symmetric: scattered and symmetrised, then symmetric terms added at
    # mirrored places (so no further symmetrisation, which would not change a bit)
    return Information(
        layout=layout, names=problem.frame_names, R=R.copy(), t=t.copy(), alpha=a,
        H=H, Q_ee=Qee, chi2=float(edge_chi2.sum()), n_pairs=problem.n_measurements,
        edge_chi2=edge_chi2)


def information_from_cost_matrix(
    problem: Problem, Q, X: np.ndarray, Y: np.ndarray, alpha: float = 1.0
) -> Information:
    """The same :class:`Information` from the assembled cost matrix ``Q`` of eq. (42) (without
    any prior penalty), e.g. the one a solve has built already: ``H = 2 J^T Q J`` plus the
    curvature terms of the gradient ``2 Q x`` (``J = dx / d xi``, ``x`` of eq. (44)).

    ``Q`` (12 F + 1, 12 F + 1), dense or sparse. ``chi2 = 2 x^T Q x`` here (rounding of order
    ``u |x|^T |Q| |x|``); :func:`information_matrix` sums the residuals directly.
    """
    import scipy.sparse as sp

    from ..model.cost import StateLayout, pack_state

    T, a = _check_estimate(problem, X, Y, alpha)
    F = T.shape[0]
    layout = TangentLayout(problem.M, problem.P, problem.unknown_scale)
    st = StateLayout(problem.M, problem.P)
    R, t = T[:, :3, :3], T[:, :3, 3]
    x = pack_state(st, T[: problem.M], T[problem.M:], a)
    Qd = Q.toarray() if sp.issparse(Q) else np.asarray(Q, float)
    g = 2.0 * (Qd @ x)
    # J: translations alpha I (and t for d alpha), rotations vec(R_f hat(e_k)) (right)
    J = np.zeros((st.size, layout.size))
    J[: 3 * F, : 3 * F] = a * np.eye(3 * F)
    if layout.alpha is not None:
        J[: 3 * F, layout.alpha] = t.reshape(-1)
        J[st.alpha, layout.alpha] = 1.0
    basis = np.swapaxes(R[:, None] @ hat(np.eye(3))[None], -1, -2).reshape(F, 3, 9)  # vec(R e_k^)
    for f in range(F):
        J[st.r_slice(f), layout.r0 + 3 * f: layout.r0 + 3 * f + 3] = basis[f].T
    H = 2.0 * J.T @ (Qd @ J)
    G = np.swapaxes(g[st.r0:].reshape(F, 3, 3), 1, 2)  # unvec of the rotation gradient blocks
    GtR = np.swapaxes(G, 1, 2) @ R
    curv = _sym(GtR) - np.trace(GtR, axis1=1, axis2=2)[:, None, None] * _I3
    for f in range(F):
        sl = slice(layout.r0 + 3 * f, layout.r0 + 3 * f + 3)
        H[sl, sl] += curv[f]
    if layout.alpha is not None:  # d2 (alpha t) / (dt d alpha) = I, contracted with g_t
        H[: 3 * F, layout.alpha] += g[: 3 * F]
        H[layout.alpha, : 3 * F] += g[: 3 * F]
    m = 3 * F + (1 if layout.unknown_scale else 0)
    elim = np.arange(m) if not layout.unknown_scale else np.r_[0:3 * F, st.alpha]
    return Information(
        layout=layout, names=problem.frame_names, R=R.copy(), t=t.copy(), alpha=a,
        H=_sym(H), Q_ee=Qd[np.ix_(elim, elim)].copy(), chi2=float(2.0 * x @ (Qd @ x)),
        n_pairs=problem.n_measurements, edge_chi2=np.full(len(problem.edges), np.nan))

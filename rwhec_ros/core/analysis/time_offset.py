"""What the data say about a time offset per camera: the profile Newton step and its information.

Each pair of camera ``k`` pairs the image with the pose stream at the image stamp; when the
camera's stamps are off by ``delta_k`` (``t_pose = t_image + delta_k``), the pose that belongs to
the image is ``A_i(delta_k)``, the stream at ``s_i + delta_k``. The MLE of the pose level (eq.
(33)) with the offsets as further unknowns is

.. math::

    \\min_{X, Y, \\alpha, \\delta} f = \\tfrac12 \\sum_i \\Big( |r_{t,i}(\\delta)|^2 / \\sigma_i^2
    + \\kappa_i \\| R_{A_i(\\delta)} R_X - R_Y R_{B_i} \\|_F^2 \\Big),

``r_t = alpha (R_A t_X + t_A - t_Y) - R_Y t_B``. Along the stream ``A`` moves with its twist rate
``xi_i = [rho, omega]`` (metres and radians per second, in ``A``'s parent frame):
``A_i(delta + e) = exp(e xi_i^) A_i(delta)`` to first order, so ``dA/d delta = xi^ A``. The
derivative of the whitened residual is then closed-form (:func:`offset_terms`).

Why a profile Newton step (and not a 1-D search with a solve at each trial offset, nor the
offsets inside the solver): the certified solver already gives ``X, Y, alpha`` optimal for the
current offsets, ``theta*(delta)``; the offsets' profile cost ``f(theta*(delta), delta)`` has
gradient ``g_delta - H_dt H_tt^+ g_theta`` and Hessian ``S = H_dd - H_dt H_tt^+ H_td`` (the Schur
complement of the joint Gauss-Newton information). One step ``-S^-1 g`` per certified solve
reaches the joint optimum in a few solves (the residuals are close to linear in the offsets over
the +-100 ms a camera is off), every camera's offset at once (they share the targets), and ``S``
is the marginal information of the offsets with ``X, Y, alpha`` free: its inverse, scaled by the
variance factor ``s0^2 = 2 f / dof`` of the residuals, is their model-based covariance. Pairs of
one image (several targets), of cameras triggered together and of neighbouring stream samples
share the stream's error, which that covariance takes as independent: given cluster labels,
:func:`offset_step` reports the cluster-robust ("sandwich") covariance ``S^-1 V S^-1`` instead,
``V`` the spread of the profile gradient over the clusters (:func:`_robust_covariance`). A grid
search needs tens of solves per camera and gives no standard deviation; offsets inside the local
solver would leave the certificate, which proves optimality for fixed pairs only. Here every solve
stays the certified solve of fixed pairs; the offsets only choose which pairs.

A camera whose pairs carry no rate (the rig at rest at its images: stop-and-go data) has no
information on its offset (``S_kk = 0``): :attr:`OffsetStep.determined` is False, and no number is
given for it.

The tangent of ``X, Y, alpha`` is :class:`~rwhec_ros.core.analysis.information.TangentLayout`'s
(right rotation perturbations, metric translations); ``H_tt`` is the exact Hessian of
:func:`~rwhec_ros.core.analysis.information.information_matrix` (or its edge-block form), the
cross and offset terms are Gauss-Newton (exact at zero residual).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..lie import hat
from ..numerics.pinv import pinv_solve
from ..problem import Problem
from .information import TangentLayout

__all__ = ["OffsetTerms", "OffsetStep", "offset_terms", "offset_step", "MIN_CLUSTERS"]

#: ``hat(e_l)`` for the three unit vectors, shape (3, 3, 3).
_E = hat(np.eye(3))
#: An offset is determined when its marginal information is at least this fraction of the
#: information the same pairs would carry with ``X, Y`` known (``S_kk / H_dd,kk``): below it the
#: offset is confounded with the extrinsics (e.g. a pure translation along the camera axis).
_MIN_INFORMATION_SHARE = 1e-6


@dataclass(frozen=True)
class OffsetTerms:
    """The offset parts of the Gauss-Newton system at an estimate (:func:`offset_terms`).

    Attributes
    ----------
    H_td : ndarray, shape (n, m)
        ``sum_i J_theta,i^T J_delta,i`` on the tangent of ``X, Y, alpha`` (``n``) and the
        offsets (``m``, one per Y frame of the problem, in its order).
    H_dd : ndarray, shape (m, m)
        ``sum_i J_delta,i^T J_delta,i`` (diagonal: a pair depends on its camera's offset only).
    g_t : ndarray, shape (n,)
        Gradient of ``f`` on ``X, Y, alpha`` (Gauss-Newton: ``sum J_theta^T e``).
    g_d : ndarray, shape (m,)
        Gradient of ``f`` on the offsets [1/s].
    cost : float
        ``f = 1/2 sum_i J_i`` at the estimate.
    n_pairs : int
    used : ndarray, shape (m,), int
        Pairs per camera that carry a rate (a finite, non-zero twist rate).
    pair_camera : ndarray, shape (N,), int, optional
        Each pair's offset (camera) index (problem order); with the two below, each pair's share
        of the gradients, for the cluster-robust covariance of :func:`offset_step`.
    pair_score_d : ndarray, shape (N,), optional
        ``J_delta,i^T e_i``: the pair's share of ``g_d``.
    pair_score_t : ndarray, shape (N, L), optional
        ``J_theta,i^T e_i`` on the pair's ``L`` tangent coordinates ``pair_tangent``.
    pair_tangent : ndarray, shape (N, L), int, optional
        Those coordinates' indices in the tangent of ``X, Y, alpha``.
    """

    H_td: np.ndarray
    H_dd: np.ndarray
    g_t: np.ndarray
    g_d: np.ndarray
    cost: float
    n_pairs: int
    used: np.ndarray
    pair_camera: np.ndarray | None = None
    pair_score_d: np.ndarray | None = None
    pair_score_t: np.ndarray | None = None
    pair_tangent: np.ndarray | None = None


@dataclass(frozen=True)
class OffsetStep:
    """The profile Newton step on the offsets and their marginal information
    (:func:`offset_step`).

    Attributes
    ----------
    step_s : ndarray, shape (m,)
        ``-S^-1 g`` on the determined offsets [s]; 0 for the others.
    information : ndarray, shape (m, m)
        ``S = H_dd - H_dt H_tt^+ H_td`` [1/s^2] (stated noise).
    gradient : ndarray, shape (m,)
        The profile gradient ``g_d - H_dt H_tt^+ g_t``.
    determined : ndarray, shape (m,), bool
        Offsets the data determine (information above the floor of the module docstring).
    covariance : ndarray, shape (m, m)
        The offsets' covariance [s^2] on the determined offsets, NaN in the rows and columns of
        the others: the cluster-robust one where clusters are given (each offset's variance at
        least its model-based one), else the model-based ``s0^2 S^-1``.
    covariance_model : ndarray, shape (m, m)
        ``s0^2 S^-1`` (independent pairs, the stated weights' shape).
    clusters : int
        Clusters of the cluster-robust covariance (0: model-based only).
    variance_factor : float
        ``s0^2 = 2 f / dof``, ``dof = 6 N - n - m`` (at least 1).
    cost : float
        ``f`` at the estimate.
    """

    step_s: np.ndarray
    information: np.ndarray
    gradient: np.ndarray
    determined: np.ndarray
    covariance: np.ndarray
    variance_factor: float
    cost: float
    covariance_model: np.ndarray | None = None
    clusters: int = 0

    @property
    def std_s(self) -> np.ndarray:
        """Standard deviation of each offset [s] (a posteriori), NaN where not determined."""
        return np.sqrt(np.diag(self.covariance))


def _check_rates(problem: Problem, rates: np.ndarray) -> np.ndarray:
    r = np.asarray(rates, dtype=float)
    n = problem.n_measurements
    if r.shape != (n, 6):
        raise ValueError(f"rates: expected shape ({n}, 6) (one twist rate per pair, problem "
                         f"order), got {r.shape}")
    return np.where(np.isfinite(r), r, 0.0)


def offset_terms(problem: Problem, X: np.ndarray, Y: np.ndarray, alpha: float,
                 rates: np.ndarray) -> OffsetTerms:
    """The offset parts of the Gauss-Newton system of the module docstring.

    Parameters
    ----------
    problem : Problem
    X, Y : ndarray, shape (M, 4, 4) and (P, 4, 4)
        The estimate (metric translations), problem order.
    alpha : float
        Its scale (ignored for known scale).
    rates : ndarray, shape (N, 6)
        Per pair (problem order: edge by edge), the twist rate ``[rho, omega]`` of the stream at
        the pair's stamp, ``dA/d delta = xi^ A`` [m/s, rad/s]; a row of zeros or NaN: the pair
        says nothing about its camera's offset (at rest, or the stream does not cover it).

    Returns
    -------
    OffsetTerms
        One offset per Y frame of ``problem``.
    """
    X, Y = np.asarray(X, dtype=float), np.asarray(Y, dtype=float)
    if X.shape != (problem.M, 4, 4) or Y.shape != (problem.P, 4, 4):
        raise ValueError(f"X, Y: expected shapes ({problem.M}, 4, 4) and ({problem.P}, 4, 4), "
                         f"got {X.shape} and {Y.shape}")
    xi = _check_rates(problem, rates)
    a = float(alpha) if problem.unknown_scale else 1.0
    layout = TangentLayout(problem.M, problem.P, problem.unknown_scale)
    st = problem.stacked()
    N = xi.shape[0]
    RA, tA = st["A"][:, :3, :3], st["A"][:, :3, 3]
    RB, tB = st["B"][:, :3, :3], st["B"][:, :3, 3]
    RX, tX = X[st["xi"], :3, :3], X[st["xi"], :3, 3]
    RY, tY = Y[st["yi"], :3, :3], Y[st["yi"], :3, 3]
    ws = 1.0 / st["sigma"]
    wk = np.sqrt(st["kappa"])
    u = np.einsum("nij,nj->ni", RA, tX) + tA  # R_A t_X + t_A
    p = u - tY
    C = RA @ RX
    e = np.empty((N, 12))
    e[:, :3] = (a * p - np.einsum("nij,nj->ni", RY, tB)) * ws[:, None]
    e[:, 3:] = ((C - RY @ RB) * wk[:, None, None]).reshape(N, 9)
    # Jacobian on [dt_X, dt_Y, d alpha, w_X, w_Y] (TangentLayout's local order)
    J = np.zeros((N, 12, 13))
    J[:, :3, 0:3] = a * RA * ws[:, None, None]
    J[:, 0, 3] = J[:, 1, 4] = J[:, 2, 5] = -a * ws
    J[:, :3, 6] = p * ws[:, None]
    J[:, :3, 10:13] = (RY @ hat(tB)) * ws[:, None, None]
    for v in range(3):  # columns vec(R_A R_X e_v^) and -vec(R_Y e_v^ R_B), scaled
        J[:, 3:, 7 + v] = (C @ _E[v]).reshape(N, 9) * wk[:, None]
        J[:, 3:, 10 + v] = -((RY @ _E[v]) @ RB).reshape(N, 9) * wk[:, None]
    rho, om = xi[:, :3], xi[:, 3:]
    Jd = np.empty((N, 12))
    Jd[:, :3] = a * (np.cross(om, u) + rho) * ws[:, None]
    Jd[:, 3:] = (hat(om) @ C * wk[:, None, None]).reshape(N, 9)
    starts = np.r_[0, np.cumsum([ed.n for ed in problem.edges])[:-1]].astype(int)
    both = (np.stack([Jd, e], axis=1) @ J)  # (N, 2, 13): J^T J_delta and J^T e per pair
    cross = np.add.reduceat(both[:, 0], starts, axis=0)  # (E, 13)
    grad = np.add.reduceat(both[:, 1], starts, axis=0)
    dd = np.add.reduceat((Jd * Jd).sum(axis=1), starts)
    gd = np.add.reduceat((Jd * e).sum(axis=1), starts)
    moving = np.add.reduceat((np.abs(xi) > 0).any(axis=1).astype(int), starts)
    idx = layout.pair_indices(problem.edge_x, problem.edge_y)  # (E, 13 or 12)
    local = slice(None) if problem.unknown_scale else np.r_[0:6, 7:13]
    n, m = layout.size, problem.P
    H_td = np.zeros((n, m))
    g_t = np.zeros(n)
    H_dd = np.zeros((m, m))
    g_d = np.zeros(m)
    used = np.zeros(m, dtype=int)
    for k_edge, k in enumerate(problem.edge_y):
        H_td[idx[k_edge], k] += cross[k_edge, local]
        g_t[idx[k_edge]] += grad[k_edge, local]
        H_dd[k, k] += dd[k_edge]
        g_d[k] += gd[k_edge]
        used[k] += moving[k_edge]
    sizes = [ed.n for ed in problem.edges]
    return OffsetTerms(H_td=H_td, H_dd=H_dd, g_t=g_t, g_d=g_d,
                       cost=0.5 * float((e * e).sum()), n_pairs=N, used=used,
                       pair_camera=np.repeat(np.asarray(problem.edge_y, dtype=int), sizes),
                       pair_score_d=(Jd * e).sum(axis=1),
                       pair_score_t=both[:, 1][:, local],
                       pair_tangent=np.repeat(np.asarray(idx, dtype=int), sizes, axis=0))


def offset_step(terms: OffsetTerms, H_tt: np.ndarray,
                clusters: np.ndarray | None = None) -> OffsetStep:
    """The profile Newton step and the marginal information of the offsets (module docstring).

    Parameters
    ----------
    terms : OffsetTerms
        :func:`offset_terms` at the estimate.
    H_tt : ndarray, shape (n, n)
        Hessian of ``f`` on ``X, Y, alpha`` at the same estimate
        (:func:`~rwhec_ros.core.analysis.information.information_matrix` ``.H``).
    clusters : ndarray, shape (N,), int, optional
        A label per pair (problem order): pairs whose errors may be correlated share a label
        (pairs of one image, of images taken together, pairs interpolated from the same stretch
        of the pose stream). Given (and at least :data:`MIN_CLUSTERS` labels), the covariance is
        the cluster-robust one (:func:`_robust_covariance`).
    """
    H_tt = np.asarray(H_tt, dtype=float)
    n, m = terms.H_td.shape
    if H_tt.shape != (n, n):
        raise ValueError(f"H_tt: expected shape ({n}, {n}), got {H_tt.shape}")
    if clusters is not None and np.shape(clusters) != (terms.n_pairs,):
        raise ValueError(f"clusters: expected shape ({terms.n_pairs},) (one label per pair), "
                         f"got {np.shape(clusters)}")
    Z = pinv_solve(H_tt, np.c_[terms.H_td, terms.g_t])
    S = terms.H_dd - terms.H_td.T @ Z[:, :m]
    S = 0.5 * (S + S.T)
    g = terms.g_d - terms.H_td.T @ Z[:, m]
    hdd = np.diag(terms.H_dd)
    determined = (terms.used > 0) & (hdd > 0) & (np.diag(S) > _MIN_INFORMATION_SHARE * hdd)
    step = np.zeros(m)
    cov = np.full((m, m), np.nan)
    cov_model = cov.copy()
    n_clusters = 0
    dof = max(1, 6 * terms.n_pairs - n - int(determined.sum()))
    s0 = 2.0 * terms.cost / dof
    if determined.any():
        ix = np.flatnonzero(determined)
        Sd = S[np.ix_(ix, ix)]
        try:
            L = np.linalg.cholesky(Sd)
        except np.linalg.LinAlgError:
            w = np.linalg.eigvalsh(Sd)
            determined[ix[w.argmin()]] = False  # the worst-determined combination: give up one
            return offset_step(dataclasses.replace(
                terms, used=np.where(determined, terms.used, 0)), H_tt, clusters)
        Sinv = np.linalg.inv(L).T @ np.linalg.inv(L)
        step[ix] = -Sinv @ g[ix]
        cov_model[np.ix_(ix, ix)] = s0 * Sinv
        cov = cov_model.copy()
        if clusters is not None and terms.pair_score_d is not None:
            robust, n_clusters = _robust_covariance(terms, Z[:, :m], clusters, ix, Sinv,
                                                    s0 * np.diag(Sinv))
            if robust is not None:
                cov[np.ix_(ix, ix)] = robust
    return OffsetStep(step_s=step, information=S, gradient=g, determined=determined,
                      covariance=cov, variance_factor=s0, cost=terms.cost,
                      covariance_model=cov_model, clusters=n_clusters)


#: Fewest clusters for the cluster-robust covariance; below it the model-based one is kept (the
#: sandwich's middle term is an average over clusters: with few it is itself too uncertain).
MIN_CLUSTERS = 20


def _robust_covariance(terms: OffsetTerms, Z: np.ndarray, clusters: np.ndarray,
                       ix: np.ndarray, Sinv: np.ndarray, model_variance: np.ndarray
                       ) -> tuple[np.ndarray | None, int]:
    """The cluster-robust ("sandwich") covariance of the determined offsets ``ix``:
    ``S^-1 (G / (G - 1) sum_g c_g c_g^T) S^-1``, ``c_g`` the profile gradient
    ``g_d - H_dt H_tt^+ g_t`` summed over cluster ``g``'s pairs, ``Z = H_tt^+ H_td`` (n, m).

    Why: the model-based ``s0^2 S^-1`` takes every pair's residual as independent, with the
    translation and rotation parts independent too. Pairs of one image (several targets) share
    the pose-stream pose and its error, pairs of cameras triggered together share it too, and a
    stream's error is correlated over its neighbouring samples; the rotation error of the stream
    moves the translation residual by the lever arm. All of these add to the offsets' variance
    without showing in ``s0``: with the stream's error shared by the pairs of one image the
    model-based std is 2.0-2.3x too small (``test/core/test_time_offset.py``); on the rendered
    rigs of ``benchmarks/time_offset.md`` (10 seeds) the offsets' error over their std has an
    RMS of 1.32 / 1.20 with it and 1.27 / 1.12 with this one (0.2 / 0.8 m/s): closer, still
    small. The sandwich estimates the variance of the gradient from the residuals themselves,
    correlations within a cluster included (Liang & Zeger 1986; White 1980 for clusters of one),
    and stays consistent when the weights are wrong. Each offset's variance is kept at least its
    model-based one (the sandwich is noisier: with few clusters it can fall below by chance), by
    scaling its row and column. ``(None, G)`` when there are fewer than :data:`MIN_CLUSTERS`
    clusters."""
    labels, inverse = np.unique(np.asarray(clusters), return_inverse=True)
    G = labels.shape[0]
    if G < MIN_CLUSTERS:
        return None, G
    n, m = Z.shape
    U = np.zeros((G, n))  # per cluster, J_theta^T e summed on the global tangent
    np.add.at(U, (np.repeat(inverse, terms.pair_tangent.shape[1]), terms.pair_tangent.ravel()),
              terms.pair_score_t.ravel())
    D = np.zeros((G, m))  # per cluster, J_delta^T e per offset
    np.add.at(D, (inverse, terms.pair_camera), terms.pair_score_d)
    C = (D - U @ Z)[:, ix]
    meat = (G / (G - 1.0)) * (C.T @ C)
    robust = Sinv @ meat @ Sinv
    robust = 0.5 * (robust + robust.T)
    scale = np.sqrt(np.maximum(1.0, model_variance / np.maximum(np.diag(robust), 1e-300)))
    return robust * np.outer(scale, scale), G

"""Closed-form initial estimate: rotations from the null vector of the rotation-only cost, then
the optimal translations and scale (eq. (47)).

This is the linear "vectorised rotations" estimate in the spirit of Wang et al. (2022): minimise
``r^T L_rho r`` (the kappa-weighted rotation terms of eq. (36)) over ``|r| = const``, fix the sign
and magnitude so that the rotation blocks have positive unit determinant on average, project every
block onto SO(3), and recover translations (and ``alpha``) in closed form from the reduced cost.
Used to start the local solvers and to scale the SDP data by an upper bound on the optimum.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..model.cost import StateLayout, build_cost_matrices
from ..model.estimate import Estimate, rotations_from_vector
from ..model.reduction import ReducedCost
from ..numerics.verified import lanczos_start
from ..problem import Problem

__all__ = ["closed_form_estimate", "estimate_from_rotations", "primal_cost", "proven_cost",
           "initial_rotations"]


def estimate_from_rotations(
    problem: Problem, reduced: ReducedCost, R: np.ndarray
) -> Estimate:
    """Optimal translations and scale for fixed rotations ``R`` (n, 3, 3), eq. (47)."""
    n = problem.n_frames
    z = np.concatenate([np.swapaxes(R, 1, 2).reshape(-1), [1.0]])
    ta = reduced.recover @ z
    alpha = float(ta[-1]) if problem.unknown_scale else 1.0
    t_alpha = ta[:-1].reshape(n, 3)
    t = t_alpha / alpha if abs(alpha) > 1e-12 else t_alpha
    cost = float(z @ reduced.Qr @ z)
    return Estimate(R=R, t=t, alpha=alpha, cost=cost)


def closed_form_estimate(
    problem: Problem, reduced: ReducedCost, Q_rot: np.ndarray | sp.spmatrix | None = None
) -> Estimate:
    """Closed-form (uncertified) estimate; see the module docstring. ``Q_rot`` is the rotation-only
    cost matrix of :func:`~rwhec_ros.core.model.cost.build_cost_matrices` (built if not given)."""
    n = problem.n_frames
    layout = StateLayout(problem.M, problem.P)
    if Q_rot is None:
        Q_rot = build_cost_matrices(problem)[1]
    rr = slice(layout.r0, layout.size)
    L = Q_rot[rr, rr]
    d = L.shape[0]
    if d <= 200:
        L = L.toarray() if sp.issparse(L) else np.asarray(L)
        w, V = np.linalg.eigh(L)
        v = V[:, 0]
    elif d <= 1000 or not sp.issparse(L):
        L = L.toarray() if sp.issparse(L) else np.asarray(L)  # a sparse cost above DENSE_MAX_SIZE
        w, V = scipy.linalg.eigh(L, subset_by_index=[0, 0], driver="evr")
        v = V[:, 0]
    else:
        L = sp.csr_matrix(L)
        shift = 1e-9 * abs(L).max()
        w, V = spla.eigsh(L + shift * sp.eye(d), k=1, sigma=0, which="LM",
                          v0=lanczos_start(d))
        v = V[:, 0]
    R, _ = rotations_from_vector(v, n)
    return estimate_from_rotations(problem, reduced, R)


def primal_cost(problem: Problem, est: Estimate, gauge=None) -> float:
    """``p`` of a certificate: a proven upper bound on the cost of ``est`` in exact arithmetic,
    the cost evaluated directly from the residuals of eq. (33)
    (:func:`~rwhec_ros.core.model.cost.direct_cost`) plus the term of the prior that fixes
    unobservable translations (:class:`~rwhec_ros.core.model.gauge.GaugeFix`) when there is one,
    each plus the bound on its rounding (:func:`~rwhec_ros.core.model.cost.direct_cost_error`,
    :meth:`~rwhec_ros.core.model.gauge.GaugeFix.penalty_error`; about ``u L / r`` relative), the sum
    rounded upwards. A certificate compares it with its dual bound, so the rounding of the cost
    can only make it more cautious."""
    X, Y = est.split(problem.M)
    if gauge is None or not gauge.has_penalty:
        return proven_cost(problem, X, Y, est.alpha)
    from ..model.cost import direct_cost_error

    p, err = direct_cost_error(problem, X, Y, est.alpha)
    h = est.alpha if problem.unknown_scale else 1.0
    p += gauge.penalty_value(est.t, h)
    err += gauge.penalty_error(est.t, h)
    return float(np.nextafter(p + err, np.inf))


def proven_cost(problem: Problem, X: np.ndarray, Y: np.ndarray, alpha: float = 1.0) -> float:
    """A proven upper bound on the cost (eq. (33), no prior term) of ``X`` (M, 4, 4), ``Y``
    (P, 4, 4) and ``alpha`` (used for unknown scale only) on ``problem``'s data: the direct cost
    plus the bound on its rounding (:func:`~rwhec_ros.core.model.cost.direct_cost_error`), rounded
    upwards; :func:`primal_cost` without a prior."""
    from ..model.cost import direct_cost_error

    p, err = direct_cost_error(problem, X, Y, alpha if problem.unknown_scale else 1.0)
    return float(np.nextafter(p + err, np.inf))


def initial_rotations(problem: Problem, initial: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """The rotations (n, 3, 3) of a given start ``(X (M, 4, 4), Y (P, 4, 4))`` in state order;
    ``ValueError`` naming ``initial`` when the counts do not match the problem."""
    X0, Y0 = initial
    R0 = np.concatenate([np.asarray(X0, float), np.asarray(Y0, float)])[:, :3, :3]
    if R0.shape != (problem.n_frames, 3, 3):
        raise ValueError(f"initial: expected {problem.M} X and {problem.P} Y transforms, "
                         f"got {R0.shape[0]} in total")
    return R0

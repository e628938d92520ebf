"""Dornaika and Horaud (1998): joint nonlinear least squares on rotations and translations
(any connected graph, known scale), started from :func:`~.wang2022.wang2022`."""

from __future__ import annotations

import numpy as np

from ..lie import hat, project_to_so3, so3_exp
from ..problem import Problem
from .opencv import BaselineOutput
from .wang2022 import wang2022

__all__ = ["dornaika1998", "dornaika_cost"]


def _vec_hat_generators() -> np.ndarray:
    """``vec(hat(e_k))`` for k = 0, 1, 2 as columns (9, 3), column-major ``vec``."""
    return np.stack([hat(np.eye(3)[k]).T.reshape(9) for k in range(3)], axis=1)


def _dornaika_residuals(
    problem: Problem,
    X: np.ndarray,
    Y: np.ndarray,
    lambda_rot: float,
    lambda_trans: float,
    with_jacobian: bool,
):
    """Stacked residuals (12 per pair) and optionally the Jacobian w.r.t. the local
    perturbation ``[dphi_X (3M), dphi_Y (3P), dt_X (3M), dt_Y (3P)]`` with
    ``R <- R exp(dphi^)`` and ``t <- t + dt``."""
    M, n = problem.M, problem.n_frames
    G = _vec_hat_generators()
    wr, wt = np.sqrt(lambda_rot), np.sqrt(lambda_trans)
    res, jacs = [], []
    for e, j, k in zip(problem.edges, problem.edge_x, problem.edge_y, strict=True):
        N = e.n
        RA, tA = e.A[:, :3, :3], e.A[:, :3, 3]
        RB, tB = e.B[:, :3, :3], e.B[:, :3, 3]
        RX, tX = X[j, :3, :3], X[j, :3, 3]
        RY, tY = Y[k, :3, :3], Y[k, :3, 3]
        RARX = RA @ RX
        rR = RARX - RY @ RB  # (N, 3, 3)
        rt = RA @ tX + tA - tY - tB @ RY.T  # (N, 3)
        r = np.concatenate([wr * np.swapaxes(rR, 1, 2).reshape(N, 9), wt * rt], axis=1)
        res.append(r.reshape(-1))
        if not with_jacobian:
            continue
        J = np.zeros((N, 12, 6 * n))
        I3 = np.eye(3)
        # d vec(R_A R_X exp(w^)) / dw = (I (x) R_A R_X) G
        kx = np.einsum("ab,nij->naibj", I3, RARX).reshape(N, 9, 9)
        J[:, :9, 3 * j : 3 * j + 3] = wr * kx @ G
        # d vec(-R_Y exp(w^) R_B) / dw = -(R_B^T (x) R_Y) G
        ky = np.einsum("nba,ij->naibj", RB, RY).reshape(N, 9, 9)
        J[:, :9, 3 * (M + k) : 3 * (M + k) + 3] = -wr * ky @ G
        # d(-R_Y exp(w^) t_B)/dw = R_Y hat(t_B)
        J[:, 9:, 3 * (M + k) : 3 * (M + k) + 3] = wt * RY @ hat(tB)
        o = 3 * n
        J[:, 9:, o + 3 * j : o + 3 * j + 3] = wt * RA
        J[:, 9:, o + 3 * (M + k) : o + 3 * (M + k) + 3] = -wt * I3
        jacs.append(J.reshape(12 * N, 6 * n))
    r = np.concatenate(res)
    return (r, np.concatenate(jacs)) if with_jacobian else (r, None)


def dornaika_cost(
    problem: Problem,
    X: np.ndarray,
    Y: np.ndarray,
    *,
    lambda_rot: float = 1.0,
    lambda_trans: float = 1.0,
) -> float:
    """Dornaika & Horaud's joint objective
    ``sum lambda_rot |R_A R_X - R_Y R_B|_F^2 + lambda_trans |R_A t_X + t_A - R_Y t_B - t_Y|^2``."""
    r, _ = _dornaika_residuals(problem, X, Y, lambda_rot, lambda_trans, with_jacobian=False)
    return float(r @ r)


def dornaika1998(
    problem: Problem,
    X0: np.ndarray | None = None,
    Y0: np.ndarray | None = None,
    *,
    lambda_rot: float = 1.0,
    lambda_trans: float = 1.0,
    max_iterations: int = 100,
    tol: float = 1e-12,
) -> BaselineOutput:
    """Simultaneous nonlinear RWHEC of Dornaika & Horaud (1998), generalized to graphs.

    Minimises :func:`dornaika_cost` jointly over rotations and translations by
    Levenberg-Marquardt on the manifold (right perturbations ``R exp(phi^)``), starting from
    ``X0, Y0`` (default: :func:`wang2022`, as in the paper's tables). Dornaika & Horaud use
    unit quaternions with a penalty ``lambda (1 - q^T q)^2`` on the norm; the on-manifold
    parametrisation enforces the constraint exactly (the limit of a large penalty). Their
    rotation term is the chordal (Frobenius) error, the translation term is in metres, and both
    weights are 1, i.e. **not** the noise-model weighting of the MLE.

    Parameters
    ----------
    problem : Problem
        Known scale, connected graph.
    X0 : ndarray, shape (M, 4, 4), optional
    Y0 : ndarray, shape (P, 4, 4), optional
    lambda_rot, lambda_trans : float
        Weights of the rotation and translation terms.
    max_iterations : int
    tol : float
        Stop when the relative cost decrease or the step norm falls below ``tol``.

    Returns
    -------
    X : ndarray, shape (M, 4, 4)
    Y : ndarray, shape (P, 4, 4)
    alpha : float
        Always 1.0.
    """
    if not isinstance(problem, Problem):
        raise ValueError(f"dornaika: problem must be a Problem, got {type(problem).__name__}")
    if problem.unknown_scale:
        raise ValueError("dornaika: unknown_scale=True is not supported (known-scale method)")
    for name, val in (("lambda_rot", lambda_rot), ("lambda_trans", lambda_trans)):
        if not np.isfinite(val) or val <= 0:
            raise ValueError(f"dornaika: {name} must be finite and > 0, got {val!r}")
    if X0 is None or Y0 is None:
        Xw, Yw, _ = wang2022(problem)
        X0 = Xw if X0 is None else X0
        Y0 = Yw if Y0 is None else Y0
    X = np.array(X0, dtype=float).reshape(problem.M, 4, 4)
    Y = np.array(Y0, dtype=float).reshape(problem.P, 4, 4)
    M, n = problem.M, problem.n_frames
    r, J = _dornaika_residuals(problem, X, Y, lambda_rot, lambda_trans, True)
    cost = float(r @ r)
    mu = 1e-6
    for _ in range(max_iterations):
        H = J.T @ J
        g = J.T @ r
        while True:
            step = -np.linalg.solve(H + mu * np.diag(np.diag(H) + 1e-12), g)
            Xn, Yn = _retract(X, Y, step, M, n)
            rn, _ = _dornaika_residuals(problem, Xn, Yn, lambda_rot, lambda_trans, False)
            cn = float(rn @ rn)
            if cn <= cost or mu > 1e12:
                break
            mu *= 10.0
        if cn > cost:
            break
        decrease = cost - cn
        X, Y = Xn, Yn
        r, J = _dornaika_residuals(problem, X, Y, lambda_rot, lambda_trans, True)
        cost = float(r @ r)
        mu = max(mu / 10.0, 1e-12)
        if decrease <= tol * max(cost, 1e-300) or np.linalg.norm(step) <= tol:
            break
    return X, Y, 1.0


def _retract(X: np.ndarray, Y: np.ndarray, step: np.ndarray, M: int, n: int):
    T = np.concatenate([X, Y]).copy()
    dphi = step[: 3 * n].reshape(n, 3)
    dt = step[3 * n :].reshape(n, 3)
    T[:, :3, :3] = project_to_so3(T[:, :3, :3] @ so3_exp(dphi))
    T[:, :3, 3] = T[:, :3, 3] + dt
    return T[:M], T[M:]


"""Local solver on the SDP's own MLE objective: damped Riemannian Newton on the dense ``Q'``.

The objective is the reduced chordal cost of Problem 6, ``f(R) = z^T Q' z`` with
``z = [vec R_1, ..., vec R_n, 1]`` (translations and, for unknown scale, ``alpha`` eliminated in
closed form by eq. (47)), minimised over SO(3)^n by a damped Riemannian Newton method with
right perturbations ``R_l <- R_l exp(omega_l^)``. The multipliers of the fast certificate at its
solution are :mod:`rwhec_ros.core.certify.multipliers`.

With ``G_l`` the 3x3 block of ``Q' z`` belonging to ``R_l`` (half the Euclidean gradient):

* Riemannian gradient: ``g_l = 2 * vee(R_l^T G_l - G_l^T R_l)`` (``vee`` of the antisymmetric part),
* Riemannian Hessian: ``H = 2 J^T Q' J + 2 Diag(S_l - tr(S_l) I)`` with ``S_l = sym(R_l^T G_l)``
  and ``J`` the block-diagonal map ``omega_l -> vec(R_l omega_l^)``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..lie import so3_exp, vee

__all__ = [
    "LocalSolverOptions",
    "LocalSolution",
    "refine_rotations",
    "damped_newton",
]


@dataclass
class LocalSolverOptions:
    """Options of :func:`refine_rotations`.

    Attributes
    ----------
    max_iterations : int
    gradient_tol : float
        Stop when the Riemannian gradient norm is below ``gradient_tol * max(1, f)`` (1e-10).
    step_tol : float
        Stop when the step norm is below this (1e-12 rad).
    """

    max_iterations: int = 100
    gradient_tol: float = 1e-10
    step_tol: float = 1e-12


@dataclass
class LocalSolution:
    """Rotations (n, 3, 3), cost ``f``, Riemannian gradient norm, iterations, convergence flag."""

    R: np.ndarray
    cost: float
    gradient_norm: float
    iterations: int
    converged: bool


def _z_of(R: np.ndarray) -> np.ndarray:
    return np.concatenate([np.swapaxes(R, 1, 2).reshape(-1), [1.0]])


def _basis_jacobian(R: np.ndarray) -> np.ndarray:
    """``J_l[:, i] = vec(R_l hat(e_i))``, shape (n, 9, 3); written out column by column:
    ``vec(R e1^) = [0, R_3, -R_2]``, ``vec(R e2^) = [-R_3, 0, R_1]``,
    ``vec(R e3^) = [R_2, -R_1, 0]``
    with ``R_c`` the columns of ``R``."""
    n = R.shape[0]
    J = np.zeros((n, 9, 3))
    c1, c2, c3 = R[:, :, 0], R[:, :, 1], R[:, :, 2]
    J[:, 3:6, 0] = c3
    J[:, 6:9, 0] = -c2
    J[:, 0:3, 1] = -c3
    J[:, 6:9, 1] = c1
    J[:, 0:3, 2] = c2
    J[:, 3:6, 2] = -c1
    return J


def _cost_grad(Q: np.ndarray, R: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """``f = z^T Q z`` at rotations ``R`` (n, 3, 3), its Riemannian gradient (3 n,) and
    ``R_l^T G_l`` (n, 3, 3) (``G_l`` the unvec of the rotation blocks of ``Q z``), which the
    Hessian's curvature term needs."""
    n = R.shape[0]
    z = _z_of(R)
    Qz = Q @ z
    f = float(z @ Qz)
    G = np.swapaxes(Qz[: 9 * n].reshape(n, 3, 3), 1, 2)  # unvec blocks
    RtG = np.swapaxes(R, 1, 2) @ G
    g = 2.0 * (2.0 * vee(RtG))  # d f / d omega = 2 tr(G^T R hat w) = 4 vee(R^T G) . w
    return f, g.reshape(-1), RtG


def _hessian(Q: np.ndarray, R: np.ndarray, RtG: np.ndarray) -> np.ndarray:
    """The Riemannian Hessian (3 n, 3 n) of ``z^T Q z`` at ``R`` (``RtG`` from
    :func:`_cost_grad`)."""
    n = R.shape[0]
    J = _basis_jacobian(R)  # (n, 9, 3)
    # H = 2 J^T Q_rr J with block-diagonal J, as two batched products (BLAS, no einsum loops)
    Qrr = Q[: 9 * n, : 9 * n]
    QJ = np.matmul(Qrr.reshape(9 * n, n, 9).transpose(1, 0, 2), J)  # (n, 9n, 3): Q[:, l] J_l
    QJ = QJ.transpose(1, 0, 2).reshape(n, 9, 3 * n)  # row blocks k of [Q J]
    H = 2.0 * np.matmul(np.swapaxes(J, 1, 2), QJ).reshape(3 * n, 3 * n)
    S = 0.5 * (RtG + np.swapaxes(RtG, 1, 2))
    D = S - np.trace(S, axis1=1, axis2=2)[:, None, None] * np.eye(3)
    blk = np.arange(3 * n).reshape(n, 3)  # the n diagonal 3x3 blocks, in one indexed add
    H[blk[:, :, None], blk[:, None, :]] += 2.0 * D
    H_sym = H + H.T
    H_sym *= 0.5  # 0.5 (H + H^T) with one temporary fewer (the same bits)
    return H_sym


def _grad_hess(Q: np.ndarray, R: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Cost, Riemannian gradient and Hessian of ``z^T Q z`` at ``R``."""
    f, g, RtG = _cost_grad(Q, R)
    return f, g, _hessian(Q, R, RtG)


class _DenseModel:
    """Cost, gradient and Hessian of the reduced cost at ``R`` for :func:`damped_newton`; the
    Hessian is formed when a step needs it (never at the point where the iteration stops)."""

    def __init__(self, Q: np.ndarray, R: np.ndarray) -> None:
        self.f, self.g, self._RtG = _cost_grad(Q, R)
        self._Q, self._R = Q, R

    @functools.cached_property
    def H(self) -> np.ndarray:
        return _hessian(self._Q, self._R, self._RtG)

    @functools.cached_property
    def scale_h(self) -> float:
        return max(1.0, float(np.max(np.abs(np.diag(self.H)))))

    def step(self, damping: float) -> np.ndarray:
        return -np.linalg.solve(self.H + damping * np.eye(self.H.shape[0]), self.g)

    def curvature(self, step: np.ndarray, damping: float) -> float:
        return float(step @ self.H @ step)


def damped_newton(R0: np.ndarray, evaluate, options: LocalSolverOptions, f_noise: float,
                  f_floor: float = 1.0, first=None) -> LocalSolution:
    """Damped Riemannian Newton over SO(3)^n with right perturbations, shared by the dense and the
    sparse local solvers.

    ``evaluate(R)`` returns a model with the cost ``f``, the Riemannian gradient ``g`` (3 n,), a
    damping scale ``scale_h``, ``step(damping)`` (the step solving ``(H + damping I) step =
    -g``; raises ``numpy.linalg.LinAlgError`` when it cannot) and ``curvature(step, damping)``
    (``step^T H step``). A step is accepted when the decrease is at least a quarter of the
    predicted one or below the round-off level ``f_noise``; the damping grows tenfold on every
    rejection and shrinks tenfold on acceptance. Stops when ``|g| <= gradient_tol max(f_floor,
    |f|)`` or the step is below ``step_tol``. ``first``: the model at ``R0`` if already built.
    """
    R = np.array(R0, dtype=float)
    n = R.shape[0]
    mu = 1e-6
    m = first if first is not None else evaluate(R)
    converged = False
    it = 0
    step = np.zeros(3 * n)
    for it in range(1, options.max_iterations + 1):
        gnorm = float(np.linalg.norm(m.g))
        if gnorm <= options.gradient_tol * max(f_floor, abs(m.f)):
            converged = True
            it -= 1
            break
        accepted = False
        for _ in range(30):
            lam = mu * m.scale_h
            try:
                step = m.step(lam)
            except np.linalg.LinAlgError:
                mu *= 10.0
                continue
            if not m.g @ step < 0.0:  # not a descent direction: H + mu I is not pos. definite
                mu *= 10.0
                continue
            R_new = R @ so3_exp(step.reshape(n, 3))
            m_new = evaluate(R_new)
            predicted = -(m.g @ step + 0.5 * m.curvature(step, lam))
            actual = m.f - m_new.f
            if actual >= 0.25 * predicted or abs(actual) <= f_noise:
                R, m = R_new, m_new
                mu = max(mu / 10.0, 1e-12)
                accepted = True
                break
            mu *= 10.0
        if not accepted:
            break
        if float(np.linalg.norm(step)) < options.step_tol:
            converged = True
            break
    return LocalSolution(R=R, cost=m.f, gradient_norm=float(np.linalg.norm(m.g)), iterations=it,
                         converged=converged)


def refine_rotations(
    Q: np.ndarray, R0: np.ndarray, options: LocalSolverOptions | None = None
) -> LocalSolution:
    """Minimise ``z^T Q z`` over SO(3)^n from ``R0`` (n, 3, 3) by damped Riemannian Newton
    (:func:`damped_newton`).

    ``Q`` (9 n + 1, 9 n + 1) is the (possibly scaled) reduced cost of eq. (48).
    """
    n = np.asarray(R0).shape[0]
    # round-off level of f = z^T Q z at |z|^2 = 3 n + 1: decreases below it are noise
    f_noise = 64.0 * np.finfo(float).eps * float(np.abs(Q).max()) * (3 * n + 1)
    return damped_newton(R0, lambda R: _DenseModel(Q, R), options or LocalSolverOptions(),
                         f_noise)


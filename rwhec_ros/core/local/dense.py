"""Local solver on the SDP's own MLE objective and the fast (SE-Sync style) certificate.

The objective is the reduced chordal cost of Problem 6, ``f(R) = z^T Q' z`` with
``z = [vec R_1, ..., vec R_n, 1]`` (translations and, for unknown scale, ``alpha`` eliminated in
closed form by eq. (47)), minimised over SO(3)^n by a damped Riemannian Newton method with
right perturbations ``R_l <- R_l exp(omega_l^)``.

With ``G_l`` the 3x3 block of ``Q' z`` belonging to ``R_l`` (half the Euclidean gradient):

* Riemannian gradient: ``g_l = 2 * vee(R_l^T G_l - G_l^T R_l)`` (``vee`` of the antisymmetric part),
* Riemannian Hessian: ``H = 2 J^T Q' J + 2 Diag(S_l - tr(S_l) I)`` with ``S_l = sym(R_l^T G_l)``
  and ``J`` the block-diagonal map ``omega_l -> vec(R_l omega_l^)``.

Fast certificate (cf. SE-Sync, Rosen et al. 2019): at a first-order critical point the Lagrange
multipliers of the orthogonality constraints ``R^T R = s^2 I`` (eq. (50b)) are
``Gamma_l = sym(R_l^T G_l)``, and those of ``s^2 = 1`` is ``lambda_s = p`` (the cost), which gives::

    Z = Q' - Diag(Gamma_l (x) I_3, 0) + (sum_l tr(Gamma_l) - lambda_s) e_s e_s^T,

with ``Z z = 0``. Its multipliers for the remaining constraints of eq. (50) are zero, which is a
valid (if not always the strongest) dual point: if ``Z >= 0`` the solution is globally optimal by
weak duality (the bound of :mod:`certificate` applies unchanged); if ``lambda_min(Z) < 0`` the fast
certificate is inconclusive and :func:`rwhec_ros.core.solve.solve` falls back to the SDP.
At a non-global critical point ``Z`` cannot be PSD, so a wrong basin is never certified.
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
    "fast_certificate_multipliers",
    "fast_certificate_matrix",
    "handedness_multipliers",
    "strengthen_certificate",
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


def fast_certificate_multipliers(Q: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The first-order multipliers at ``R`` as a vector over the constraints of
    :func:`~rwhec_ros.core.certify.relaxation.so3_constraint_matrices` (21 per rotation, then
    ``s^2``).

    Only the column-orthogonality constraints (50b) get non-zero multipliers: ``Gamma_l[a, a]``
    for ``(R^T R)_aa = s^2`` and ``2 Gamma_l[a, b]`` for ``(R^T R)_ab = 0`` (``a < b``: the
    constraint counts the pair once), and ``lambda_s = z^T Q z`` (the cost). Then
    ``K(lambda) = Diag(Gamma_l (x) I_3, lambda_s - sum_l tr Gamma_l)`` and ``Z = Q - K`` is the
    matrix of the module docstring. Returns shape (21 n + 1,), in the units of ``Q``.
    """
    n = R.shape[0]
    z = _z_of(R)
    Qz = Q @ z
    G = np.swapaxes(Qz[: 9 * n].reshape(n, 3, 3), 1, 2)
    RtG = np.swapaxes(R, 1, 2) @ G
    Gamma = 0.5 * (RtG + np.swapaxes(RtG, 1, 2))
    lam = np.zeros(21 * n + 1)
    pairs = [(a, b) for a in range(3) for b in range(a, 3)]  # the (50b) order of the constraints
    for c, (a, b) in enumerate(pairs):
        lam[6 + c: 21 * n: 21] = Gamma[:, a, b] * (1.0 if a == b else 2.0)
    lam[-1] = float(z @ Qz)
    return lam


def fast_certificate_matrix(Q: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, float]:
    """Certificate matrix ``Z`` and ``lambda_s`` from the first-order multipliers at ``R``.

    Returns ``(Z, lambda_s)`` in the units of ``Q``; see the module docstring.
    """
    n = R.shape[0]
    z = _z_of(R)
    Qz = Q @ z
    G = np.swapaxes(Qz[: 9 * n].reshape(n, 3, 3), 1, 2)
    RtG = np.swapaxes(R, 1, 2) @ G
    Gamma = 0.5 * (RtG + np.swapaxes(RtG, 1, 2))
    lambda_s = float(z @ Qz)
    Z = np.array(Q, dtype=float, copy=True)
    # Gamma_l (x) I_3, all l at once: block (a, b) of rotation l is Gamma_l[a, b] I_3
    kron = np.einsum("lab,ij->laibj", Gamma, np.eye(3)).reshape(n, 9, 9)
    for l in range(n):
        sl = slice(9 * l, 9 * l + 9)
        Z[sl, sl] -= kron[l]
    Z[-1, -1] += float(np.trace(Gamma, axis1=1, axis2=2).sum()) - lambda_s
    return 0.5 * (Z + Z.T), lambda_s


def handedness_multipliers(R: np.ndarray) -> np.ndarray:
    """A multiplier direction (vector over the constraints, like
    :func:`fast_certificate_multipliers`) whose matrix ``D`` satisfies ``D z = 0``.

    For each rotation ``l`` it is the quadratic form of
    ``g_l(z) = sum_cyc R*_c . (R_a x R_b - s R_c) - 1/2 (|R|_F^2 - 3 s^2)``: a combination of the
    handedness constraints (50c), weighted by the current columns ``R*_c``, and of the column
    norm constraints (50b). At the feasible ``z*`` its gradient vanishes (the handedness part
    contributes ``R*_a`` per column and ``-3`` on ``s``, the norm part cancels both), so
    ``Z - t D`` satisfies the stationarity ``Z z* = 0`` for every ``t``.
    """
    n = R.shape[0]
    lam = np.zeros(21 * n + 1)
    cyclic = ((0, 1, 2), (1, 2, 0), (2, 0, 1))
    for l in range(n):
        base = 21 * l
        for a_col in (0, 3, 5):  # the diagonal column constraints |R_a|^2 - s^2
            lam[base + 6 + a_col] = -0.5
        for ci, (_, _, c) in enumerate(cyclic):
            for k in range(3):
                lam[base + 12 + 3 * ci + k] = R[l, k, c]
    return lam


def handedness_direction(R: np.ndarray) -> np.ndarray:
    """The dense (9 n + 1, 9 n + 1) matrix of :func:`handedness_multipliers`."""
    from ..certify.relaxation import so3_constraint_matrices

    n = R.shape[0]
    d = 9 * n + 1
    return so3_constraint_matrices(np.arange(n) * 9, d, d - 1).apply(handedness_multipliers(R))


def strengthen_certificate(Z: np.ndarray, R: np.ndarray, *, null_tol: float = 1e-6
                           ) -> tuple[float, float]:
    """Step along :func:`handedness_direction` to lift spurious null directions of the fast
    certificate, keeping ``Z z* = 0``.

    The orthogonality-only multipliers leave ``e_s`` in the null space whenever the cost does not
    couple ``s`` to the rotations at the optimum (e.g. single-sphere trajectories, where eq. (63)
    fails); the handedness constraints can. ``t`` maximises the smallest eigenvalue of
    ``Z - t D`` on the complement of ``z*`` -- a concave function of ``t`` (minimum of affine
    functions), maximised by a bounded scalar search. Returns ``(t, that eigenvalue)``: the
    multipliers become ``lambda + t * handedness_multipliers(R)`` (``Z - t D``).
    """
    from scipy.optimize import minimize_scalar

    z = _z_of(R)
    z = z / np.linalg.norm(z)
    D = handedness_direction(R)
    big = float(np.abs(Z).max()) + 1.0
    Zp = Z + big * np.outer(z, z)

    def lam_perp(t: float) -> float:
        return float(np.linalg.eigvalsh(Zp - t * D)[0])

    scale = float(np.abs(Z).max()) / max(float(np.abs(D).max()), 1e-300)
    res = minimize_scalar(lambda t: -lam_perp(t), bounds=(-scale, scale), method="bounded",
                          options={"xatol": 1e-6 * scale})
    t_best = float(res.x) if lam_perp(float(res.x)) > lam_perp(0.0) else 0.0
    return t_best, lam_perp(t_best)

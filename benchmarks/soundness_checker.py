"""Independent checker of a certified RWHEC result (issue 10): own cost, own local solver.

Nothing here imports ``rwhec_ros``. The objective is eq. (33) of Wise et al. (IJRR 2025) with the
1/2 of eq. (42), written from the paper::

    f(X, Y, alpha) = 1/2 sum_pairs ( |alpha (R_A t_X + t_A - t_Y) - R_Y t_B|^2 / sigma^2
                                     + kappa |R_A R_X - R_Y R_B|_F^2 )

with metric ``t_X, t_Y`` (``alpha = 1`` for known scale). The local solver works on
``u = alpha t`` (the paper's scaled unknowns, eq. (22)), where the translation residual
``R_A u_X + alpha t_A - u_Y - R_Y t_B`` is linear, and rotations ``R = R_ref exp(w)``
(rotation vectors ``w``, re-centred between runs); it is :func:`scipy.optimize.least_squares`
with an analytic Jacobian, from random starts (uniform rotations, translations at the scene scale,
log-uniform positive ``alpha``), the product's estimate and the ground truth. For unknown scale
``alpha >= 0`` is a bound: the physical problem has ``alpha > 0`` and a point with ``alpha = 0``
is the limit of feasible points (``t = u / alpha``), so its cost is an infimum of feasible costs.

Costs of candidate points are evaluated in extended precision (``np.longdouble``); a point that
beats a dual bound is confirmed in exact rational arithmetic (:func:`exact_cost`) on rotation
matrices that are exactly orthogonal (rational quaternions).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

__all__ = ["Pairs", "Point", "CheckerOptions", "CheckResult", "direct_cost", "direct_cost_metric",
           "exact_cost", "check_minimum", "optimal_translations", "project_so3"]


@dataclass
class Pairs:
    """All measurement pairs stacked. ``xi`` (N,) X-frame index, ``yi`` (N,) global index
    ``M + k`` of the Y frame; ``RA, RB`` (N,3,3), ``tA, tB`` (N,3), ``sigma, kappa`` (N,)."""

    M: int
    P: int
    RA: np.ndarray
    tA: np.ndarray
    RB: np.ndarray
    tB: np.ndarray
    sigma: np.ndarray
    kappa: np.ndarray
    xi: np.ndarray
    yi: np.ndarray
    unknown_scale: bool

    @property
    def n(self) -> int:
        return self.M + self.P

    @staticmethod
    def from_edges(M: int, P: int, edges, unknown_scale: bool) -> Pairs:
        """From ``[(j, k, A (N,4,4), B (N,4,4), sigma (N,), kappa (N,)), ...]``."""
        A = np.concatenate([e[2] for e in edges])
        B = np.concatenate([e[3] for e in edges])
        xi = np.concatenate([np.full(e[2].shape[0], e[0]) for e in edges])
        yi = np.concatenate([np.full(e[2].shape[0], M + e[1]) for e in edges])
        return Pairs(M, P, A[:, :3, :3], A[:, :3, 3], B[:, :3, :3], B[:, :3, 3],
                     np.concatenate([e[4] for e in edges]).astype(float),
                     np.concatenate([e[5] for e in edges]).astype(float), xi, yi,
                     bool(unknown_scale))

    def scene_scale(self) -> float:
        """Typical translation length [m] of the data (random starts use it)."""
        s = np.median(np.r_[np.linalg.norm(self.tA, axis=1), np.linalg.norm(self.tB, axis=1)])
        return float(max(s, 1e-3))


@dataclass
class Point:
    """A candidate solution: rotations ``R`` (n,3,3) (X frames then Y frames), scaled
    translations ``u = alpha t`` (n,3) and ``alpha`` (1 for known scale)."""

    R: np.ndarray
    u: np.ndarray
    alpha: float

    @property
    def t(self) -> np.ndarray:
        """Metric translations ``u / alpha`` (inf where ``alpha = 0``)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.u / self.alpha


def project_so3(M: np.ndarray) -> np.ndarray:
    """Nearest rotation(s) to ``M`` (...,3,3) in the Frobenius norm (SVD, det +1)."""
    U, _, Vt = np.linalg.svd(M)
    D = np.ones(M.shape[:-1])
    D[..., -1] = np.sign(np.linalg.det(U @ Vt))
    return (U * D[..., None, :]) @ Vt


def direct_cost(pairs: Pairs, point: Point, dtype=np.longdouble) -> float:
    """``f`` of eq. (33) at ``point`` in arithmetic ``dtype`` (longdouble: extended precision).

    With the scaled translations the residual is ``R_A u_X + alpha t_A - u_Y - R_Y t_B``, which
    equals ``alpha (R_A t_X + t_A - t_Y) - R_Y t_B`` for ``u = alpha t``.
    """
    c = lambda a: np.asarray(a, dtype=dtype)
    R, u, al = c(point.R), c(point.u), c(point.alpha)
    RA, tA, RB, tB = c(pairs.RA), c(pairs.tA), c(pairs.RB), c(pairs.tB)
    RX, RY = R[pairs.xi], R[pairs.yi]
    rt = (np.einsum("nij,nj->ni", RA, u[pairs.xi]) + al * tA - u[pairs.yi]
          - np.einsum("nij,nj->ni", RY, tB))
    rR = RA @ RX - RY @ RB
    terms = (rt**2).sum(axis=1) / c(pairs.sigma) ** 2 + c(pairs.kappa) * (rR**2).sum(axis=(1, 2))
    return float(c(0.5) * np.sort(terms).sum())


def direct_cost_metric(pairs: Pairs, R: np.ndarray, t: np.ndarray, alpha: float,
                       dtype=np.longdouble) -> float:
    """``f`` of eq. (33) at rotations ``R`` (n,3,3), METRIC translations ``t`` (n,3) and
    ``alpha``, in the form ``alpha (R_A t_X + t_A - t_Y) - R_Y t_B`` of a returned estimate."""
    c = lambda a: np.asarray(a, dtype=dtype)
    R, t, al = c(R), c(t), c(alpha)
    RA, tA, RB, tB = c(pairs.RA), c(pairs.tA), c(pairs.RB), c(pairs.tB)
    rt = (al * (np.einsum("nij,nj->ni", RA, t[pairs.xi]) + tA - t[pairs.yi])
          - np.einsum("nij,nj->ni", R[pairs.yi], tB))
    rR = RA @ R[pairs.xi] - R[pairs.yi] @ RB
    terms = (rt**2).sum(axis=1) / c(pairs.sigma) ** 2 + c(pairs.kappa) * (rR**2).sum(axis=(1, 2))
    return float(c(0.5) * np.sort(terms).sum())


def _exact_rotation(R: np.ndarray) -> list[list[Fraction]]:
    """An exactly orthogonal rational rotation within ~1e-16 of ``R``: the rotation of the
    (float, hence rational) quaternion of ``R``, divided by its exact squared norm."""
    x, y, z, w = (Fraction(float(v)) for v in Rotation.from_matrix(R).as_quat())
    n2 = x * x + y * y + z * z + w * w
    m = [[w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
         [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
         [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z]]
    return [[v / n2 for v in row] for row in m]


def exact_cost(pairs: Pairs, point: Point) -> tuple[Fraction, Point]:
    """Exact rational ``f`` at an exactly feasible neighbour of ``point`` (rotations made exactly
    orthogonal, :func:`_exact_rotation`); returns the cost and that neighbour (float copy)."""
    Rq = [_exact_rotation(R) for R in point.R]
    u = [[Fraction(float(v)) for v in row] for row in point.u]
    al = Fraction(float(point.alpha))
    F = lambda a: [[Fraction(float(v)) for v in row] for row in a]
    mm = lambda a, b: [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)]
                       for i in range(3)]
    mv = lambda a, v: [sum(a[i][k] * v[k] for k in range(3)) for i in range(3)]
    total = Fraction(0)
    for i in range(pairs.RA.shape[0]):
        RA, RB = F(pairs.RA[i]), F(pairs.RB[i])
        tA = [Fraction(float(v)) for v in pairs.tA[i]]
        tB = [Fraction(float(v)) for v in pairs.tB[i]]
        RX, RY = Rq[pairs.xi[i]], Rq[pairs.yi[i]]
        a, b = mv(RA, u[pairs.xi[i]]), mv(RY, tB)
        rt = [a[r] + al * tA[r] - u[pairs.yi[i]][r] - b[r] for r in range(3)]
        P1, P2 = mm(RA, RX), mm(RY, RB)
        rR2 = sum((P1[r][c] - P2[r][c]) ** 2 for r in range(3) for c in range(3))
        s2, kap = Fraction(float(pairs.sigma[i])) ** 2, Fraction(float(pairs.kappa[i]))
        total += sum(v * v for v in rt) / s2 + kap * rR2
    R_float = np.array([[[float(v) for v in row] for row in Rm] for Rm in Rq])
    return total / 2, Point(R_float, point.u.copy(), point.alpha)


# --- the local solver ---------------------------------------------------------------------------

def _hat(v: np.ndarray) -> np.ndarray:
    """Skew matrices (...,3,3) of vectors (...,3)."""
    H = np.zeros(v.shape[:-1] + (3, 3))
    H[..., 0, 1], H[..., 0, 2] = -v[..., 2], v[..., 1]
    H[..., 1, 0], H[..., 1, 2] = v[..., 2], -v[..., 0]
    H[..., 2, 0], H[..., 2, 1] = -v[..., 1], v[..., 0]
    return H


def _right_jacobian(w: np.ndarray) -> np.ndarray:
    """Right Jacobian of SO(3) (n,3,3): ``exp(w + dw) = exp(w) exp(Jr(w) dw) + O(dw^2)``."""
    th = np.linalg.norm(w, axis=1)
    W = _hat(w)
    small = th < 1e-5
    ths = np.where(small, 1.0, th)
    a = np.where(small, 0.5 - th**2 / 24, (1 - np.cos(ths)) / ths**2)
    b = np.where(small, 1 / 6 - th**2 / 120, (ths - np.sin(ths)) / ths**3)
    return np.eye(3) - a[:, None, None] * W + b[:, None, None] * (W @ W)


def _rotate(R_ref: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``R_ref exp(w)`` for (n,3,3) and (n,3)."""
    return R_ref @ Rotation.from_rotvec(w).as_matrix().reshape(-1, 3, 3)


def _rotation_residuals(p: Pairs, R: np.ndarray) -> np.ndarray:
    """``sqrt(kappa) (R_A R_X - R_Y R_B)`` flattened, (9 N,)."""
    return ((p.RA @ R[p.xi] - R[p.yi] @ p.RB) * np.sqrt(p.kappa)[:, None, None]).ravel()


def _rotation_jacobian(p: Pairs, R: np.ndarray, Jr: np.ndarray) -> np.ndarray:
    """Jacobian (9 N, 3 n) of :func:`_rotation_residuals` w.r.t. the rotation vectors, with
    ``dR/dw_m = R [Jr e_m]x``."""
    N, n = p.RA.shape[0], p.n
    k = np.sqrt(p.kappa)[:, None, None, None]
    G_X = _hat(np.swapaxes(Jr[p.xi], 1, 2))  # (N, m, 3, 3): [c_m]x, c_m = column m of Jr
    G_Y = _hat(np.swapaxes(Jr[p.yi], 1, 2))
    dX = ((p.RA @ R[p.xi])[:, None] @ G_X) * k  # (N, m, 3, 3)
    dY = -(R[p.yi][:, None] @ G_Y @ p.RB[:, None]) * k
    dX = np.swapaxes(dX.reshape(N, 3, 9), 1, 2)
    dY = np.swapaxes(dY.reshape(N, 3, 9), 1, 2)
    J = np.zeros((9 * N, 3 * n))
    rows = 9 * np.arange(N)[:, None, None] + np.arange(9)[None, :, None]
    J[rows, (3 * p.xi[:, None] + np.arange(3))[:, None, :]] = dX
    J[rows, (3 * p.yi[:, None] + np.arange(3))[:, None, :]] = dY
    return J


class _Translations:
    """The translation residual ``r_t = C theta + b(R)`` (weighted by ``1/sigma``), linear in
    ``theta = [u (3 n), (alpha)]`` with ``C`` independent of the rotations and
    ``b = (t_A - R_Y t_B) / sigma`` (known scale) or ``-R_Y t_B / sigma`` (unknown). ``C`` is
    factored once (SVD, rank at machine precision); for unknown scale also without its ``alpha``
    column (the branch ``alpha = 0`` of the bound ``alpha >= 0``)."""

    def __init__(self, p: Pairs):
        self.p = p
        N, n = p.RA.shape[0], p.n
        self.s = 1.0 / p.sigma
        C = np.zeros((3 * N, 3 * n + (1 if p.unknown_scale else 0)))
        rows = 3 * np.arange(N)[:, None] + np.arange(3)
        C[rows[:, :, None], (3 * p.xi[:, None] + np.arange(3))[:, None, :]] = \
            p.RA * self.s[:, None, None]
        C[rows[:, :, None], (3 * p.yi[:, None] + np.arange(3))[:, None, :]] = \
            -np.eye(3) * self.s[:, None, None]
        if p.unknown_scale:
            C[rows, -1] = p.tA * self.s[:, None]
        self.C = C
        self.bases = [self._basis(C)]
        if p.unknown_scale:
            self.bases.append(self._basis(C[:, :-1]))

    @staticmethod
    def _basis(C: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        U, s, Vt = np.linalg.svd(C, full_matrices=False)
        keep = s > s[0] * np.finfo(float).eps * max(C.shape)
        return U[:, keep], s[keep], Vt[keep]

    def b(self, R: np.ndarray) -> np.ndarray:
        """``b`` (3 N,): ``-R_Y t_B / sigma``, plus ``t_A / sigma`` for known scale."""
        p = self.p
        b = -np.einsum("nij,nj->ni", R[p.yi], p.tB)
        if not p.unknown_scale:
            b = b + p.tA
        return (b * self.s[:, None]).ravel()

    def db_dw(self, R: np.ndarray, Jr: np.ndarray) -> np.ndarray:
        """Jacobian (3 N, 3 n) of ``b``: ``d(-R_Y t_B)/dw_Y = R_Y [t_B]x Jr_Y``."""
        p = self.p
        N = p.RA.shape[0]
        D = np.zeros((3 * N, 3 * p.n))
        blk = R[p.yi] @ _hat(p.tB) @ Jr[p.yi] * self.s[:, None, None]
        D[(3 * np.arange(N)[:, None] + np.arange(3))[:, :, None],
          (3 * p.yi[:, None] + np.arange(3))[:, None, :]] = blk
        return D

    def solve(self, b: np.ndarray) -> tuple[np.ndarray, int]:
        """Minimiser ``theta`` of ``|C theta + b|`` subject to ``alpha >= 0``, and the branch
        (0: unconstrained, 1: ``alpha = 0``)."""
        U, s, Vt = self.bases[0]
        theta = -Vt.T @ ((U.T @ b) / s)
        if self.p.unknown_scale and theta[-1] < 0:
            U, s, Vt = self.bases[1]
            return np.r_[-Vt.T @ ((U.T @ b) / s), 0.0], 1
        return theta, 0

    def refine(self, theta: np.ndarray, b: np.ndarray, branch: int) -> np.ndarray:
        """One step of iterative refinement with the residual in extended precision (large
        translations along nearly unobservable directions lose digits in float64)."""
        r = (self.C.astype(np.longdouble) @ theta.astype(np.longdouble)
             + b.astype(np.longdouble)).astype(float)
        U, s, Vt = self.bases[branch]
        step = -Vt.T @ ((U.T @ r) / s)
        if branch == 1:
            step = np.r_[step, 0.0]
        return theta + step

    def point(self, R: np.ndarray) -> Point:
        """``R`` with its exactly optimal translations (and scale)."""
        b = self.b(R)
        theta, branch = self.solve(b)
        theta = self.refine(theta, b, branch)
        n = self.p.n
        alpha = float(theta[-1]) if self.p.unknown_scale else 1.0
        return Point(R, theta[: 3 * n].reshape(n, 3), alpha)


class _Projected:
    """Variable projection: residuals of eq. (33) as a function of the rotation vectors only,
    translations (and scale) at their exact optimum. Since ``C`` does not depend on the rotations,
    the projected residual ``(I - U U^T) b(R)`` has the exact Jacobian ``(I - U U^T) db/dw``."""

    def __init__(self, trans: _Translations, R_ref: np.ndarray):
        self.t, self.p, self.R_ref = trans, trans.p, R_ref

    def _branch(self, b: np.ndarray) -> int:
        return self.t.solve(b)[1]

    def residuals(self, w: np.ndarray) -> np.ndarray:
        R = _rotate(self.R_ref, w.reshape(-1, 3))
        b = self.t.b(R)
        U = self.t.bases[self._branch(b)][0]
        return np.concatenate([b - U @ (U.T @ b), _rotation_residuals(self.p, R)])

    def jacobian(self, w: np.ndarray) -> np.ndarray:
        w = w.reshape(-1, 3)
        R, Jr = _rotate(self.R_ref, w), _right_jacobian(w)
        b = self.t.b(R)
        U = self.t.bases[self._branch(b)][0]
        D = self.t.db_dw(R, Jr)
        return np.vstack([D - U @ (U.T @ D), _rotation_jacobian(self.p, R, Jr)])


class _Compressed:
    """The projected cost of :class:`_Projected` as ``|L z|^2 / 2`` with ``z = [R_1.ravel(), ...,
    R_n.ravel(), 1]``: every residual of eq. (33) is affine in the rotation entries, so the
    projected residual is ``F z`` and ``F^T F = L^T L`` with ``L`` of size at most ``9 n + 1``
    (independent of the number of pairs). Stage 1 of the search runs on this form (fast); the
    polish runs on the raw residuals. For unknown scale, the optimal ``alpha = a . z`` of the
    unconstrained projection is linear too, and ``alpha < 0`` switches to the factor of the
    ``alpha = 0`` branch."""

    def __init__(self, trans: _Translations):
        p = trans.p
        N, n = p.RA.shape[0], p.n
        self.n = n
        # translation rows: b = G z (+ t_A / sigma on the constant for known scale)
        G = np.zeros((3 * N, 9 * n + 1))
        rows = 3 * np.arange(N)[:, None] + np.arange(3)  # (N, 3): row i of pair
        for kk in range(3):  # -(R_Y t_B)_i = -sum_k R_Y[i, k] t_B[k]
            cols = 9 * p.yi[:, None] + 3 * np.arange(3)[None, :] + kk
            G[rows, cols] = -(p.tB[:, kk] * trans.s)[:, None]
        if not p.unknown_scale:
            G[:, -1] = (p.tA * trans.s[:, None]).ravel()
        # rotation rows: (R_A R_X).ravel() = kron(R_A, I) R_X.ravel(),
        # (R_Y R_B).ravel() = kron(I, R_B^T) R_Y.ravel()
        k = np.sqrt(p.kappa)[:, None, None]
        F_rot = np.zeros((9 * N, 9 * n + 1))
        r9 = 9 * np.arange(N)[:, None, None] + np.arange(9)[None, :, None]
        c9 = np.arange(9)[None, None, :]
        F_rot[r9, 9 * p.xi[:, None, None] + c9] = np.einsum("nij,lk->niljk", p.RA,
                                                             np.eye(3)).reshape(N, 9, 9) * k
        F_rot[r9, 9 * p.yi[:, None, None] + c9] = -np.einsum("ij,nlk->niljk", np.eye(3),
                                                              np.swapaxes(p.RB, 1, 2)
                                                              ).reshape(N, 9, 9) * k
        H_rot = F_rot.T @ F_rot
        self.factors = []
        for U, _, _ in trans.bases:
            UG = U.T @ G
            H = H_rot + G.T @ G - UG.T @ UG
            lam, V = np.linalg.eigh(0.5 * (H + H.T))
            self.factors.append(np.sqrt(np.clip(lam, 0.0, None))[:, None] * V.T)
        self.a = None
        if p.unknown_scale:
            U, s, Vt = trans.bases[0]
            self.a = -(Vt[:, -1] / s) @ (U.T @ G)  # alpha of the unconstrained optimum
        self.R_ref = None

    def _L(self, z: np.ndarray) -> np.ndarray:
        return self.factors[1 if self.a is not None and self.a @ z < 0 else 0]

    @staticmethod
    def _z(R: np.ndarray) -> np.ndarray:
        return np.r_[R.reshape(-1), 1.0]

    def residuals(self, w: np.ndarray) -> np.ndarray:
        z = self._z(_rotate(self.R_ref, w.reshape(-1, 3)))
        return self._L(z) @ z

    def jacobian(self, w: np.ndarray) -> np.ndarray:
        w = w.reshape(-1, 3)
        R, Jr = _rotate(self.R_ref, w), _right_jacobian(w)
        z = self._z(R)
        n = self.n
        blocks = R[:, None] @ _hat(np.swapaxes(Jr, 1, 2))  # (n, m, 3, 3): R [c_m]x
        D = np.zeros((9 * n + 1, 3 * n))
        D[(9 * np.arange(n)[:, None, None] + np.arange(9)[None, :, None]),
          (3 * np.arange(n)[:, None, None] + np.arange(3)[None, None, :])] = \
            np.swapaxes(blocks.reshape(n, 3, 9), 1, 2)
        return self._L(z) @ D


class _Joint:
    """Residuals of eq. (33) on ``x = [w (3 n), u (3 n), (alpha)]`` (all unknowns at once)."""

    def __init__(self, trans: _Translations, R_ref: np.ndarray):
        self.t, self.p, self.R_ref = trans, trans.p, R_ref
        self.n = trans.p.n

    def split(self, x: np.ndarray) -> Point:
        n = self.n
        alpha = float(x[-1]) if self.p.unknown_scale else 1.0
        return Point(_rotate(self.R_ref, x[: 3 * n].reshape(n, 3)),
                     x[3 * n: 6 * n].reshape(n, 3), alpha)

    def residuals(self, x: np.ndarray) -> np.ndarray:
        R = _rotate(self.R_ref, x[: 3 * self.n].reshape(-1, 3))
        return np.concatenate([self.t.C @ x[3 * self.n:] + self.t.b(R),
                               _rotation_residuals(self.p, R)])

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        w = x[: 3 * self.n].reshape(-1, 3)
        R, Jr = _rotate(self.R_ref, w), _right_jacobian(w)
        top = np.hstack([self.t.db_dw(R, Jr), self.t.C])
        bottom = np.hstack([_rotation_jacobian(self.p, R, Jr),
                            np.zeros((9 * self.p.RA.shape[0], self.t.C.shape[1]))])
        return np.vstack([top, bottom])


@dataclass
class CheckerOptions:
    """Budget of the independent local solves.

    Attributes
    ----------
    n_random : int
        Random starts of the projected (rotation-only) solver (>= 20 for the benchmark).
    n_joint : int
        Extra random starts of the joint solver (random rotations, translations at the scene
        scale and, for unknown scale, a log-uniform positive ``alpha``).
    n_polish : int
        At most this many distinct stage-1 results within ``polish_window`` (relative) of the
        best are polished to tight tolerance.
    loose_tol, tight_tol : float
        ``ftol = xtol = gtol`` of stage 1 and of the polish.
    loose_nfev, tight_nfev : int
        Evaluation budgets of stage 1 and of the polish.
    """

    n_random: int = 20
    n_joint: int = 1
    n_polish: int = 3
    polish_window: float = 0.01
    loose_tol: float = 1e-6
    tight_tol: float = 1e-12
    loose_nfev: int = 60
    tight_nfev: int = 60


@dataclass
class CheckResult:
    """Best point the checker found, its extended-precision cost, and bookkeeping."""

    best: Point
    best_cost: float
    best_origin: str
    n_starts: int
    seconds: float


def _projected_run(trans: _Translations, R0: np.ndarray, tol: float, nfev: int) -> Point:
    model = _Projected(trans, R0)
    sol = least_squares(model.residuals, np.zeros(3 * trans.p.n), jac=model.jacobian,
                        method="lm", ftol=tol, xtol=tol, gtol=tol, max_nfev=nfev)
    return trans.point(_rotate(R0, sol.x.reshape(-1, 3)))


def _compressed_run(comp: _Compressed, trans: _Translations, R0: np.ndarray, tol: float,
                    nfev: int) -> Point:
    comp.R_ref = R0
    sol = least_squares(comp.residuals, np.zeros(3 * trans.p.n), jac=comp.jacobian,
                        method="lm", ftol=tol, xtol=tol, gtol=tol, max_nfev=nfev)
    return trans.point(_rotate(R0, sol.x.reshape(-1, 3)))


def _joint_run(trans: _Translations, start: Point, tol: float, nfev: int) -> list[Point]:
    """Joint Levenberg-Marquardt run on all unknowns (``alpha`` free); returns the end point when
    it is feasible (``alpha >= 0``) and its rotations with exactly optimal translations."""
    p, n = trans.p, trans.p.n
    model = _Joint(trans, start.R)
    x0 = np.r_[np.zeros(3 * n), start.u.ravel(), [start.alpha] if p.unknown_scale else []]
    sol = least_squares(model.residuals, x0, jac=model.jacobian, method="lm", ftol=tol,
                        xtol=tol, gtol=tol, max_nfev=nfev)
    end = model.split(sol.x)
    return ([end] if end.alpha >= 0 else []) + [trans.point(end.R)]


def optimal_translations(pairs: Pairs, R: np.ndarray) -> Point:
    """``R`` (n,3,3) with the exactly optimal translations (and ``alpha >= 0``) of eq. (33)."""
    return _Translations(pairs).point(R)


def check_minimum(pairs: Pairs, rng: np.random.Generator, starts: dict[str, Point] | None = None,
                  options: CheckerOptions | None = None) -> CheckResult:
    """Search for the global minimum of eq. (33).

    Stage 1 (loose tolerance): ``n_random`` projected runs on the compressed form
    (:class:`_Compressed`) from uniformly random rotations, ``n_joint`` joint runs on the raw
    residuals from random rotations, translations and scale, and a projected run from each named
    start (e.g. the product's estimate, the ground truth). Stage 2: the best distinct stage-1
    points (at most ``n_polish``, within ``polish_window`` of the best) are polished on the raw
    residuals (projected run, exact translations), and the best of those once more by a joint run
    on all unknowns. Every candidate -- including each named start's own rotations with exactly
    optimal translations, which checks a translation recovery -- is costed in extended precision
    (:func:`direct_cost`); the cheapest wins.
    """
    opts = options or CheckerOptions()
    t0 = time.perf_counter()
    trans = _Translations(pairs)
    comp = _Compressed(trans)
    n, scale = pairs.n, pairs.scene_scale()
    rand_R = lambda: Rotation.random(n, random_state=rng).as_matrix().reshape(n, 3, 3)
    stage1: list[tuple[str, Point]] = []
    for i in range(opts.n_random):
        stage1.append((f"random {i}", _compressed_run(comp, trans, rand_R(), opts.loose_tol,
                                                     opts.loose_nfev)))
    for i in range(opts.n_joint):
        alpha = float(np.exp(rng.uniform(np.log(0.1), np.log(10.0)))) \
            if pairs.unknown_scale else 1.0
        st = Point(rand_R(), alpha * scale * rng.standard_normal((n, 3)), alpha)
        for q in _joint_run(trans, st, opts.loose_tol, opts.loose_nfev):
            stage1.append((f"joint random {i}", q))
    final: list[tuple[float, str, Point]] = []
    for name, st in (starts or {}).items():
        R0 = project_so3(st.R)
        fixed = trans.point(R0)
        final.append((direct_cost(pairs, fixed), f"{name} rotations, optimal translations",
                      fixed))
        stage1.append((name, _compressed_run(comp, trans, R0, opts.loose_tol, opts.loose_nfev)))
    scored = sorted(((direct_cost(pairs, pt, float), name, pt) for name, pt in stage1),
                    key=lambda c: c[0])
    chosen = [scored[0]]
    for c in scored[1:]:
        if len(chosen) == opts.n_polish or c[0] > scored[0][0] * (1 + opts.polish_window):
            break
        if all(abs(c[0] - d[0]) > 1e-9 * abs(d[0]) for d in chosen):
            chosen.append(c)
    polished: list[tuple[float, str, Point]] = []
    for _c, name, pt in chosen:
        final.append((direct_cost(pairs, pt), name, pt))
        q = _projected_run(trans, pt.R, opts.tight_tol, opts.tight_nfev)
        polished.append((direct_cost(pairs, q), name + " +polish", q))
    top = min(polished, key=lambda c: c[0])
    for q in _joint_run(trans, top[2], opts.tight_tol, opts.tight_nfev):
        polished.append((direct_cost(pairs, q), top[1] + " +joint", q))
    best = min(final + polished, key=lambda c: c[0])
    return CheckResult(best=best[2], best_cost=best[0], best_origin=best[1],
                       n_starts=len(stage1), seconds=time.perf_counter() - t0)

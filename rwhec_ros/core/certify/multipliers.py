"""The fast (SE-Sync style) certificate's multipliers at a local solution of the dense path.

Fast certificate (cf. SE-Sync, Rosen et al. 2019): at a first-order critical point the Lagrange
multipliers of the orthogonality constraints ``R^T R = s^2 I`` (eq. (50b)) are
``Gamma_l = sym(R_l^T G_l)``, and those of ``s^2 = 1`` is ``lambda_s = p`` (the cost), which gives::

    Z = Q' - Diag(Gamma_l (x) I_3, 0) + (sum_l tr(Gamma_l) - lambda_s) e_s e_s^T,

with ``Z z = 0``. Its multipliers for the remaining constraints of eq. (50) are zero, which is a
valid (if not always the strongest) dual point: if ``Z >= 0`` the solution is globally optimal by
weak duality (the bound of :mod:`rwhec_ros.core.certify.dense` applies unchanged); if
``lambda_min(Z) < 0`` the fast certificate is inconclusive and :func:`rwhec_ros.core.solve.solve`
falls back to the SDP. At a non-global critical point ``Z`` cannot be PSD, so a wrong basin is never
certified.

The local solution itself is :func:`rwhec_ros.core.local.dense.refine_rotations`.
"""

from __future__ import annotations

import numpy as np

from ..local.dense import _z_of
from .relaxation import so3_constraint_matrices

__all__ = [
    "fast_certificate_multipliers",
    "fast_certificate_matrix",
    "handedness_multipliers",
    "handedness_direction",
    "strengthen_certificate",
]


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

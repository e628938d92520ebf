"""Closing the duality gap of an interior point of Problem 7 at a refined rounding.

Near the optimum of a tight relaxation the moment matrix ``X`` is nearly ``x x^T`` and the
interior-point method's Newton systems become ill-conditioned: the relaxation has ``m = 20 n + 1``
constraints for ``d = 9 n + 1`` unknowns, more than a rank-one solution can make independent, so
the optimal multipliers are not unique (the primal problem is degenerate) and the Schur complement
loses about two digits per digit of the gap. Rather than fight that, :func:`polish`

1. rounds ``X`` to rotations (its top eigenvector, normalised to ``s = 1``, each block projected
   onto SO(3): Algorithm 1 step 6) and refines them with the local Riemannian Newton solver
   (:func:`~rwhec_ros.core.local_solver.refine_rotations`) to a stationary point ``z``;
2. moves the interior point's multipliers ``y`` by the smallest change ``delta`` (least squares)
   that makes ``z`` a null vector of ``Z(y + delta)``: ``J delta = Z(y) z`` with ``J = [A_i z]``
   (:meth:`~rwhec_ros.core.certify.sdp_structure.FrameBlocks.jacobian`), solvable exactly
   because ``z`` is stationary (first-order conditions, eq. (71)). Then
   ``lambda_s = z^T Q' z``: the gap to the rounded estimate is zero in exact arithmetic.

If the relaxation is tight and ``y`` lies near the dual optimal face, ``Z(y + delta)`` is positive
semidefinite and ``(z z^T, y + delta)`` is an optimal primal-dual pair of the SDP; the caller
accepts it only when its estimated bound ``lambda_s + (3 n + 1) min(0, lambda_min(Z))`` is within
the SDP tolerances of ``z^T Q' z``. Nothing here certifies: the certificate
(:mod:`rwhec_ros.core.certificate`) re-evaluates ``Z`` from the multipliers and proves its
eigenvalue bound in floating point, as for any other multipliers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ..local.dense import LocalSolverOptions, refine_rotations
from ..model.estimate import rotations_from_vector
from .sdp_structure import FrameBlocks

__all__ = ["Polished", "polish", "rounded_rotations"]


@dataclass(frozen=True)
class Polished:
    """Multipliers at a refined rounding.

    Attributes
    ----------
    y : ndarray, shape (m,)
        The moved multipliers (order of :class:`~rwhec_ros.core.certify.sdp_structure.FrameBlocks`).
    R : ndarray, shape (n, 3, 3)
        The refined rotations.
    cost : float
        ``z^T Q' z`` at ``R`` (scaled units).
    lambda_min, lambda_2 : float
        Estimates of the two smallest eigenvalues of ``Z(y)`` (``lambda_2`` well above 0: ``z``
        spans its null space, the rounded estimate is the unique solution).
    bound : float
        ``lambda_s + (3 n + 1) min(0, lambda_min)``: the dual bound those multipliers give (an
        estimate; the certificate proves its own).
    """

    y: np.ndarray
    R: np.ndarray
    cost: float
    lambda_min: float
    lambda_2: float
    bound: float


def rounded_rotations(X: np.ndarray, n: int) -> np.ndarray | None:
    """Rotations (n, 3, 3) from the top eigenvector of the moment matrix ``X`` (d, d),
    normalised to ``s = 1`` and projected (Algorithm 1 step 6), or None when its ``s`` entry
    vanishes."""
    d = X.shape[0]
    _, V = scipy.linalg.eigh(X, subset_by_index=[d - 1, d - 1], check_finite=False)
    x = V[:, 0]
    if not abs(x[-1]) > 1e-8 * np.linalg.norm(x):
        return None
    R, _ = rotations_from_vector(x[:-1] / x[-1], n)
    return R


def polish(C: np.ndarray, fb: FrameBlocks, X: np.ndarray, y: np.ndarray,
           local: LocalSolverOptions | None = None) -> Polished | None:
    """The multipliers ``y + delta`` at the refined rounding of ``X`` (module docstring).

    Parameters
    ----------
    C : ndarray, shape (d, d)
        The scaled reduced cost ``Q'`` (symmetric).
    fb : FrameBlocks
        The constraint structure of ``C``'s frames.
    X : ndarray, shape (d, d)
        The interior point's moment matrix.
    y : ndarray, shape (m,)
        Its multipliers (``Z(y) = C - A^T(y)`` positive definite).
    local : LocalSolverOptions, optional
        Options of the refinement.

    Returns
    -------
    Polished or None
        None when ``X`` has no usable top eigenvector or a factorisation failed.
    """
    try:
        R0 = rounded_rotations(X, fb.n)
        if R0 is None:
            return None
        R = refine_rotations(C, R0, local).R
        z = np.concatenate([np.swapaxes(R, 1, 2).reshape(-1), [1.0]])
        J = fb.jacobian(z)
        r = C @ z - fb.adjoint(y) @ z
        delta = np.linalg.lstsq(J, r, rcond=None)[0]
        y2 = y + delta
        Z = C - fb.adjoint(y2)
        lam, lam2 = scipy.linalg.eigh(Z, eigvals_only=True, subset_by_index=[0, 1],
                                      check_finite=False)
    except (np.linalg.LinAlgError, ValueError, ArithmeticError):
        return None
    if not (np.all(np.isfinite(y2)) and np.isfinite(lam) and np.isfinite(lam2)):
        return None
    cost = float(z @ C @ z)
    bound = float(y2[-1] + (3 * fb.n + 1) * min(0.0, float(lam)))
    return Polished(y=y2, R=R, cost=cost, lambda_min=float(lam), lambda_2=float(lam2),
                    bound=bound)

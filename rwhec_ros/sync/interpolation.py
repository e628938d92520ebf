"""Lie-algebraic pose interpolation on SE(3) (Barfoot, *State Estimation for Robotics*, ch. 8).

The paper synchronises the motion-capture poses with the camera stamps "by interpolating the
OptiTrack system measurements to the camera measurement timestamps with the Lie-algebraic method
in Chapter 8 of Barfoot (2024)" (Section 9.1). This module implements that method with the full
SE(3) exponential map (rotation and translation coupled through the left Jacobian of SO(3)), not
the SO(3) x R^3 split, so that it is exact on constant-twist (constant body/spatial velocity)
motion.

Twists follow Barfoot's ordering ``xi = [rho, phi]`` (translation part first, rotation vector
second), shape (..., 6), and ``T = exp(xi^)`` with

.. math::

    \\exp(\\xi^\\wedge) = \\begin{bmatrix} \\exp(\\phi^\\wedge) & J(\\phi)\\rho \\\\
    0^T & 1 \\end{bmatrix},

where ``J`` is the left Jacobian of SO(3) (Barfoot eq. (7.86)).
"""

from __future__ import annotations

import numpy as np

from ..core.lie import hat, invert_transform, make_transform, so3_exp, so3_log

__all__ = [
    "so3_left_jacobian",
    "so3_left_jacobian_inverse",
    "se3_exp",
    "se3_log",
    "interpolate_se3",
]

#: Below this rotation angle [rad] the Jacobian coefficients use their Taylor series; the
#: truncation error of the series is O(theta^6) < 1e-24 there, the closed forms lose ~8 digits.
_SMALL_ANGLE = 1e-4


def _jacobian_coefficients(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``a = (1 - cos t) / t^2`` and ``b = (t - sin t) / t^3``, series-safe near ``t = 0``."""
    small = theta < _SMALL_ANGLE
    t = np.where(small, 1.0, theta)  # dummy value where the series is used
    t2 = theta * theta
    a = np.where(small, 0.5 - t2 / 24.0 + t2 * t2 / 720.0, (1.0 - np.cos(t)) / (t * t))
    b = np.where(small, 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0, (t - np.sin(t)) / (t * t * t))
    return a, b


def so3_left_jacobian(phi: np.ndarray) -> np.ndarray:
    """Left Jacobian ``J(phi) = I + a phi^ + b phi^ phi^`` of SO(3); (..., 3) -> (..., 3, 3).

    ``a = (1 - cos theta) / theta^2``, ``b = (theta - sin theta) / theta^3``,
    ``theta = |phi|`` (Barfoot eq. (7.86)); Taylor series below 1e-4 rad.
    """
    phi = np.asarray(phi, dtype=float)
    theta = np.linalg.norm(phi, axis=-1)
    a, b = _jacobian_coefficients(theta)
    P = hat(phi)
    return np.eye(3) + a[..., None, None] * P + b[..., None, None] * (P @ P)


def so3_left_jacobian_inverse(phi: np.ndarray) -> np.ndarray:
    """Inverse left Jacobian ``J^-1(phi) = I - phi^/2 + c phi^ phi^``; (..., 3) -> (..., 3, 3).

    ``c = 1/theta^2 - cot(theta/2) / (2 theta)`` (Barfoot eq. (7.87)); finite on ``[0, pi]``
    (``cot(pi/2) = 0``) and replaced by its series ``1/12 + theta^2/720 + theta^4/30240`` below
    1e-4 rad. Singular at ``theta = 2 pi``, which :func:`se3_log` never produces.
    """
    phi = np.asarray(phi, dtype=float)
    theta = np.linalg.norm(phi, axis=-1)
    small = theta < _SMALL_ANGLE
    t = np.where(small, 1.0, theta)
    t2 = theta * theta
    c = np.where(
        small,
        1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0,
        1.0 / (t * t) - np.cos(0.5 * t) / (2.0 * t * np.sin(0.5 * t)),
    )
    P = hat(phi)
    return np.eye(3) - 0.5 * P + c[..., None, None] * (P @ P)


def se3_exp(xi: np.ndarray) -> np.ndarray:
    """Exponential map se(3) -> SE(3); twists ``xi = [rho, phi]`` (..., 6) -> (..., 4, 4).

    ``R = exp(phi^)``, ``t = J(phi) rho`` (Barfoot eq. (7.83)).
    """
    xi = np.asarray(xi, dtype=float)
    if xi.shape[-1:] != (6,):
        raise ValueError(f"xi: expected shape (..., 6), got {xi.shape}")
    rho, phi = xi[..., :3], xi[..., 3:]
    t = np.einsum("...ij,...j->...i", so3_left_jacobian(phi), rho)
    return make_transform(so3_exp(phi), t)


def se3_log(T: np.ndarray) -> np.ndarray:
    """Logarithm SE(3) -> se(3); (..., 4, 4) -> twists ``[rho, phi]`` (..., 6).

    ``phi = log(R)`` with ``|phi| <= pi`` (principal branch, via scipy) and
    ``rho = J^-1(phi) t``. At exactly ``|phi| = pi`` the axis sign is ambiguous (either choice is
    a valid logarithm).
    """
    T = np.asarray(T, dtype=float)
    if T.shape[-2:] != (4, 4):
        raise ValueError(f"T: expected shape (..., 4, 4), got {T.shape}")
    phi = so3_log(T[..., :3, :3])
    rho = np.einsum("...ij,...j->...i", so3_left_jacobian_inverse(phi), T[..., :3, 3])
    return np.concatenate([rho, phi], axis=-1)


def interpolate_se3(T0: np.ndarray, T1: np.ndarray, u: float | np.ndarray) -> np.ndarray:
    """Pose between ``T0`` (at ``u = 0``) and ``T1`` (at ``u = 1``) along a constant twist.

    .. math:: T(u) = \\exp\\left(u \\log(T_1 T_0^{-1})^\\wedge\\right) T_0

    (Barfoot ch. 8; the paper's Section 9.1). For ``T_a_b`` poses this holds the relative motion
    ``T1 T0^-1`` at constant twist expressed in frame ``a``; it equals the body-frame form
    ``T0 exp(u log(T0^-1 T1))``, so the result does not depend on which side the twist is taken.
    Exact on constant-twist motion ``T(s) = exp(s xi^) T_start`` as long as the rotation between
    ``T0`` and ``T1`` is below pi (the principal logarithm then recovers ``(s1 - s0) xi``).

    Parameters
    ----------
    T0, T1 : ndarray, shape (4, 4)
        Rigid transforms at the bracketing stamps (same frames, e.g. both ``T_world_body``).
    u : float or ndarray, shape (K,)
        Fraction(s) of the way from ``T0`` to ``T1``; values outside ``[0, 1]`` extrapolate
        along the same twist.

    Returns
    -------
    ndarray, shape (4, 4) for scalar ``u``, else (K, 4, 4)
    """
    T0 = np.asarray(T0, dtype=float)
    T1 = np.asarray(T1, dtype=float)
    for name, T in (("T0", T0), ("T1", T1)):
        if T.shape != (4, 4):
            raise ValueError(f"{name}: expected shape (4, 4), got {T.shape}")
    u_arr = np.asarray(u, dtype=float)
    if u_arr.ndim > 1:
        raise ValueError(f"u: expected a scalar or shape (K,), got shape {u_arr.shape}")
    if not np.all(np.isfinite(u_arr)):
        raise ValueError(f"u: must be finite, got {u_arr.tolist()}")
    xi = se3_log(T1 @ invert_transform(T0))
    out = se3_exp(u_arr[..., None] * xi) @ T0
    return out

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

where ``J`` is the left Jacobian of SO(3) (Barfoot eq. (7.86)). The maps themselves live in
:mod:`rwhec_ros.core.lie` (the core uses them too) and are re-exported here.
"""

from __future__ import annotations

import numpy as np

from ..core.lie import (
    invert_transform,
    se3_exp,
    se3_log,
    so3_left_jacobian,
    so3_left_jacobian_inverse,
)

__all__ = [
    "so3_left_jacobian",
    "so3_left_jacobian_inverse",
    "se3_exp",
    "se3_log",
    "interpolate_se3",
]

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

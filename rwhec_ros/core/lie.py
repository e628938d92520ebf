"""SO(3)/SE(3) helpers on top of :mod:`scipy.spatial.transform`.

Conventions (see README):

* ``T_a_b`` is a 4x4 homogeneous transform that maps coordinates in frame ``b`` to frame ``a``
  (the paper's ``T_ab``, eq. (2)).
* Quaternions are ``(x, y, z, w)`` everywhere inside the package (ROS and scipy order). The paper's
  CSV files store ``(w, x, y, z)``; :func:`quat_wxyz_to_xyzw` / :func:`quat_xyzw_to_wxyz` are the
  one place where that order is converted.
* ``vec`` is column-major (Fortran) vectorisation, as in the paper's eq. (26).
* Twists are ``xi = [rho, phi]`` (translation part first; Barfoot, *State Estimation for
  Robotics*, ch. 7-8): :func:`se3_exp`, :func:`se3_log` with the left Jacobian of SO(3), exact on
  constant-twist motion (used by :mod:`rwhec_ros.sync.interpolation` and the core's analyses).

All functions accept a single object or a stack along the leading axis where noted.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = [
    "so3_left_jacobian",
    "so3_left_jacobian_inverse",
    "se3_exp",
    "se3_log",
    "hat",
    "vee",
    "so3_exp",
    "so3_log",
    "project_to_so3",
    "make_transform",
    "invert_transform",
    "transform_from_quat_xyzw",
    "transform_to_quat_xyzw",
    "quat_wxyz_to_xyzw",
    "quat_xyzw_to_wxyz",
    "rotation_angle",
    "rotation_distance",
    "vec",
    "unvec",
]


def hat(p: np.ndarray) -> np.ndarray:
    """Skew-symmetric matrix ``p^`` of eq. (3); ``p`` of shape (..., 3) -> (..., 3, 3)."""
    p = np.asarray(p, dtype=float)
    out = np.zeros(p.shape[:-1] + (3, 3))
    out[..., 0, 1] = -p[..., 2]
    out[..., 0, 2] = p[..., 1]
    out[..., 1, 0] = p[..., 2]
    out[..., 1, 2] = -p[..., 0]
    out[..., 2, 0] = -p[..., 1]
    out[..., 2, 1] = p[..., 0]
    return out


def vee(S: np.ndarray) -> np.ndarray:
    """Inverse of :func:`hat` (uses the antisymmetric part); (..., 3, 3) -> (..., 3)."""
    S = np.asarray(S, dtype=float)
    return 0.5 * np.stack(
        [S[..., 2, 1] - S[..., 1, 2], S[..., 0, 2] - S[..., 2, 0], S[..., 1, 0] - S[..., 0, 1]],
        axis=-1,
    )


def so3_exp(phi: np.ndarray) -> np.ndarray:
    """Exponential map so(3) -> SO(3) (Rodrigues); rotation vector(s) (..., 3) -> (..., 3, 3).

    Plain numpy (no per-call object construction) because the local solvers call it in their
    inner loop; Taylor coefficients below 1e-4 rad keep it accurate to machine precision.
    """
    phi = np.asarray(phi, dtype=float)
    theta2 = np.sum(phi * phi, axis=-1)[..., None, None]
    theta = np.sqrt(theta2)
    small = theta2 < 1e-8
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - theta2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))
    K = hat(phi)
    return np.eye(3) + a * K + b * (K @ K)


def so3_log(R: np.ndarray) -> np.ndarray:
    """Logarithm SO(3) -> so(3) as rotation vector(s); (..., 3, 3) -> (..., 3)."""
    R = np.asarray(R, dtype=float)
    flat = R.reshape(-1, 3, 3)
    phi = Rotation.from_matrix(flat).as_rotvec()
    return phi.reshape(R.shape[:-2] + (3,))


def project_to_so3(M: np.ndarray) -> np.ndarray:
    """Closest rotation in Frobenius norm to ``M`` (SVD with det correction); (..., 3, 3)."""
    M = np.asarray(M, dtype=float)
    U, _, Vt = np.linalg.svd(M)
    d = np.sign(np.linalg.det(U @ Vt))
    d = np.where(d == 0, 1.0, d)
    D = np.zeros(M.shape[:-2] + (3,))
    D[..., 0] = 1.0
    D[..., 1] = 1.0
    D[..., 2] = d
    return (U * D[..., None, :]) @ Vt


def make_transform(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Stack rotation(s) (..., 3, 3) and translation(s) (..., 3) into (..., 4, 4)."""
    R = np.asarray(R, dtype=float)
    t = np.asarray(t, dtype=float)
    T = np.zeros(R.shape[:-2] + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = t
    T[..., 3, 3] = 1.0
    return T


def invert_transform(T: np.ndarray) -> np.ndarray:
    """Inverse of rigid transform(s) (..., 4, 4): ``T_b_a`` from ``T_a_b``."""
    T = np.asarray(T, dtype=float)
    R = T[..., :3, :3]
    t = T[..., :3, 3]
    Rt = np.swapaxes(R, -1, -2)
    return make_transform(Rt, -np.einsum("...ij,...j->...i", Rt, t))


def transform_from_quat_xyzw(q_xyzw: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Transform(s) from quaternion(s) (..., 4) in (x, y, z, w) order and translation(s) (..., 3).

    The quaternion is normalised; a zero or non-finite quaternion raises ``ValueError``.
    """
    q = np.asarray(q_xyzw, dtype=float)
    norms = np.linalg.norm(q, axis=-1)
    if not np.all(np.isfinite(q)) or np.any(norms < 1e-12):
        raise ValueError(f"quaternion must be finite and non-zero, got {q.tolist()}")
    R = Rotation.from_quat(q.reshape(-1, 4)).as_matrix().reshape(q.shape[:-1] + (3, 3))
    return make_transform(R, t)


def transform_to_quat_xyzw(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(quaternion (x, y, z, w) with w >= 0, translation) of transform(s) (..., 4, 4)."""
    T = np.asarray(T, dtype=float)
    q = Rotation.from_matrix(T[..., :3, :3].reshape(-1, 3, 3)).as_quat(canonical=True)
    return q.reshape(T.shape[:-2] + (4,)), T[..., :3, 3].copy()


def quat_wxyz_to_xyzw(q_wxyz: np.ndarray) -> np.ndarray:
    """Convert quaternion(s) from the paper's CSV order (w, x, y, z) to (x, y, z, w).

    This is the one place where the scalar-first order enters the package.
    """
    q = np.asarray(q_wxyz, dtype=float)
    return np.concatenate([q[..., 1:4], q[..., 0:1]], axis=-1)


def quat_xyzw_to_wxyz(q_xyzw: np.ndarray) -> np.ndarray:
    """Convert quaternion(s) from (x, y, z, w) to the paper's CSV order (w, x, y, z)."""
    q = np.asarray(q_xyzw, dtype=float)
    return np.concatenate([q[..., 3:4], q[..., 0:3]], axis=-1)


def rotation_angle(R: np.ndarray) -> np.ndarray:
    """Rotation angle(s) in radians, in [0, pi], of (..., 3, 3), robust near 0 and pi."""
    return np.linalg.norm(so3_log(R), axis=-1)


def rotation_distance(R1: np.ndarray, R2: np.ndarray) -> np.ndarray:
    """Geodesic angle (radians) between rotations, ``|log(R1^T R2)|``."""
    R1 = np.asarray(R1, dtype=float)
    R2 = np.asarray(R2, dtype=float)
    return rotation_angle(np.swapaxes(R1, -1, -2) @ R2)


def vec(M: np.ndarray) -> np.ndarray:
    """Column-major vectorisation of (..., 3, 3) -> (..., 9), cf. eq. (26)."""
    M = np.asarray(M, dtype=float)
    return np.swapaxes(M, -1, -2).reshape(M.shape[:-2] + (9,))


def unvec(v: np.ndarray) -> np.ndarray:
    """Inverse of :func:`vec`: (..., 9) -> (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    return np.swapaxes(v.reshape(v.shape[:-1] + (3, 3)), -1, -2)


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

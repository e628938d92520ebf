"""Precision of target poses: the per-pair ``sigma`` [m] and ``kappa`` of the paper's eq. (20).

Single tags (:func:`pose_precision`)
------------------------------------
With ``r`` the RMS corner reprojection error (pixels, 2D norm over the 4 corners), the per-
coordinate corner noise is estimated as ``sigma_px = max(pixel_noise_floor_px, sqrt(2) r)``
(8 residual coordinates, 6 pose parameters: ``E[4 r^2] = 2 sigma_px^2``). With ``z`` the tag
distance, ``s`` its size and ``f`` the focal length (pixels), first-order perspective gives the
depth standard deviation ``z^2 sigma_px / (f s)`` (the largest translation component for
``z > s/2``) and the out-of-plane tilt standard deviation ``2 z^2 sigma_px / (f s^2)`` (from the
difference of the apparent lengths of opposite edges), so

* ``sigma = max(sigma_floor_m, z^2 sigma_px / (f s))`` (metres; nominal units if
  ``unknown_scale``), isotropic as in the paper's eq. (20);
* ``sigma_rot = max(rotation_std_floor_deg, 2 z^2 sigma_px / (f s^2))`` (radians, per axis) and
  ``kappa = 1 / (2 sigma_rot^2)``, because ``Lang(I, kappa)`` has density proportional to
  ``exp(kappa tr R) ~ exp(-kappa |phi|^2)`` for small rotation vectors ``phi``.

This is a face-on, first-order model; it ignores the (beneficial) effect of obliquity on the tilt
and is meant for relative weighting, not as a calibrated covariance.

Boards (:func:`points_precision`)
---------------------------------
First-order covariance of the pose from the reprojection Jacobian of all points, with the
per-coordinate pixel noise estimated from the residual: ``sigma_px = max(pixel_noise_floor_px,
rms sqrt(N / (2N - 6)))`` (``rms`` over the N points of the 2D residual norm: ``E[N rms^2] =
(2N - 6) sigma_px^2``, 6 pose parameters; ``sqrt(2) rms`` for one tag, as above). ``sigma`` is the
square root of the largest eigenvalue of the translation block (origin of the board, camera
axes), ``sigma_rot`` that of the rotation block (rotation about the board origin), ``kappa = 1 /
(2 sigma_rot^2)``; floors as for single tags. A partly seen board gets a larger ``sigma`` when
its origin lies away from the corners seen.
"""

from __future__ import annotations

import numpy as np

from .intrinsics import CameraIntrinsics

__all__ = ["pose_precision", "points_precision"]


def pose_precision(
    rms_px: float,
    distance_m: float,
    focal_px: float,
    size_m: float,
    *,
    pixel_noise_floor_px: float = 0.1,
    sigma_floor_m: float = 1e-3,
    rotation_std_floor_deg: float = 0.05,
) -> tuple[float, float]:
    """``(sigma, kappa)`` of one tag pose from its reprojection error (module docstring model).

    Parameters
    ----------
    rms_px : float
        RMS corner reprojection error (pixels).
    distance_m : float
        Distance camera-tag centre ``|t|`` (metres).
    focal_px : float
        Focal length (pixels).
    size_m : float
        Tag size (metres).
    pixel_noise_floor_px, sigma_floor_m, rotation_std_floor_deg : float
        Floors of the corner noise, of ``sigma`` and of the rotation standard deviation.

    Returns
    -------
    sigma : float
        Isotropic translation standard deviation (metres).
    kappa : float
        Langevin concentration of the rotation, ``1 / (2 sigma_rot^2)``.
    """
    sigma_px = max(float(pixel_noise_floor_px), np.sqrt(2.0) * float(rms_px))
    z2 = float(distance_m) ** 2
    sigma = max(float(sigma_floor_m), z2 * sigma_px / (focal_px * size_m))
    sigma_rot = max(
        np.deg2rad(float(rotation_std_floor_deg)), 2.0 * z2 * sigma_px / (focal_px * size_m**2)
    )
    return float(sigma), float(1.0 / (2.0 * sigma_rot**2))



def points_precision(
    object_points: np.ndarray,
    T_cam_target: np.ndarray,
    intrinsics: CameraIntrinsics,
    rms_px: float,
    *,
    pixel_noise_floor_px: float = 0.1,
    sigma_floor_m: float = 1e-3,
    rotation_std_floor_deg: float = 0.05,
) -> tuple[float, float]:
    """``(sigma, kappa)`` of a target pose from the reprojection Jacobian (module docstring).

    Parameters
    ----------
    object_points : ndarray, shape (N, 3)
        Points in the target frame, ``N >= 4``.
    T_cam_target : ndarray, shape (4, 4)
    intrinsics : CameraIntrinsics
        Only ``K`` is used (the Jacobian of the pinhole projection).
    rms_px : float
        RMS reprojection error of the points (pixels).
    pixel_noise_floor_px, sigma_floor_m, rotation_std_floor_deg : float
        Floors of the pixel noise, of ``sigma`` and of the rotation standard deviation.

    Returns
    -------
    sigma : float
        Translation standard deviation [m], the largest over directions.
    kappa : float
        Langevin concentration ``1 / (2 sigma_rot^2)``.
    """
    X = np.asarray(object_points, dtype=float).reshape(-1, 3)
    T = np.asarray(T_cam_target, dtype=float)
    n = len(X)
    if n < 4:
        raise ValueError(f"object_points must hold at least 4 points, got {n}")
    dof = 2 * n - 6
    sigma_px = max(float(pixel_noise_floor_px), float(rms_px) * np.sqrt(n / dof))
    K = np.asarray(intrinsics.K)
    RX = X @ T[:3, :3].T  # target points about the origin, camera axes
    p = RX + T[:3, 3]
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    # d(pixel)/d(camera point): rows (u, v).
    du = np.stack([K[0, 0] / z, K[0, 1] / z, -(K[0, 0] * x + K[0, 1] * y) / z**2], axis=1)
    dv = np.stack([np.zeros_like(z), K[1, 1] / z, -K[1, 1] * y / z**2], axis=1)
    # Camera point under exp(dtheta) R X + t + dt: d/d(dtheta) = -[R X]_x, d/d(dt) = I.
    skew = np.zeros((n, 3, 3))
    skew[:, 0, 1], skew[:, 0, 2] = -RX[:, 2], RX[:, 1]
    skew[:, 1, 0], skew[:, 1, 2] = RX[:, 2], -RX[:, 0]
    skew[:, 2, 0], skew[:, 2, 1] = -RX[:, 1], RX[:, 0]
    dp = np.concatenate([-skew, np.broadcast_to(np.eye(3), (n, 3, 3))], axis=2)  # (n, 3, 6)
    J = np.concatenate([np.einsum("nk,nkj->nj", du, dp), np.einsum("nk,nkj->nj", dv, dp)])
    cov = sigma_px**2 * np.linalg.pinv(J.T @ J)
    sigma_rot = float(np.sqrt(max(np.linalg.eigvalsh(cov[:3, :3])[-1], 0.0)))
    sigma_t = float(np.sqrt(max(np.linalg.eigvalsh(cov[3:, 3:])[-1], 0.0)))
    sigma = max(float(sigma_floor_m), sigma_t)
    sigma_rot = max(np.deg2rad(float(rotation_std_floor_deg)), sigma_rot)
    return sigma, float(1.0 / (2.0 * sigma_rot**2))

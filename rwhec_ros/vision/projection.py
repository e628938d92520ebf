"""Projection of camera-frame points with its Jacobian, for the corner-level refinement.

:class:`IntrinsicsProjector` wraps a :class:`~rwhec_ros.vision.intrinsics.CameraIntrinsics` in the
interface :mod:`rwhec_ros.core.refine` asks of a camera (``project_with_jacobian``): the distorted
pixels of points given in the camera frame (the same numbers as
:meth:`CameraIntrinsics.project_points`) and the 2x3 derivative of each pixel with respect to its
point. OpenCV's ``projectPoints`` (``cv2.fisheye.projectPoints`` for ``equidistant``) gives the
derivative with respect to the translation vector; with the identity pose that is the derivative
with respect to the point itself, exact for every distortion model the package supports.
"""

from __future__ import annotations

import cv2
import numpy as np

from .intrinsics import DISTORTION_MODELS, CameraIntrinsics

__all__ = ["IntrinsicsProjector"]

#: Columns of the translation vector in OpenCV's projection Jacobian (2N x ...): ``projectPoints``
#: orders rvec, tvec, f, c, dist; ``fisheye.projectPoints`` orders f, c, k, rvec, tvec, skew.
_TVEC_COLUMNS = {False: slice(3, 6), True: slice(11, 14)}


class IntrinsicsProjector:
    """A camera for :func:`rwhec_ros.core.refine.refine` (module docstring).

    Parameters
    ----------
    intrinsics : CameraIntrinsics
    """

    def __init__(self, intrinsics: CameraIntrinsics) -> None:
        if not isinstance(intrinsics, CameraIntrinsics):
            raise ValueError(f"intrinsics: expected CameraIntrinsics, got "
                             f"{type(intrinsics).__name__}")
        self.intrinsics = intrinsics

    def project_with_jacobian(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixels (N, 2) of camera-frame points (N, 3) [m] and their derivatives (N, 2, 3)
        [px/m]. Points at or behind the camera give meaningless values: the caller checks
        ``z > 0``."""
        P = np.ascontiguousarray(np.asarray(points, float))
        if P.ndim != 2 or P.shape[1] != 3:
            raise ValueError(f"points must have shape (N, 3), got {P.shape}")
        n = P.shape[0]
        if n == 0:
            return np.zeros((0, 2)), np.zeros((0, 2, 3))
        intr = self.intrinsics
        zero = np.zeros(3)
        coeffs = intr.D if intr.D.size else np.zeros(DISTORTION_MODELS[intr.model])
        if intr.is_fisheye:
            uv, J = cv2.fisheye.projectPoints(P.reshape(-1, 1, 3), zero, zero, intr.K, coeffs)
        else:
            uv, J = cv2.projectPoints(P, zero, zero, intr.K, coeffs)
        jac = np.asarray(J, float)[:, _TVEC_COLUMNS[intr.is_fisheye]].reshape(n, 2, 3)
        return uv.reshape(n, 2).astype(float), jac

"""Camera intrinsics (pinhole + distortion) with the ROS ``sensor_msgs/CameraInfo`` models.

Pixel convention: OpenCV's, pixel centres at integer coordinates, ``u`` to the right and ``v``
down; the camera frame has ``z`` along the optical axis, ``x`` right, ``y`` down (REP 103 optical
frame). Supported distortion models (``CameraInfo.distortion_model``):

* ``plumb_bob``: ``(k1, k2, p1, p2, k3)``, OpenCV's standard model (5 coefficients);
* ``rational_polynomial``: ``(k1, k2, p1, p2, k3, k4, k5, k6)`` (8 coefficients);
* ``equidistant``: ``(k1, k2, k3, k4)``, OpenCV's ``cv2.fisheye`` (Kannala-Brandt) model.

An empty ``D`` means no distortion for any model.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

__all__ = ["DISTORTION_MODELS", "CameraIntrinsics"]

#: Distortion model name -> number of coefficients in ``D`` (an empty ``D`` is also accepted).
DISTORTION_MODELS: dict[str, int] = {
    "plumb_bob": 5,
    "rational_polynomial": 8,
    "equidistant": 4,
}


def _undistort_criteria(max_iter: int, eps: float) -> tuple[int, int, float]:
    return (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, int(max_iter), float(eps))


@dataclass(frozen=True, eq=False)
class CameraIntrinsics:
    """Intrinsics of one camera: image size, camera matrix ``K`` and distortion ``D``.

    Parameters
    ----------
    width, height : int
        Image size in pixels (> 0).
    K : ndarray, shape (3, 3)
        Camera matrix ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]`` with ``fx, fy > 0``.
    D : ndarray, shape (n,)
        Distortion coefficients; ``n`` is fixed by ``model`` (see :data:`DISTORTION_MODELS`) or
        0 for no distortion.
    model : str
        ``"plumb_bob"``, ``"rational_polynomial"`` or ``"equidistant"``.

    Raises
    ------
    ValueError
        Naming the field and the value for a zero/negative size, a non-finite ``K`` or one with a
        non-positive focal length or a last row other than ``(0, 0, 1)``, an unknown ``model`` or
        a ``D`` of the wrong length or with non-finite entries.

    Notes
    -----
    The arrays are stored as read-only float64 copies.
    """

    width: int
    height: int
    K: np.ndarray
    D: np.ndarray
    model: str = "plumb_bob"

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or int(value) <= 0:
                raise ValueError(f"{name} must be a positive integer, got {value!r}")
            object.__setattr__(self, name, int(value))
        K = np.array(self.K, dtype=float)
        if K.shape == (9,):
            K = K.reshape(3, 3)
        if K.shape != (3, 3):
            raise ValueError(f"K must have shape (3, 3) or (9,), got {K.shape}")
        if not np.all(np.isfinite(K)):
            raise ValueError(f"K must be finite, got {K.tolist()}")
        if not (K[0, 0] > 0 and K[1, 1] > 0):
            raise ValueError(
                f"K focal lengths must be positive, got fx={float(K[0, 0])!r}, "
                f"fy={float(K[1, 1])!r}"
            )
        if K[1, 0] != 0 or not np.allclose(K[2], [0.0, 0.0, 1.0]):
            raise ValueError(
                f"K must be upper triangular with last row (0, 0, 1), got {K.tolist()}"
            )
        if self.model not in DISTORTION_MODELS:
            raise ValueError(
                f"model must be one of {sorted(DISTORTION_MODELS)}, got {self.model!r}"
            )
        D = np.array(self.D if self.D is not None else [], dtype=float).reshape(-1)
        n = DISTORTION_MODELS[self.model]
        if D.size not in (0, n):
            raise ValueError(
                f"D must have {n} coefficients for model {self.model!r} (or 0 for none), "
                f"got {D.size}: {D.tolist()}"
            )
        if not np.all(np.isfinite(D)):
            raise ValueError(f"D must be finite, got {D.tolist()}")
        K.setflags(write=False)
        D.setflags(write=False)
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "D", D)

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_camera_info(cls, msg: Any) -> CameraIntrinsics:
        """Build from a ``sensor_msgs/CameraInfo``-like object (duck-typed).

        Reads the fields ``width``, ``height``, ``k`` (9, row-major), ``d`` and
        ``distortion_model``. An empty ``distortion_model`` with an empty ``d`` is read as
        ``plumb_bob`` without distortion.
        """
        model = str(getattr(msg, "distortion_model", "") or "")
        d = np.asarray(getattr(msg, "d", []), dtype=float).reshape(-1)
        if model == "" and d.size in (0, 5):
            model = "plumb_bob"
        k = np.asarray(msg.k, dtype=float).reshape(-1)
        if k.size != 9:
            raise ValueError(f"k must have 9 entries (row-major 3x3), got {k.size}")
        return cls(
            width=msg.width,
            height=msg.height,
            K=k.reshape(3, 3),
            D=d,
            model=model,
        )

    @classmethod
    def pinhole(
        cls,
        width: int,
        height: int,
        fx: float,
        fy: float | None = None,
        cx: float | None = None,
        cy: float | None = None,
    ) -> CameraIntrinsics:
        """Distortion-free camera; ``fy`` defaults to ``fx`` and ``(cx, cy)`` to the centre."""
        fy = fx if fy is None else fy
        cx = (width - 1) / 2.0 if cx is None else cx
        cy = (height - 1) / 2.0 if cy is None else cy
        K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
        return cls(width=width, height=height, K=K, D=np.zeros(0), model="plumb_bob")

    def with_distortion(self, D: np.ndarray, model: str) -> CameraIntrinsics:
        """Same size and ``K`` with another distortion model and coefficients."""
        return CameraIntrinsics(self.width, self.height, self.K, np.asarray(D), model)

    # ------------------------------------------------------------------ properties
    @property
    def has_distortion(self) -> bool:
        """True when any distortion coefficient is non-zero."""
        return bool(self.D.size and np.any(self.D != 0.0))

    @property
    def focal_px(self) -> float:
        """Geometric mean focal length ``sqrt(fx fy)`` in pixels."""
        return float(np.sqrt(self.K[0, 0] * self.K[1, 1]))

    @property
    def is_fisheye(self) -> bool:
        """True for the ``equidistant`` (``cv2.fisheye``) model."""
        return self.model == "equidistant"

    def _coeffs(self) -> np.ndarray:
        if self.D.size:
            return np.array(self.D)
        return np.zeros(DISTORTION_MODELS[self.model])

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, CameraIntrinsics):
            return NotImplemented
        return (
            self.width == other.width
            and self.height == other.height
            and self.model == other.model
            and np.array_equal(self.K, other.K)
            and np.array_equal(self._coeffs(), other._coeffs())
        )

    __hash__ = None  # type: ignore[assignment]

    # ------------------------------------------------------------------ geometry
    def normalize_points(
        self, pixels: np.ndarray, *, max_iter: int = 50, eps: float = 1e-12
    ) -> np.ndarray:
        """Undistort pixels to normalized image coordinates ``(x/z, y/z)`` of their rays.

        Parameters
        ----------
        pixels : ndarray, shape (N, 2)
            Distorted pixel coordinates ``(u, v)``.
        max_iter, eps : int, float
            Termination of OpenCV's iterative undistortion (its default of 5 iterations is
            not enough for strong distortion).

        Returns
        -------
        ndarray, shape (N, 2)
            Undistorted normalized coordinates (the ray through pixel ``i`` is ``(x_i, y_i, 1)``
            in the camera frame). For the ``equidistant`` model rays beyond 90 degrees from the
            axis have no such representation and come back as OpenCV returns them.
        """
        pts = self._check_pixels(pixels)
        if pts.shape[0] == 0:
            return np.zeros((0, 2))
        src = pts.reshape(-1, 1, 2)
        criteria = _undistort_criteria(max_iter, eps)
        if self.is_fisheye:
            out = cv2.fisheye.undistortPoints(
                src, self.K, self._coeffs(), R=np.eye(3), P=np.eye(3), criteria=criteria
            )
        elif self.has_distortion:
            out = cv2.undistortPointsIter(src, self.K, self._coeffs(), None, None, criteria)
        else:
            fx, skew, cx = self.K[0]
            fy, cy = self.K[1, 1], self.K[1, 2]
            y = (pts[:, 1] - cy) / fy
            x = (pts[:, 0] - cx - skew * y) / fx
            return np.stack([x, y], axis=1)
        return out.reshape(-1, 2).astype(float)

    def undistort_points(
        self, pixels: np.ndarray, *, max_iter: int = 50, eps: float = 1e-12
    ) -> np.ndarray:
        """Undistort pixels to the ideal (distortion-free) pixels of the same ``K``; (N, 2)."""
        xy = self.normalize_points(pixels, max_iter=max_iter, eps=eps)
        fx, skew, cx = self.K[0]
        fy, cy = self.K[1, 1], self.K[1, 2]
        return np.stack([fx * xy[:, 0] + skew * xy[:, 1] + cx, fy * xy[:, 1] + cy], axis=1)

    def project_points(self, points: np.ndarray, T_cam_obj: np.ndarray | None = None) -> np.ndarray:
        """Project 3D points to distorted pixel coordinates.

        Parameters
        ----------
        points : ndarray, shape (N, 3)
            Points in the object frame (the camera frame when ``T_cam_obj`` is None).
        T_cam_obj : ndarray, shape (4, 4), optional
            Pose of the object frame in the camera frame.

        Returns
        -------
        ndarray, shape (N, 2)
            Pixel coordinates ``(u, v)`` (``cv2.projectPoints`` / ``cv2.fisheye.projectPoints``).
            Points at or behind the camera give meaningless values: check ``z > 0`` first.
        """
        P = np.asarray(points, dtype=float)
        if P.ndim != 2 or P.shape[1] != 3:
            raise ValueError(f"points must have shape (N, 3), got {P.shape}")
        if P.shape[0] == 0:
            return np.zeros((0, 2))
        if T_cam_obj is None:
            T = np.eye(4)
        else:
            T = np.asarray(T_cam_obj, dtype=float)
            if T.shape != (4, 4):
                raise ValueError(f"T_cam_obj must have shape (4, 4), got {T.shape}")
        rvec, _ = cv2.Rodrigues(np.ascontiguousarray(T[:3, :3]))
        tvec = np.ascontiguousarray(T[:3, 3]).reshape(3, 1)
        if self.is_fisheye:
            out, _ = cv2.fisheye.projectPoints(
                P.reshape(-1, 1, 3), rvec, tvec, self.K, self._coeffs()
            )
        else:
            out, _ = cv2.projectPoints(P, rvec, tvec, self.K, self._coeffs())
        return out.reshape(-1, 2).astype(float)

    @staticmethod
    def _check_pixels(pixels: np.ndarray) -> np.ndarray:
        pts = np.asarray(pixels, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 2:
            raise ValueError(f"pixels must have shape (N, 2), got {pts.shape}")
        return pts

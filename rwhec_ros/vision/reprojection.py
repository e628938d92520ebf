"""Reprojection error of the detected corners (tags, boards) through the calibrated chain, per
camera.

For a pair ``(A_i, B_i)`` of edge (tag ``x``, camera ``y``) the calibration predicts the tag pose
in the camera frame without using ``B_i``::

    T_cam_tag = Y^-1 A_i X        (camera <- carrier <- pose stream <- tag carrier <- tag)

(``A = T_<camera carrier>_<tag carrier>``, ``X = T_<tag carrier>_tag``, ``Y = T_<camera
carrier>_cam``). Projecting the tag's corners with the camera's intrinsics (distortion included)
and comparing them with the corners the detector found gives an error in pixels that a user can
judge against the detector's own noise (a few tenths of a pixel for sharp tags): it is the
residual of the whole calibration, not of the tag pose fit.

Corners are the *detected, distorted* pixel coordinates, as
:attr:`rwhec_ros.vision.targets.TargetObservation.image_points` reports them: a single tag's
four in the corner order of :data:`~rwhec_ros.vision.detection.TAG_CORNERS_UNIT` (placed in the
tag frame by its size), or the corners a board's pose came from with their board-frame points
(``object_points``; a partly seen board gives fewer). The prediction is projected through the
distortion model (:meth:`CameraIntrinsics.project_points`), so no undistortion is needed. For an
unknown scale (monocular), ``tag_size_m`` and the board points are nominal: the true size is
``size / alpha`` and the estimate's translations are metric, so the corners are placed at that
size. The statistics of a camera are over its corners, so a board (up to a few hundred corners
per view) weighs more than a tag (four).

Next to it, each camera's **focal fit** (:attr:`CameraReprojection.focal`,
:func:`rwhec_ros.vision.focal_fit.fit_focal_scale`): how well the same corners fit each image's
own best pose (what the corners allow at best) and the factor on the focal length that they
fit best; the verdict's focal check (:mod:`rwhec_ros.core.verdict.focal_check`) reads it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..core.lie import invert_transform
from .detection import tag_object_points
from .focal_fit import FocalFit, fit_focal_scale
from .intrinsics import CameraIntrinsics

__all__ = ["CornerObservation", "CameraReprojection", "reprojection_errors"]


@dataclass(frozen=True)
class CornerObservation:
    """What one pair needs for the reprojection check.

    Attributes
    ----------
    x : str
        The tag (X) frame.
    y : str
        The camera (Y) frame.
    A : ndarray, shape (4, 4)
        The pair's pose-stream transform ``T_<camera carrier>_<tag carrier>``.
    corners_px : ndarray, shape (4, 2) or (K, 2)
        The detected corners in distorted pixels: a tag's, order of ``TAG_CORNERS_UNIT``; or
        ``K >= 4`` corners of a board (with ``object_points``).
    tag_size_m : float or None
        Single tags: edge length of the tag's black square (nominal for unknown scale). None
        for a board.
    object_points : ndarray, shape (K, 3), or None
        Boards: the same corners in the board frame [m] (nominal for unknown scale).
    """

    x: str
    y: str
    A: np.ndarray
    corners_px: np.ndarray
    tag_size_m: float | None = None
    object_points: np.ndarray | None = None

    def __post_init__(self) -> None:
        A = np.asarray(self.A, float)
        if A.shape != (4, 4) or not np.all(np.isfinite(A)):
            raise ValueError(f"A of ({self.x}, {self.y}): expected a finite (4, 4) transform, "
                             f"got shape {A.shape}")
        c = np.asarray(self.corners_px, float)
        who = f"({self.x}, {self.y})"
        if self.object_points is None:
            if c.shape != (4, 2) or not np.all(np.isfinite(c)):
                raise ValueError(f"corners_px of {who}: expected finite (4, 2) pixels, got "
                                 f"shape {c.shape}")
            size = self.tag_size_m
            if size is None or not (np.isfinite(size) and size > 0):
                raise ValueError(f"tag_size_m of {who}: must be finite and > 0 (or give "
                                 f"object_points), got {size!r}")
            object.__setattr__(self, "tag_size_m", float(size))
        else:
            if c.ndim != 2 or c.shape[0] < 4 or c.shape[1] != 2 or not np.all(np.isfinite(c)):
                raise ValueError(f"corners_px of {who}: expected finite (K, 2) pixels with K "
                                 f">= 4, got shape {c.shape}")
            P = np.asarray(self.object_points, float)
            if P.shape != (c.shape[0], 3) or not np.all(np.isfinite(P)):
                raise ValueError(f"object_points of {who}: expected finite ({c.shape[0]}, 3) "
                                 f"points (one per corner), got shape {P.shape}")
            object.__setattr__(self, "object_points", P)
        object.__setattr__(self, "A", A)
        object.__setattr__(self, "corners_px", c)

    def target_points(self, alpha: float = 1.0) -> np.ndarray:
        """The corners in the target frame [m], shape (K, 3): the tag's corners at
        ``tag_size_m / alpha``, or the board points over ``alpha`` (module docstring)."""
        if self.object_points is None:
            return tag_object_points(self.tag_size_m / alpha)
        return self.object_points / alpha


@dataclass
class CameraReprojection:
    """Reprojection errors of one camera's corners (pixels; 2D distance per corner).

    ``n_behind`` pairs whose predicted tag lies at or behind the camera are left out of the
    statistics (the estimate cannot be right for them). ``focal`` is the focal fit of the same
    camera's corners (every pair; module docstring), None when not computed;
    ``per_target_rms_px`` the RMS over the corners of each target it sees."""

    camera: str
    n_pairs: int
    rms_px: float
    median_px: float
    max_px: float
    n_behind: int = 0
    focal: FocalFit | None = None
    per_target_rms_px: dict[str, float] | None = None

    def to_dict(self) -> dict:
        return {"camera": self.camera, "n_pairs": int(self.n_pairs), "rms_px": float(self.rms_px),
                "median_px": float(self.median_px), "max_px": float(self.max_px),
                "n_behind": int(self.n_behind),
                "per_target_rms_px": {k: float(v) for k, v in
                                      (self.per_target_rms_px or {}).items()},
                **_focal_keys(self.focal)}


def _focal_keys(fit: FocalFit | None) -> dict:
    """The focal fit's result-YAML keys (flat, NaN when not computed): the factor on the
    focal length the corners fit and its std, the per-image fit RMS as configured and with the
    fitted focal length."""
    nan = float("nan")
    if fit is None:
        return {"focal_scale": nan, "focal_scale_std": nan, "image_fit_rms_px": nan,
                "image_fit_rms_fitted_px": nan}
    return {"focal_scale": float(fit.scale), "focal_scale_std": float(fit.scale_std),
            "image_fit_rms_px": float(fit.rms_px),
            "image_fit_rms_fitted_px": float(fit.fitted_rms_px)}


def reprojection_errors(
    observations: Sequence[CornerObservation],
    intrinsics: Mapping[str, CameraIntrinsics],
    result,
) -> dict[str, CameraReprojection]:
    """Per camera, the RMS (and median, max) reprojection error of the detected corners through
    the calibrated chain (module docstring).

    Parameters
    ----------
    observations : sequence of CornerObservation
    intrinsics : mapping of camera name to CameraIntrinsics
    result : CalibrationResult
        ``X``, ``Y`` (metric) and ``scale`` with frame names ``x_names``, ``y_names``.

    Returns
    -------
    dict of str to CameraReprojection
        One entry per camera that has observations, in first-seen order.

    Raises
    ------
    ValueError
        For an observation whose frames the result does not have, or a camera without
        intrinsics.
    """
    alpha = float(result.scale) if np.isfinite(result.scale) and result.scale > 0 else 1.0
    groups: dict[str, list[int]] = {}
    for i, ob in enumerate(observations):
        if ob.x not in result.x_names:
            raise ValueError(f"observations[{i}]: tag frame {ob.x!r} not in the result "
                             f"{list(result.x_names)}")
        if ob.y not in result.y_names:
            raise ValueError(f"observations[{i}]: camera frame {ob.y!r} not in the result "
                             f"{list(result.y_names)}")
        if ob.y not in intrinsics:
            raise ValueError(f"observations[{i}]: no intrinsics for camera {ob.y!r}; have "
                             f"{sorted(intrinsics)}")
        groups.setdefault(ob.y, []).append(i)
    out = {}
    for cam, idx in groups.items():
        focal = fit_focal_scale([observations[i].corners_px for i in idx], intrinsics[cam],
                                object_points=[observations[i].object_points for i in idx])
        Y_inv = invert_transform(result.transform(cam))
        pts, seen, whose = [], [], []
        for i in idx:
            ob = observations[i]
            T = Y_inv @ ob.A @ result.transform(ob.x)  # T_cam_target predicted
            P = ob.target_points(alpha) @ T[:3, :3].T + T[:3, 3]
            if np.all(P[:, 2] > 0):
                pts.append(P)
                seen.append(ob.corners_px)
                whose += [ob.x] * len(P)
        n_behind = len(idx) - len(pts)
        if not pts:
            nan = float("nan")
            out[cam] = CameraReprojection(cam, len(idx), nan, nan, nan, n_behind, focal)
            continue
        uv = intrinsics[cam].project_points(np.concatenate(pts))
        err = np.linalg.norm(uv - np.concatenate(seen), axis=1)
        whose_a = np.array(whose)
        per = {x: float(np.sqrt(np.mean(err[whose_a == x] ** 2))) for x in dict.fromkeys(whose)}
        out[cam] = CameraReprojection(cam, len(idx), float(np.sqrt(np.mean(err**2))),
                                      float(np.median(err)), float(err.max()), n_behind, focal,
                                      per)
    return out


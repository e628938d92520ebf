"""Pose of a planar target from its corners, with the planar (IPPE) ambiguity made explicit.

A plane seen in perspective has, near the true pose, a second pose -- the first one mirrored
about the viewing ray, tilted the other way -- that reprojects almost as well when the target is
small in the image, far away or seen nearly face-on: the "flip" that AprilTag users meet. IPPE
(``cv2.solvePnPGeneric`` with ``SOLVEPNP_IPPE_SQUARE`` for a single square, ``SOLVEPNP_IPPE``
for any planar point set) returns both local minima. :func:`solve_planar_pose` polishes both
(``cv2.solvePnPRefineLM``), measures their RMS reprojection errors in the distorted image,
``e_best <= e_alt``, and decides:

* **unique** when only one solution lies in front of the camera, when the two poses are within
  ``min_separation_deg`` of each other (the refinement joined them: nothing to choose), or when
  ``ratio = e_alt / e_best`` reaches ``min_ratio`` scaled to the number of points ``N``
  (:func:`ratio_for_points`);
* otherwise, with a ``predicted`` pose (``T_cam_target`` from the current estimate,
  ``B = Y_k^-1 A_i X_j``), **resolved by prediction** when the solution nearer to the prediction
  in rotation is nearer by a clear margin (its angle to the prediction at most
  ``prediction_margin`` times the other's), even if it reprojects slightly worse;
* otherwise **ambiguous**: the caller rejects the detection (``tag_rejected:ambiguous_pose``).

The test is the one of the ArUco library's ``MarkerPoseTracker`` (error ratio of the two IPPE
solutions); its defaults here come from ``benchmarks/perception.md`` (flip table), for a tag's
four corners. For ``N`` points the same test in units of the corner noise that the best fit
measures, ``sigma^2 = N e_best^2 / (2N - 6)`` (6 pose parameters): the mirror pose's excess
misfit ``N (e_alt^2 - e_best^2) / sigma^2 = (2N - 6)(ratio^2 - 1)`` must reach what
``min_ratio`` asks of four points, ``2 (min_ratio^2 - 1)`` (16 noise variances for the default 3),
so ``ratio^2 >= 1 + 2 (min_ratio^2 - 1) / (2N - 6)``: 3 for a tag, 1.61 for 8 points, 1.17 for
24. A board's many points separate the two poses at a much smaller ratio than a tag's four.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import cv2
import numpy as np

from ..core.lie import rotation_distance
from .intrinsics import CameraIntrinsics

__all__ = ["PoseStatus", "PlanarPose", "solve_planar_pose", "pose_from_rvec", "check_flip_options",
           "ratio_for_points"]


class PoseStatus(str, Enum):
    """How the pose of a planar target was chosen (compares equal to its string value)."""

    UNIQUE = "unique"
    RESOLVED_BY_PREDICTION = "resolved_by_prediction"
    AMBIGUOUS = "ambiguous"
    FAILED = "failed"


@dataclass(eq=False)
class PlanarPose:
    """Outcome of :func:`solve_planar_pose`.

    Attributes
    ----------
    status : PoseStatus
    T : ndarray (4, 4) or None
        ``T_cam_target`` chosen: the best-reprojecting solution (also when ``AMBIGUOUS``, for
        callers that want the unchecked pose), the predicted one when
        ``RESOLVED_BY_PREDICTION``; None when ``FAILED``.
    rms_px : float
        RMS reprojection error of ``T`` (distorted pixels).
    alternative : ndarray (4, 4) or None
        The other IPPE solution (None when there was only one in front of the camera).
    alternative_rms_px : float
        Its RMS reprojection error (inf without one).
    ratio : float
        ``e_alt / e_best`` of the two solutions (inf without a second one).
    separation_deg : float
        Rotation angle between the two solutions (0 without a second one).
    detail : str
        Human-readable reason of the status.
    """

    status: PoseStatus
    T: np.ndarray | None
    rms_px: float = float("inf")
    alternative: np.ndarray | None = None
    alternative_rms_px: float = float("inf")
    ratio: float = float("inf")
    separation_deg: float = 0.0
    detail: str = ""


def pose_from_rvec(rvec: np.ndarray, tvec: np.ndarray) -> np.ndarray:
    """4x4 transform from an OpenCV rotation vector and translation."""
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(np.asarray(rvec, dtype=float).reshape(3, 1))[0]
    T[:3, 3] = np.asarray(tvec, dtype=float).reshape(3)
    return T


def check_flip_options(
    min_ratio: float, min_separation_deg: float, prediction_margin: float, prefix: str = ""
) -> None:
    """Raise ``ValueError`` naming the option when a flip-check option is out of range."""
    if not (np.isfinite(min_ratio) and min_ratio >= 1.0):
        raise ValueError(f"{prefix}min_ratio must be >= 1, got {min_ratio!r}")
    if not (np.isfinite(min_separation_deg) and min_separation_deg >= 0.0):
        raise ValueError(f"{prefix}min_separation_deg must be >= 0, got {min_separation_deg!r}")
    if not (np.isfinite(prediction_margin) and 0.0 < prediction_margin <= 1.0):
        raise ValueError(f"{prefix}prediction_margin must be in (0, 1], got {prediction_margin!r}")


def ratio_for_points(min_ratio: float, n_points: int) -> float:
    """The reprojection ratio ``e_alt / e_best`` that separates the two poses of ``n_points``
    points as ``min_ratio`` separates those of 4 (module docstring): ``sqrt(1 + 2 (min_ratio^2
    - 1) / (2N - 6))``; ``min_ratio`` itself for ``N <= 4``."""
    n = int(n_points)
    if n <= 4:
        return float(min_ratio)
    return float(np.sqrt(1.0 + 2.0 * (float(min_ratio) ** 2 - 1.0) / (2.0 * n - 6.0)))


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


def solve_planar_pose(
    object_points: np.ndarray,
    image_points: np.ndarray,
    ideal_points: np.ndarray,
    intrinsics: CameraIntrinsics,
    *,
    square: bool = False,
    refine: bool = True,
    min_ratio: float = 3.0,
    min_separation_deg: float = 2.0,
    prediction_margin: float = 0.75,
    predicted: np.ndarray | None = None,
) -> PlanarPose:
    """Both IPPE poses of a planar target and the choice between them (module docstring).

    Parameters
    ----------
    object_points : ndarray, shape (N, 3)
        Target points with ``z = 0`` in the target frame, ``N >= 4``; for ``square`` the four
        corners ``(-s/2, s/2), (s/2, s/2), (s/2, -s/2), (-s/2, -s/2)`` in this order.
    image_points : ndarray, shape (N, 2)
        Detected points, distorted pixels (the reprojection errors are measured here).
    ideal_points : ndarray, shape (N, 2)
        The same points undistorted (pinhole pixels of the same ``K``), input to IPPE and LM.
    intrinsics : CameraIntrinsics
    square : bool
        Use ``SOLVEPNP_IPPE_SQUARE`` (single tag) instead of ``SOLVEPNP_IPPE``.
    refine : bool
        Polish both solutions with ``cv2.solvePnPRefineLM``.
    min_ratio : float
        ``e_alt / e_best`` below which the two poses of four points are not clearly separated
        (>= 1; 1 accepts every best-reprojecting pose, i.e. no flip check); scaled to ``N``
        points by :func:`ratio_for_points`.
    min_separation_deg : float
        Solutions closer than this in rotation count as one (>= 0).
    prediction_margin : float
        In ``(0, 1]``: the solution nearer to ``predicted`` must be at most this fraction of the
        other's angle to it.
    predicted : ndarray (4, 4), optional
        Predicted ``T_cam_target``; only its rotation is used.

    Returns
    -------
    PlanarPose
    """
    obj = np.ascontiguousarray(np.asarray(object_points, dtype=np.float64).reshape(-1, 3))
    img = np.asarray(image_points, dtype=float).reshape(-1, 2)
    ideal = np.ascontiguousarray(np.asarray(ideal_points, dtype=np.float64).reshape(-1, 1, 2))
    if len(obj) < 4 or len(img) != len(obj) or len(ideal) != len(obj):
        raise ValueError(
            f"object_points, image_points and ideal_points must hold the same N >= 4 points, "
            f"got {len(obj)}, {len(img)}, {len(ideal)}"
        )
    check_flip_options(min_ratio, min_separation_deg, prediction_margin)
    K = np.array(intrinsics.K)
    flags = cv2.SOLVEPNP_IPPE_SQUARE if square else cv2.SOLVEPNP_IPPE
    try:
        n, rvecs, tvecs, _ = cv2.solvePnPGeneric(obj, ideal, K, None, flags=flags)
    except cv2.error as exc:
        return PlanarPose(PoseStatus.FAILED, None, detail=str(exc).strip()[:200])
    solutions: list[tuple[float, np.ndarray]] = []
    for rvec, tvec in zip(rvecs[:n], tvecs[:n], strict=True):
        if not (np.all(np.isfinite(rvec)) and np.all(np.isfinite(tvec))):
            continue
        if float(np.asarray(tvec).reshape(3)[2]) <= 0:
            continue
        if refine:
            rvec, tvec = cv2.solvePnPRefineLM(obj, ideal, K, None, rvec.copy(), tvec.copy())
        T = pose_from_rvec(rvec, tvec)
        if T[2, 3] <= 0:
            continue
        err = _rms(intrinsics.project_points(obj, T), img)
        if np.isfinite(err):
            solutions.append((err, T))
    if not solutions:
        return PlanarPose(PoseStatus.FAILED, None, detail="no pose in front of the camera")
    solutions.sort(key=lambda s: s[0])
    e_best, T_best = solutions[0]
    if len(solutions) == 1:
        return PlanarPose(PoseStatus.UNIQUE, T_best, e_best, detail="one solution")
    e_alt, T_alt = solutions[1]
    ratio = e_alt / max(e_best, 1e-12)
    sep = float(np.degrees(rotation_distance(T_best[:3, :3], T_alt[:3, :3])))
    out = PlanarPose(PoseStatus.UNIQUE, T_best, e_best, T_alt, e_alt, ratio, sep)
    if sep < min_separation_deg:
        out.detail = f"solutions {sep:.2f} deg apart (< min_separation_deg)"
        return out
    needed = ratio_for_points(min_ratio, len(obj))
    if ratio >= needed:
        out.detail = f"ratio {ratio:.2f} >= {needed:.3g}"
        return out
    if predicted is not None:
        R_pred = np.asarray(predicted, dtype=float)[:3, :3]
        d_best = float(np.degrees(rotation_distance(R_pred, T_best[:3, :3])))
        d_alt = float(np.degrees(rotation_distance(R_pred, T_alt[:3, :3])))
        near, far = sorted([(d_best, 0), (d_alt, 1)])
        if near[0] <= prediction_margin * far[0]:
            if near[1] == 1:  # the prediction picks the second-best reprojection
                out.T, out.rms_px, out.alternative, out.alternative_rms_px = T_alt, e_alt, \
                    T_best, e_best
            out.status = PoseStatus.RESOLVED_BY_PREDICTION
            out.detail = (f"ratio {ratio:.2f} < {needed:.3g}; prediction {near[0]:.1f} deg "
                          f"from the kept pose, {far[0]:.1f} deg from the other")
            return out
        out.status = PoseStatus.AMBIGUOUS
        out.detail = (f"ratio {ratio:.2f} < {needed:.3g} and the prediction does not decide "
                      f"({d_best:.1f} vs {d_alt:.1f} deg)")
        return out
    out.status = PoseStatus.AMBIGUOUS
    out.detail = (f"reprojection ratio {ratio:.2f} < {needed:.3g}, solutions {sep:.1f} deg "
                  f"apart")
    return out

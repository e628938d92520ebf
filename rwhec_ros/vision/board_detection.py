"""Pose of a board from its points in one image: AprilGrid and ChArUco from their markers.

Per board (:func:`estimate_board`; steps 2-4 are :func:`board_observation`, which the marker-free
boards of :mod:`rwhec_ros.vision.grid_detection` share):

1. **points** -- AprilGrid: the four corners of every detected grid tag (shortest side at least
   ``min_side_px``), refined by edge-line fitting (:mod:`rwhec_ros.vision.edges`) when the
   detector's ``corner_refinement`` is ``"edge"``. Kalibr's corner squares join the tags at
   their corners, which pulls aruco's corners a few pixels outward along the diagonals; on such
   grids each corner is first moved to its saddle point with ``cv2.cornerSubPix`` (window of
   up to 1.5 tag cells, inside the border and the gap), the way Kalibr locates them. ChArUco:
   the chessboard (saddle) corners that ``cv2.aruco.CharucoDetector`` interpolates from the
   detected markers and refines with ``cornerSubPix``. A marker id seen twice is dropped
   (``duplicate_id``).
2. **enough corners** -- fewer than the target's ``min_corners`` (or collinear ChArUco corners)
   reject the board (``too_few_corners``); a partly occluded board is fine otherwise.
3. **pose** -- ``SOLVEPNP_IPPE`` over all points (undistorted), both solutions LM-polished;
   while the worst point (for a grid: the worst tag, a wrong quad or a wrong id) reprojects
   worse than ``max(0.5 px, 3 x 1.4826 x`` the median residual), it is dropped and the pose
   solved again, keeping at least ``min_corners`` and three quarters of the points
   (:attr:`TargetObservation.outlier_corners`); then the flip check of
   :mod:`rwhec_ros.vision.planar_pose` (``ambiguous_pose``) and the detector's reprojection gate
   (:meth:`DetectorConfig.reprojection_limit
   <rwhec_ros.vision.detector_config.DetectorConfig.reprojection_limit>`: a floor, scaled to the
   camera's corner noise when the caller keeps a history) and obliquity gate.
4. **precision** (:func:`~rwhec_ros.vision.precision.points_precision`, re-exported here) --
   first-order covariance of the pose from the reprojection Jacobian of all points.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from .boards import AprilGridSpec, CharucoSpec
from .detector_config import DetectorConfig, RejectReason, corner_noise_px
from .edges import refine_corners_edges
from .intrinsics import CameraIntrinsics
from .planar_pose import PoseStatus, solve_planar_pose
from .precision import points_precision
from .targets import TargetObservation, TargetRejection, TargetSpec

__all__ = ["estimate_board", "board_observation", "points_precision", "charuco_detector"]


def charuco_detector(spec: CharucoSpec, config: DetectorConfig) -> cv2.aruco.CharucoDetector:
    """A ``cv2.aruco.CharucoDetector`` of the board (markers are passed in, not detected)."""
    return cv2.aruco.CharucoDetector(
        spec.cv2_board(), cv2.aruco.CharucoParameters(), config.aruco_parameters()
    )


def _saddle_corners(gray: np.ndarray, quad: np.ndarray, spec: AprilGridSpec) -> np.ndarray:
    """Tag corners moved to the saddle points tag / corner square (unchanged on failure)."""
    side = float(np.min(np.linalg.norm(quad - np.roll(quad, -1, axis=0), axis=1)))
    cell = side / spec.cells
    half = max(2, int(round(cell * min(1.5, spec.border_bits, spec.tag_spacing * spec.cells))))
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 50, 1e-3)
    try:
        out = cv2.cornerSubPix(gray, np.ascontiguousarray(quad, dtype=np.float32).reshape(-1, 1, 2),
                               (half, half), (-1, -1), criteria)
    except cv2.error:
        return quad
    out = np.asarray(out, dtype=float).reshape(4, 2)
    return out if np.all(np.isfinite(out)) else quad


def _edge_cells(spec: AprilGridSpec) -> float:
    """``cells`` argument of :func:`refine_corners_edges` for grid tags: its profiles may reach
    one of *these* cells into the border and into the gap, i.e. ``min(border_bits, gap cells)``
    tag cells (Kalibr: 2), which keeps them wide enough for the blur of small tags."""
    reach = max(1.0, min(float(spec.border_bits), np.floor(spec.tag_spacing * spec.cells)))
    return spec.cells / reach


def _worst_outlier(residuals: np.ndarray, per_marker: bool, *, factor: float = 3.0,
                   floor_px: float = 0.5) -> np.ndarray | None:
    """Indices of the points to drop next: those of the worst marker (grid: a tag's 4 corners)
    or the worst point (ChArUco) when its residual exceeds ``max(floor_px, factor s)``,
    ``s = 1.4826 median |r|`` over all points; None when nothing stands out."""
    r = np.linalg.norm(np.asarray(residuals, dtype=float).reshape(-1, 2), axis=1)
    limit = max(floor_px, factor * 1.4826 * float(np.median(r)))
    if per_marker:
        worst = int(np.argmax(r.reshape(-1, 4).max(axis=1)))
        idx = np.arange(4 * worst, 4 * worst + 4)
    else:
        idx = np.array([int(np.argmax(r))])
    return idx if float(r[idx].max()) > limit else None


def _aprilgrid_points(gray, spec: AprilGridSpec, markers, intrinsics, config, name, rejections):
    obj, img, ideal, used = [], [], [], []
    for marker_id, quad in markers:
        side = float(np.min(np.linalg.norm(quad - np.roll(quad, -1, axis=0), axis=1)))
        if side < config.min_side_px:
            rejections.append(TargetRejection(
                name, RejectReason.TOO_SMALL.value,
                f"grid tag {marker_id}: shortest side {side:.1f} px < min_side_px "
                f"{config.min_side_px:g}", marker_id))
            continue
        if spec.corner_squares:
            quad = _saddle_corners(gray, quad, spec)
        q_ideal = None
        if config.corner_refinement == "edge":
            refined = refine_corners_edges(gray, quad, intrinsics, _edge_cells(spec))
            if refined is not None:
                q_ideal, quad = refined
        if q_ideal is None:
            q_ideal = intrinsics.undistort_points(quad)
        obj.append(spec.marker_object_points(marker_id))
        img.append(quad)
        ideal.append(q_ideal)
        used.append(marker_id)
    if not used:
        return np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 2)), ()
    return np.concatenate(obj), np.concatenate(img), np.concatenate(ideal), tuple(used)


def _charuco_points(gray, spec: CharucoSpec, markers, intrinsics, detector):
    used = tuple(m for m, _ in markers)
    if len(markers) == 0:
        return np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 2)), used, ""
    quads = tuple(np.asarray(q, dtype=np.float32).reshape(1, 4, 2) for _, q in markers)
    ids = np.array(used, dtype=np.int32).reshape(-1, 1)
    ch_corners, ch_ids, _, _ = detector.detectBoard(gray, markerCorners=quads, markerIds=ids)
    if ch_ids is None or len(ch_ids) == 0:
        return np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 2)), used, ""
    ch_ids = np.asarray(ch_ids, dtype=int).reshape(-1)
    img = np.asarray(ch_corners, dtype=float).reshape(-1, 2)
    note = ""
    if len(ch_ids) >= 4 and detector.getBoard().checkCharucoCornersCollinear(
            ch_ids.astype(np.int32).reshape(-1, 1)):
        note = "ChArUco corners are collinear"
    obj = spec.corner_object_points()[ch_ids]
    return obj, img, intrinsics.undistort_points(img), used, note


def estimate_board(
    gray: np.ndarray,
    target: TargetSpec,
    markers: Sequence[tuple[int, np.ndarray]],
    intrinsics: CameraIntrinsics,
    config: DetectorConfig,
    *,
    predicted: np.ndarray | None = None,
    charuco: cv2.aruco.CharucoDetector | None = None,
    noise_history: Sequence[float] | None = None,
    noise: dict[str, float] | None = None,
) -> tuple[TargetObservation | None, list[TargetRejection]]:
    """Pose of one marker board from its detected markers (module docstring).

    Parameters
    ----------
    gray : ndarray, shape (H, W), uint8
        The image (for corner refinement).
    target : TargetSpec
        A board target.
    markers : sequence of (int, ndarray (4, 2))
        The markers of this board found in the image (id, corners in distorted pixels, in
        ``cv2.aruco``'s order); ids seen twice are dropped here.
    intrinsics : CameraIntrinsics
    config : DetectorConfig
        Gates, refinement, flip check and precision floors.
    predicted : ndarray (4, 4), optional
        Predicted ``T_cam_board`` (resolves pose flips).
    charuco : cv2.aruco.CharucoDetector, optional
        Reused detector of a ChArUco target (made here when None).
    noise_history, noise
        As in :func:`board_observation`.

    Returns
    -------
    observation : TargetObservation or None
    rejections : list of TargetRejection
        Dropped markers and, without an observation, why the board was rejected.
    """
    board = target.board
    if not isinstance(board, (AprilGridSpec, CharucoSpec)):
        raise ValueError(f"target {target.name!r} is not a marker board")
    name = target.name
    rejections: list[TargetRejection] = []
    counts: dict[int, int] = {}
    for marker_id, _ in markers:
        counts[int(marker_id)] = counts.get(int(marker_id), 0) + 1
    unique = []
    for marker_id in sorted(counts):
        if counts[marker_id] > 1:  # one rejection per id seen several times
            rejections.append(TargetRejection(
                name, RejectReason.DUPLICATE_ID.value,
                f"marker {marker_id} seen {counts[marker_id]} times", marker_id))
    for marker_id, quad in sorted(markers, key=lambda m: int(m[0])):
        if counts[int(marker_id)] == 1:
            unique.append((int(marker_id), np.asarray(quad, dtype=float).reshape(4, 2)))

    note = ""
    if isinstance(board, AprilGridSpec):
        obj, img, ideal, used = _aprilgrid_points(gray, board, unique, intrinsics, config, name,
                                                  rejections)
    else:
        detector = charuco if charuco is not None else charuco_detector(board, config)
        obj, img, ideal, used, note = _charuco_points(gray, board, unique, intrinsics, detector)
    if note and len(obj) >= target.min_corners:
        rejections.append(TargetRejection(name, RejectReason.TOO_FEW_CORNERS.value, note))
        return None, rejections
    obs = board_observation(target, obj, img, ideal, intrinsics, config, rejections,
                            marker_ids=used, per_marker=isinstance(board, AprilGridSpec),
                            predicted=predicted, noise_history=noise_history, noise=noise)
    return obs, rejections


def board_observation(
    target: TargetSpec,
    obj: np.ndarray,
    img: np.ndarray,
    ideal: np.ndarray,
    intrinsics: CameraIntrinsics,
    config: DetectorConfig,
    rejections: list[TargetRejection],
    *,
    marker_ids: tuple[int, ...] = (),
    per_marker: bool = False,
    predicted: np.ndarray | None = None,
    noise_history: Sequence[float] | None = None,
    noise: dict[str, float] | None = None,
) -> TargetObservation | None:
    """Steps 2-4 of the module docstring on a board's points (any board kind): enough points,
    pose with outliers dropped, flip check, reprojection and obliquity gates, precision.

    Parameters
    ----------
    target : TargetSpec
    obj, img, ideal : ndarray, shapes (N, 3), (N, 2), (N, 2)
        Board-frame points, their detected images (distorted pixels) and the same undistorted.
    intrinsics : CameraIntrinsics
    config : DetectorConfig
    rejections : list of TargetRejection
        Appended to: why the board was rejected.
    marker_ids : tuple of int
        Markers behind the points (AprilGrid: 4 points per marker, in order).
    per_marker : bool
        Drop outliers a marker (4 points) at a time.
    predicted : ndarray (4, 4), optional
        Predicted ``T_cam_board`` (resolves pose flips).
    noise_history : sequence of float, optional
        Corner noise of the camera's earlier poses (:meth:`DetectorConfig.reprojection_limit`).
    noise : dict of str to float, optional
        Receives, under the target's name, the corner noise this pose measures
        (:func:`corner_noise_px`), when solved.

    Returns
    -------
    TargetObservation or None
    """
    name = target.name

    def reject(reason: RejectReason, detail: str) -> None:
        rejections.append(TargetRejection(name, reason.value, detail))

    if len(obj) < target.min_corners:
        return reject(RejectReason.TOO_FEW_CORNERS,
                      f"{len(obj)} corners < min_corners {target.min_corners}")

    def solve(obj, img, ideal):
        return solve_planar_pose(
            obj, img, ideal, intrinsics, square=False, refine=config.refine_pose,
            min_ratio=config.flip_min_ratio, min_separation_deg=config.flip_min_separation_deg,
            prediction_margin=config.flip_prediction_margin, predicted=predicted)

    n_total = len(obj)
    used = tuple(marker_ids)
    try:
        pose = solve(obj, img, ideal)
        # Drop the worst marker / point while it stands out, at most a quarter of the points.
        while pose.T is not None:
            drop = _worst_outlier(intrinsics.project_points(obj, pose.T) - img, per_marker)
            if (drop is None or len(obj) - len(drop) < target.min_corners
                    or n_total - len(obj) + len(drop) > n_total // 4):
                break
            keep = np.ones(len(obj), dtype=bool)
            keep[drop] = False
            obj, img, ideal = obj[keep], img[keep], ideal[keep]
            if per_marker:
                used = tuple(m for i, m in enumerate(used) if keep[4 * i])
            pose = solve(obj, img, ideal)
    except (cv2.error, np.linalg.LinAlgError, ValueError) as exc:
        return reject(RejectReason.POSE_FAILED, str(exc).strip()[:200])
    if pose.T is None:
        return reject(RejectReason.POSE_FAILED, pose.detail)
    if pose.status == PoseStatus.AMBIGUOUS:
        return reject(RejectReason.AMBIGUOUS_POSE, pose.detail)
    T, rms = pose.T, pose.rms_px
    if noise is not None and np.isfinite(rms):
        noise[name] = corner_noise_px(rms, len(obj))
    limit = config.reprojection_limit(rms, len(obj), noise_history)
    if not np.isfinite(rms) or rms > limit:
        return reject(RejectReason.REPROJECTION_ERROR,
                      f"RMS {rms:.3f} px > {limit:.3g} px (max_reprojection_rms_px "
                      f"{config.max_reprojection_rms_px:g}, scaled to the camera's corner noise)")
    t = T[:3, 3]
    cos_obl = float(np.clip(T[:3, 2] @ (-t / np.linalg.norm(t)), -1.0, 1.0))
    obliquity = float(np.degrees(np.arccos(cos_obl)))
    if obliquity > config.max_obliquity_deg:
        return reject(RejectReason.TOO_OBLIQUE,
                      f"obliquity {obliquity:.1f} deg > max_obliquity_deg "
                      f"{config.max_obliquity_deg:g}")
    sigma = kappa = None
    if config.estimate_precision:
        sigma, kappa = points_precision(
            obj, T, intrinsics, rms, pixel_noise_floor_px=config.pixel_noise_floor_px,
            sigma_floor_m=config.sigma_floor_m,
            rotation_std_floor_deg=config.rotation_std_floor_deg)
    return TargetObservation(
        name=name, kind=target.kind, T_cam_target=T, reprojection_rms_px=rms,
        obliquity_deg=obliquity, marker_ids=used, image_points=img, object_points=obj,
        sigma=sigma, kappa=kappa, pose_status=pose.status.value, flip_ratio=pose.ratio,
        outlier_corners=n_total - len(obj),
    )

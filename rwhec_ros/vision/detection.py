"""AprilTag detection and tag pose estimation: the camera-tag measurements ``B = T_cam_tag``.

Pipeline per image (:meth:`TagDetector.detect`):

1. ``cv2.aruco.ArucoDetector`` with an AprilTag dictionary finds the four corners of each black
   square (distorted pixels) with the configured corner refinement
   (:class:`~rwhec_ros.vision.candidates.CandidateSearch`; on a decimated image for large images,
   ``DetectorConfig.decimate``);
2. the corners are undistorted with the camera model (:class:`CameraIntrinsics`) and
   ``cv2.solvePnPGeneric(..., SOLVEPNP_IPPE_SQUARE)`` returns the (up to two) planar poses,
   each optionally polished with ``cv2.solvePnPRefineLM``; the one with the smaller
   reprojection error in the *distorted* image is kept unless the two are not clearly
   separated (the pose flip, :mod:`rwhec_ros.vision.planar_pose`): then a predicted pose decides
   or the tag is rejected as ``ambiguous_pose``;
3. gates (tag id in the configuration, apparent size, obliquity, reprojection error) turn a
   detection into a :class:`TagObservation` or a :class:`TagRejection` with its reason;
4. optionally a translation standard deviation ``sigma`` and a Langevin rotation concentration
   ``kappa`` are attached (the paper's per-pair precisions of eq. (32)-(33);
   :mod:`rwhec_ros.vision.precision`).

Tag frame (identical in :mod:`rwhec_ros.vision.render`): origin at the centre of the black
square, ``x`` right and ``y`` up on the printed tag, ``z`` out of the tag face toward the viewer
(OpenCV's ``SOLVEPNP_IPPE_SQUARE`` / ``cv2.aruco`` convention). Corner ``i`` of
:attr:`TagObservation.corners` is the image of :data:`TAG_CORNERS_UNIT` ``[i] * size``, i.e.
top-left, top-right, bottom-right, bottom-left of the upright tag. Note: the AprilTag C library
reports a different tag frame (``y`` down, ``z`` into the tag), i.e. this frame rotated by 180
degrees about ``x``.

The precision model (``sigma``, ``kappa``) is that of :mod:`rwhec_ros.vision.precision`; the
options and rejection reasons live in :mod:`rwhec_ros.vision.detector_config` (re-exported here).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from .candidates import CandidateSearch
from .detector_config import (
    CORNER_REFINEMENT_MODES,
    DetectorConfig,
    RejectReason,
    corner_noise_px,
)
from .edges import refine_corners_edges
from .families import marker_cells
from .intrinsics import CameraIntrinsics
from .planar_pose import PoseStatus, solve_planar_pose
from .precision import pose_precision

__all__ = [
    "TAG_CORNERS_UNIT",
    "CORNER_REFINEMENT_MODES",
    "RejectReason",
    "DetectorConfig",
    "TagObservation",
    "TagRejection",
    "DetectionResult",
    "TagDetector",
    "tag_object_points",
    "pose_precision",
]

#: Corners of a unit tag in the tag frame, in the order ``cv2.aruco`` reports them and
#: ``SOLVEPNP_IPPE_SQUARE`` requires: top-left, top-right, bottom-right, bottom-left.
TAG_CORNERS_UNIT = np.array(
    [[-0.5, 0.5, 0.0], [0.5, 0.5, 0.0], [0.5, -0.5, 0.0], [-0.5, -0.5, 0.0]]
)
TAG_CORNERS_UNIT.setflags(write=False)


def tag_object_points(size: float) -> np.ndarray:
    """Corners (4, 3) of a tag of black-square edge ``size`` in the tag frame (IPPE order)."""
    return np.array(TAG_CORNERS_UNIT) * float(size)


@dataclass(eq=False)
class TagObservation:
    """One accepted tag: the measurement ``B = T_cam_tag`` with its quality figures.

    Attributes
    ----------
    tag_id : int
    T_cam_tag : ndarray, shape (4, 4)
        Pose of the tag frame in the camera frame (maps tag coordinates to camera coordinates).
    reprojection_rms_px : float
        RMS over the 4 corners of the distance between detected and reprojected corners
        (distorted image, pixels).
    side_px : float
        Shortest side of the detected quad (pixels).
    obliquity_deg : float
        Angle between the tag normal (``+z``) and the ray from the tag centre to the camera.
    corners : ndarray, shape (4, 2)
        Detected corners (distorted pixels), order of :data:`TAG_CORNERS_UNIT`.
    sigma : float or None
        Translation standard deviation (metres), cf. eq. (20); None if not estimated.
    kappa : float or None
        Langevin rotation concentration, cf. eq. (20); None if not estimated.
    size : float
        Tag size used (metres, nominal if the scale is unknown).
    pose_status : str
        ``"unique"`` or ``"resolved_by_prediction"`` (:class:`~.planar_pose.PoseStatus`).
    flip_ratio : float
        ``e_alt / e_best`` of the two IPPE poses (inf when only one was in front).
    """

    tag_id: int
    T_cam_tag: np.ndarray
    reprojection_rms_px: float
    side_px: float
    obliquity_deg: float
    corners: np.ndarray
    sigma: float | None
    kappa: float | None
    size: float
    pose_status: str = PoseStatus.UNIQUE.value
    flip_ratio: float = float("inf")


@dataclass(frozen=True)
class TagRejection:
    """A detected tag that was not accepted: ``reason`` is a :class:`RejectReason` value."""

    tag_id: int
    reason: str
    detail: str = ""


@dataclass
class DetectionResult:
    """Output of :meth:`TagDetector.detect` (every list empty when nothing is seen).

    ``skipped`` holds the configured ids that the candidate search found but that were left
    unexamined because the caller asked only for other ids (``detect(..., only_ids=...)``);
    ``corner_noise_px`` the corner noise (:func:`~rwhec_ros.vision.detector_config.
    corner_noise_px`) of every pose solved, by tag id, accepted or not (the caller's noise
    history).
    """

    observations: list[TagObservation] = field(default_factory=list)
    rejections: list[TagRejection] = field(default_factory=list)
    skipped: list[int] = field(default_factory=list)
    corner_noise_px: dict[int, float] = field(default_factory=dict)

    def by_id(self) -> dict[int, TagObservation]:
        """Accepted observations keyed by tag id."""
        return {obs.tag_id: obs for obs in self.observations}


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


class TagDetector:
    """AprilTag detector + IPPE pose estimator (see the module docstring).

    Parameters
    ----------
    config : DetectorConfig, optional
        Defaults to ``DetectorConfig()`` (tag36h11, no sizes: every tag is rejected until sizes
        are configured).
    """

    def __init__(self, config: DetectorConfig | None = None) -> None:
        self.config = DetectorConfig() if config is None else config
        self._cells = marker_cells(self.config.family)
        self._search = CandidateSearch(
            self.config.family,
            self.config.aruco_parameters(),
            fixed_min_perimeter="minMarkerPerimeterRate" in self.config.detector_parameters,
        )

    def detect(
        self,
        gray: np.ndarray,
        intrinsics: CameraIntrinsics,
        predicted: Mapping[int, np.ndarray] | None = None,
        *,
        only_ids: Collection[int] | None = None,
        noise_history: Sequence[float] | None = None,
    ) -> DetectionResult:
        """Detect tags in an 8-bit grayscale image and estimate their poses.

        Parameters
        ----------
        gray : ndarray, shape (H, W), uint8
            Image of the camera ``intrinsics`` (see :func:`rwhec_ros.vision.image.image_to_gray`).
        intrinsics : CameraIntrinsics
            Calibration of the camera; its size must match the image.
        predicted : mapping of int to ndarray (4, 4), optional
            Predicted ``T_cam_tag`` per tag id (from the current estimate); resolves pose flips
            (:mod:`rwhec_ros.vision.planar_pose`).
        only_ids : collection of int, optional
            Examine only these configured ids: the candidate search runs on the whole image as
            always, but a configured tag outside ``only_ids`` gets no corner refinement, pose or
            gates and is listed in ``DetectionResult.skipped`` (the live session passes the tags
            whose pair the keyframe test could keep). Each tag is examined on its own, so the
            observations of the ids examined are those of a full ``detect``.
        noise_history : sequence of float, optional
            Corner noise [px] of the camera's earlier poses: scales the reprojection gate
            (:meth:`DetectorConfig.reprojection_limit`); None: the fixed floor only. The noise
            of each pose solved here is in :attr:`DetectionResult.corner_noise_px`.

        Returns
        -------
        DetectionResult
            Accepted observations (ascending tag id), rejections with reasons and skipped ids.

        Raises
        ------
        ValueError
            If ``gray`` is not a 2D uint8 array of the size of ``intrinsics`` (the image itself
            never causes an exception).
        """
        img = np.asarray(gray)
        if img.ndim != 2 or img.dtype != np.uint8:
            raise ValueError(
                f"gray must be a 2D uint8 array, got shape {img.shape} dtype {img.dtype}"
            )
        if img.shape != (intrinsics.height, intrinsics.width):
            raise ValueError(
                f"gray shape {img.shape} does not match intrinsics (height, width) "
                f"{(intrinsics.height, intrinsics.width)}"
            )
        result = DetectionResult()
        try:
            ids, corners = self.detect_markers(img)
        except cv2.error as exc:  # an OpenCV failure on a valid image: report, do not raise
            result.rejections.append(
                TagRejection(-1, RejectReason.DETECTOR_ERROR.value, str(exc).strip()[:200])
            )
            return result
        return self.estimate_markers(img, ids, corners, intrinsics, predicted, result,
                                     only_ids=only_ids, noise_history=noise_history)

    def estimate_markers(
        self,
        gray: np.ndarray,
        ids: list[int],
        corners: list[np.ndarray],
        intrinsics: CameraIntrinsics,
        predicted: Mapping[int, np.ndarray] | None = None,
        result: DetectionResult | None = None,
        *,
        only_ids: Collection[int] | None = None,
        noise_history: Sequence[float] | None = None,
    ) -> DetectionResult:
        """The stages after :meth:`detect_markers` (duplicates, refinement, pose, gates) on given
        markers (ids and corners (4, 2) in distorted pixels) of a validated image; appends to
        ``result`` (a new one by default); ``only_ids`` and ``noise_history`` as in
        :meth:`detect`."""
        result = DetectionResult() if result is None else result
        img = gray
        if not ids:
            return result
        counts: dict[int, int] = {}
        for tag_id in ids:
            counts[tag_id] = counts.get(tag_id, 0) + 1
        wanted = None if only_ids is None else {int(i) for i in only_ids}
        for tag_id, quad in sorted(zip(ids, corners, strict=True), key=lambda p: p[0]):
            if (wanted is not None and tag_id not in wanted
                    and self.config.size_of(tag_id) is not None):
                result.skipped.append(tag_id)
                continue
            quad = np.asarray(quad, dtype=float).reshape(4, 2)
            if counts[tag_id] > 1:
                result.rejections.append(
                    TagRejection(
                        tag_id,
                        RejectReason.DUPLICATE_ID.value,
                        f"id seen {counts[tag_id]} times in one image",
                    )
                )
                continue
            outcome = self._estimate(
                img, tag_id, quad, intrinsics, None if predicted is None else predicted.get(tag_id),
                noise_history, result.corner_noise_px)
            if isinstance(outcome, TagObservation):
                result.observations.append(outcome)
            else:
                result.rejections.append(outcome)
        return result

    def detect_markers(self, gray: np.ndarray) -> tuple[list[int], list[np.ndarray]]:
        """Only the candidate search: tag ids and their corners (4, 2) in distorted pixels,
        with aruco's own refinement (SUBPIX for ``"edge"``, at full resolution also when the
        search ran on a decimated image, see ``DetectorConfig.decimate``); no gates, no pose."""
        img = np.ascontiguousarray(gray)
        return self._search.find(img, self.config.decimation_for(img.shape[1], img.shape[0]))

    def solve_pose(
        self, corners: np.ndarray, size: float, intrinsics: CameraIntrinsics
    ) -> np.ndarray | None:
        """``T_cam_tag`` (4, 4) from given corners (4, 2) (distorted pixels, order of
        :data:`TAG_CORNERS_UNIT`): IPPE_SQUARE, plus LM if ``refine_pose``; None if no pose in
        front of the camera. No corner refinement and no gates."""
        quad = np.asarray(corners, dtype=float).reshape(4, 2)
        pose = self._solve_pose(quad, intrinsics.undistort_points(quad), float(size), intrinsics)
        return pose.T

    # ------------------------------------------------------------------ one tag
    def _estimate(
        self,
        gray: np.ndarray,
        tag_id: int,
        quad: np.ndarray,
        intrinsics: CameraIntrinsics,
        predicted: np.ndarray | None = None,
        noise_history: Sequence[float] | None = None,
        noise: dict[int, float] | None = None,
    ) -> TagObservation | TagRejection:
        cfg = self.config
        size = cfg.size_of(tag_id)
        if size is None:
            return TagRejection(
                tag_id,
                RejectReason.NOT_IN_CONFIGURATION.value,
                "no entry in tag_sizes and default_tag_size is None",
            )
        side_px = float(np.min(np.linalg.norm(quad - np.roll(quad, -1, axis=0), axis=1)))
        if side_px < cfg.min_side_px:
            return TagRejection(
                tag_id,
                RejectReason.TOO_SMALL.value,
                f"shortest side {side_px:.1f} px < min_side_px {cfg.min_side_px:g}",
            )
        ideal = None
        if cfg.corner_refinement == "edge":
            refined = refine_corners_edges(gray, quad, intrinsics, self._cells)
            if refined is not None:
                ideal, quad = refined
        try:
            if ideal is None:
                ideal = intrinsics.undistort_points(quad)
            pose = self._solve_pose(quad, ideal, size, intrinsics, predicted)
        except (cv2.error, np.linalg.LinAlgError, ValueError) as exc:
            return TagRejection(tag_id, RejectReason.POSE_FAILED.value, str(exc).strip()[:200])
        if pose.T is None:
            return TagRejection(tag_id, RejectReason.POSE_FAILED.value, pose.detail)
        if pose.status == PoseStatus.AMBIGUOUS:
            return TagRejection(tag_id, RejectReason.AMBIGUOUS_POSE.value, pose.detail)
        T = pose.T
        obj = tag_object_points(size)
        rms = _rms(intrinsics.project_points(obj, T), quad)
        t = T[:3, 3]
        distance = float(np.linalg.norm(t))
        cos_obl = float(np.clip(T[:3, 2] @ (-t / distance), -1.0, 1.0))
        obliquity = float(np.degrees(np.arccos(cos_obl)))
        if noise is not None and np.isfinite(rms):
            noise[tag_id] = corner_noise_px(rms, 4)
        limit = cfg.reprojection_limit(rms, 4, noise_history)
        if not np.isfinite(rms) or rms > limit:
            detail = f"RMS {rms:.3f} px > max_reprojection_rms_px {cfg.max_reprojection_rms_px:g}"
            if noise_history is not None:
                detail = (f"RMS {rms:.3f} px > {limit:.3g} px (max_reprojection_rms_px "
                          f"{cfg.max_reprojection_rms_px:g}, scaled to the camera's corner noise)")
            return TagRejection(tag_id, RejectReason.REPROJECTION_ERROR.value, detail)
        if obliquity > cfg.max_obliquity_deg:
            return TagRejection(
                tag_id,
                RejectReason.TOO_OBLIQUE.value,
                f"obliquity {obliquity:.1f} deg > max_obliquity_deg {cfg.max_obliquity_deg:g}",
            )
        sigma = kappa = None
        if cfg.estimate_precision:
            sigma, kappa = pose_precision(
                rms,
                distance,
                intrinsics.focal_px,
                size,
                pixel_noise_floor_px=cfg.pixel_noise_floor_px,
                sigma_floor_m=cfg.sigma_floor_m,
                rotation_std_floor_deg=cfg.rotation_std_floor_deg,
            )
        return TagObservation(
            tag_id=tag_id,
            T_cam_tag=T,
            reprojection_rms_px=rms,
            side_px=side_px,
            obliquity_deg=obliquity,
            corners=quad,
            sigma=sigma,
            kappa=kappa,
            size=float(size),
            pose_status=pose.status.value,
            flip_ratio=pose.ratio,
        )

    def _solve_pose(
        self,
        quad: np.ndarray,
        ideal: np.ndarray,
        size: float,
        intrinsics: CameraIntrinsics,
        predicted: np.ndarray | None = None,
    ):
        """IPPE_SQUARE poses from undistorted corners and the flip check (``PlanarPose``)."""
        cfg = self.config
        return solve_planar_pose(
            tag_object_points(size),
            quad,
            ideal,
            intrinsics,
            square=True,
            refine=cfg.refine_pose,
            min_ratio=cfg.flip_min_ratio,
            min_separation_deg=cfg.flip_min_separation_deg,
            prediction_margin=cfg.flip_prediction_margin,
            predicted=predicted,
        )

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
   ``kappa`` are attached (the paper's per-pair precisions of eq. (32)-(33); model below).

Tag frame (identical in :mod:`rwhec_ros.vision.render`): origin at the centre of the black
square, ``x`` right and ``y`` up on the printed tag, ``z`` out of the tag face toward the viewer
(OpenCV's ``SOLVEPNP_IPPE_SQUARE`` / ``cv2.aruco`` convention). Corner ``i`` of
:attr:`TagObservation.corners` is the image of :data:`TAG_CORNERS_UNIT` ``[i] * size``, i.e.
top-left, top-right, bottom-right, bottom-left of the upright tag. Note: the AprilTag C library
reports a different tag frame (``y`` down, ``z`` into the tag), i.e. this frame rotated by 180
degrees about ``x``.

Precision model (``DetectorConfig.estimate_precision``)
-------------------------------------------------------
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
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
from enum import Enum

import cv2
import numpy as np

from .candidates import CandidateSearch, check_decimate, decimation_factor
from .edges import refine_corners_edges
from .families import _family_key, marker_cells
from .intrinsics import CameraIntrinsics
from .planar_pose import PoseStatus, check_flip_options, solve_planar_pose

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

#: Corner refinement name -> ``cv2.aruco`` constant.
CORNER_REFINEMENT_MODES: dict[str, int] = {
    "none": cv2.aruco.CORNER_REFINE_NONE,
    "subpix": cv2.aruco.CORNER_REFINE_SUBPIX,
    "contour": cv2.aruco.CORNER_REFINE_CONTOUR,
    "apriltag": cv2.aruco.CORNER_REFINE_APRILTAG,
    # Not an aruco mode: aruco's SUBPIX corners seed the edge-line fit of vision.edges (and are
    # kept when that fit is not possible, e.g. for tiny tags).
    "edge": cv2.aruco.CORNER_REFINE_SUBPIX,
}


class RejectReason(str, Enum):
    """Why a detected tag did not become an observation (compares equal to its string value)."""

    NOT_IN_CONFIGURATION = "not_in_configuration"
    DUPLICATE_ID = "duplicate_id"
    TOO_SMALL = "too_small"
    POSE_FAILED = "pose_failed"
    REPROJECTION_ERROR = "reprojection_error"
    TOO_OBLIQUE = "too_oblique"
    DETECTOR_ERROR = "detector_error"
    AMBIGUOUS_POSE = "ambiguous_pose"
    TOO_FEW_CORNERS = "too_few_corners"


def tag_object_points(size: float) -> np.ndarray:
    """Corners (4, 3) of a tag of black-square edge ``size`` in the tag frame (IPPE order)."""
    return np.array(TAG_CORNERS_UNIT) * float(size)


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


@dataclass
class DetectorConfig:
    """Options of :class:`TagDetector` (validated on construction).

    Attributes
    ----------
    family : str
        AprilTag family: ``tag16h5``, ``tag25h9``, ``tag36h10`` or ``tag36h11`` (default).
    tag_sizes : dict[int, float]
        Black-square edge length (metres) per tag id.
    default_tag_size : float or None
        Size of tags not in ``tag_sizes``; None (default) rejects them as
        ``not_in_configuration``.
    unknown_scale : bool
        The sizes are nominal (one common unknown factor, the paper's alpha of Section 4.3):
        poses and ``sigma`` are then in nominal units; build the problem with
        ``Problem(..., unknown_scale=True)``.
    corner_refinement : str
        ``"edge"`` (default): edge-line fitting of :mod:`rwhec_ros.vision.edges` seeded by
        aruco's SUBPIX corners; or one of ``cv2.aruco``'s own refinements ``"subpix"``,
        ``"apriltag"``, ``"contour"``, ``"none"``. The default was chosen by measured corner and
        pose accuracy on rendered images (``benchmarks/perception.md``).
    refine_pose : bool
        Polish the IPPE pose with ``cv2.solvePnPRefineLM`` (default True: IPPE alone is not the
        reprojection-error minimum for near face-on tags; LM cut the worst rotation error
        several-fold in ``benchmarks/perception.md``).
    max_reprojection_rms_px : float
        Reject a tag whose RMS corner reprojection error exceeds this (default 1.0 px; rendered
        tags give below 0.05 px with the edge refinement, so 1 px flags a wrong quad, not noise).
    min_side_px : float
        Reject a tag whose shortest quad side is below this (default 20 px: 2.5 px per cell of a
        tag36h11, about the least for reliable decoding and for the edge refinement, whose
        profiles must stay within one cell of the edge).
    max_obliquity_deg : float
        Reject a tag whose normal makes more than this angle with the ray to the camera
        (default 70 degrees; 0 = face-on; see the obliquity table of
        ``benchmarks/perception.md``).
    estimate_precision : bool
        Attach ``sigma`` / ``kappa`` to each observation (default True); None otherwise.
    pixel_noise_floor_px, sigma_floor_m, rotation_std_floor_deg : float
        Floors of the precision model (defaults 0.1 px, 1 mm, 0.05 degrees).
    detector_parameters : dict[str, float]
        Overrides of ``cv2.aruco.DetectorParameters`` attributes (e.g.
        ``{"adaptiveThreshWinSizeStep": 20}``); names are checked. They apply to the searched
        (possibly decimated) image.
    decimate : int or "auto"
        Candidate search on the image shrunk by this integer factor, corners refined at full
        resolution (:mod:`rwhec_ros.vision.candidates`); 1 searches the full image. ``"auto"``
        (default) picks ``max(W, H) // 600`` (1280x1024 -> 2, 640x480 -> 1). Only the
        ``"edge"`` and ``"subpix"`` refinements have a full-resolution step; the other modes
        always search the full image. A factor ``d`` raises the smallest detectable tag about
        ``d``-fold (``benchmarks/perception.md``).
    flip_min_ratio : float
        Pose-flip check (:mod:`rwhec_ros.vision.planar_pose`): a tag whose two IPPE poses
        reproject within this ratio of each other (``e_alt / e_best``) is ambiguous (default 3;
        1 disables the check).
    flip_min_separation_deg : float
        Two IPPE poses closer than this in rotation count as one (default 2 degrees).
    flip_prediction_margin : float
        An ambiguous tag is resolved by a predicted pose when the nearer solution is at most
        this fraction of the other's angle from it (default 0.75).
    """

    family: str = "tag36h11"
    tag_sizes: dict[int, float] = field(default_factory=dict)
    default_tag_size: float | None = None
    unknown_scale: bool = False
    corner_refinement: str = "edge"
    refine_pose: bool = True
    max_reprojection_rms_px: float = 1.0
    min_side_px: float = 20.0
    max_obliquity_deg: float = 70.0
    estimate_precision: bool = True
    pixel_noise_floor_px: float = 0.1
    sigma_floor_m: float = 1e-3
    rotation_std_floor_deg: float = 0.05
    detector_parameters: dict[str, float] = field(default_factory=dict)
    decimate: int | str = "auto"
    flip_min_ratio: float = 3.0
    flip_min_separation_deg: float = 2.0
    flip_prediction_margin: float = 0.75

    def __post_init__(self) -> None:
        self.family = _family_key(self.family)
        sizes: dict[int, float] = {}
        for key, value in dict(self.tag_sizes).items():
            if isinstance(key, bool) or int(key) != key or int(key) < 0:
                raise ValueError(f"tag_sizes key must be a non-negative integer id, got {key!r}")
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"tag_sizes[{key}] must be positive, got {value!r}")
            sizes[int(key)] = float(value)
        self.tag_sizes = sizes
        if self.default_tag_size is not None and not (
            np.isfinite(self.default_tag_size) and self.default_tag_size > 0
        ):
            raise ValueError(
                f"default_tag_size must be positive or None, got {self.default_tag_size!r}"
            )
        if self.corner_refinement not in CORNER_REFINEMENT_MODES:
            raise ValueError(
                f"corner_refinement must be one of {sorted(CORNER_REFINEMENT_MODES)}, got "
                f"{self.corner_refinement!r}"
            )
        for name in (
            "max_reprojection_rms_px",
            "pixel_noise_floor_px",
            "sigma_floor_m",
            "rotation_std_floor_deg",
        ):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be positive, got {value!r}")
        if not (np.isfinite(self.min_side_px) and self.min_side_px >= 0):
            raise ValueError(f"min_side_px must be >= 0, got {self.min_side_px!r}")
        if not (0 < self.max_obliquity_deg <= 90):
            raise ValueError(
                f"max_obliquity_deg must be in (0, 90], got {self.max_obliquity_deg!r}"
            )
        params = cv2.aruco.DetectorParameters()
        for name in dict(self.detector_parameters):
            if name.startswith("_") or not hasattr(params, name) or callable(getattr(params, name)):
                raise ValueError(f"detector_parameters has an unknown name {name!r}")
        self.detector_parameters = dict(self.detector_parameters)
        self.decimate = check_decimate(self.decimate)
        check_flip_options(self.flip_min_ratio, self.flip_min_separation_deg,
                           self.flip_prediction_margin, prefix="flip_")

    def decimation_for(self, width: int, height: int) -> int:
        """The decimation factor used for images of ``width x height`` (1 for refinements
        without a full-resolution step)."""
        if self.corner_refinement not in ("edge", "subpix"):
            return 1
        return decimation_factor(self.decimate, width, height)

    def size_of(self, tag_id: int) -> float | None:
        """Configured size of ``tag_id`` (metres), or None when the tag is not configured."""
        return self.tag_sizes.get(int(tag_id), self.default_tag_size)

    def aruco_parameters(self) -> cv2.aruco.DetectorParameters:
        """``cv2.aruco.DetectorParameters`` for this configuration."""
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = CORNER_REFINEMENT_MODES[self.corner_refinement]
        # Let the gates (min_side_px) decide about small tags, with a reason, instead of aruco.
        params.minMarkerPerimeterRate = 0.01
        for name, value in self.detector_parameters.items():
            setattr(params, name, type(getattr(params, name))(value))
        return params


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
    unexamined because the caller asked only for other ids (``detect(..., only_ids=...)``).
    """

    observations: list[TagObservation] = field(default_factory=list)
    rejections: list[TagRejection] = field(default_factory=list)
    skipped: list[int] = field(default_factory=list)

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
                                     only_ids=only_ids)

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
    ) -> DetectionResult:
        """The stages after :meth:`detect_markers` (duplicates, refinement, pose, gates) on given
        markers (ids and corners (4, 2) in distorted pixels) of a validated image; appends to
        ``result`` (a new one by default); ``only_ids`` as in :meth:`detect`."""
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
                img, tag_id, quad, intrinsics, None if predicted is None else predicted.get(tag_id)
            )
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
        if not np.isfinite(rms) or rms > cfg.max_reprojection_rms_px:
            return TagRejection(
                tag_id,
                RejectReason.REPROJECTION_ERROR.value,
                f"RMS {rms:.3f} px > max_reprojection_rms_px {cfg.max_reprojection_rms_px:g}",
            )
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

"""Options of the target detectors: :class:`DetectorConfig`, the corner refinements and the reasons
a detection is rejected (:class:`RejectReason`).

Shared by the single-tag detector (:mod:`rwhec_ros.vision.detection`), the boards
(:mod:`rwhec_ros.vision.board_detection`) and :mod:`rwhec_ros.vision.target_detector`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import Enum

import cv2
import numpy as np

from .candidates import check_decimate, decimation_factor
from .families import dictionary_key
from .planar_pose import check_flip_options

__all__ = ["CORNER_REFINEMENT_MODES", "CHESSBOARD_REFINEMENTS", "RejectReason", "DetectorConfig",
           "corner_noise_px"]

#: ``chessboard_refinement`` values: SB's own corners, or ``cv2.cornerSubPix`` after them.
CHESSBOARD_REFINEMENTS = ("sb", "subpix")

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



def corner_noise_px(rms_px: float, n_points: int) -> float:
    """Per-coordinate corner noise [px] that a pose fit of ``n_points >= 4`` points with RMS
    reprojection error ``rms_px`` (2D norm) measures: ``rms sqrt(N / (2N - 6))`` (``E[N rms^2]
    = (2N - 6) sigma^2``, 6 pose parameters; ``sqrt(2) rms`` for a tag's 4 corners, the model
    of :mod:`rwhec_ros.vision.precision`)."""
    n = int(n_points)
    if n < 4:
        raise ValueError(f"n_points must be >= 4, got {n_points!r}")
    return float(rms_px) * float(np.sqrt(n / (2.0 * n - 6.0)))


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
    PARTIAL_VIEW = "partial_view"
    AMBIGUOUS_ORIENTATION = "ambiguous_orientation"



@dataclass
class DetectorConfig:
    """Options of :class:`TagDetector` (validated on construction).

    Attributes
    ----------
    family : str
        AprilTag family: ``tag16h5``, ``tag25h9``, ``tag36h10`` or ``tag36h11`` (default), or an
        ArUco dictionary of ``cv2.aruco`` (``DICT_6X6_250``; single markers as users print them
        with OpenCV: the tag's size is the side of its black square, as for AprilTags).
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
    chessboard_refinement : str
        Chessboard corners: ``"sb"`` (default) as ``cv2.findChessboardCornersSB`` finds them,
        or ``"subpix"`` polished by ``cv2.cornerSubPix`` (:mod:`rwhec_ros.vision.
        grid_detection`); chosen on the real chessboard set and renders
        (``benchmarks/real_data.md``).
    refine_pose : bool
        Polish the IPPE pose with ``cv2.solvePnPRefineLM`` (default True: IPPE alone is not the
        reprojection-error minimum for near face-on tags; LM cut the worst rotation error
        several-fold in ``benchmarks/perception.md``).
    max_reprojection_rms_px : float
        Reprojection gate, floor (default 1.0 px): a pose whose RMS corner reprojection error is
        at or below it is never rejected for it. Without a noise history (``detect(...,
        noise_history=None)``) it is the whole gate (rendered tags give below 0.05 px with the
        edge refinement, so 1 px flags a wrong quad, not noise).
    reprojection_gate_factor : float
        Reprojection gate, scaled part (default 4): with a noise history (the live session keeps
        one per camera) a pose above the floor is rejected when the corner noise it measures,
        :func:`corner_noise_px`, exceeds this factor times the median of the history and itself
        (:meth:`reprojection_limit`): the gate follows the corner noise of the camera's own
        images (lens model errors included) instead of a fixed pixel count.
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
        1 disables the check); for ``N > 4`` points the same excess misfit of the mirror pose
        in units of the measured corner noise, a ratio nearer 1 (:func:`~rwhec_ros.vision.
        planar_pose.ratio_for_points`).
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
    chessboard_refinement: str = "sb"
    refine_pose: bool = True
    max_reprojection_rms_px: float = 1.0
    reprojection_gate_factor: float = 4.0
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
        try:
            self.family = dictionary_key(self.family)
        except ValueError as exc:
            raise ValueError(f"family: {exc}") from None
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
        if self.chessboard_refinement not in CHESSBOARD_REFINEMENTS:
            raise ValueError(
                f"chessboard_refinement must be one of {list(CHESSBOARD_REFINEMENTS)}, got "
                f"{self.chessboard_refinement!r}")
        for name in (
            "max_reprojection_rms_px",
            "reprojection_gate_factor",
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
        if self.reprojection_gate_factor < 1:
            raise ValueError(f"reprojection_gate_factor must be >= 1, got "
                             f"{self.reprojection_gate_factor!r}")

    def reprojection_limit(self, rms_px: float, n_points: int,
                           noise_history: Sequence[float] | None = None) -> float:
        """The RMS reprojection error [px] above which a pose of ``n_points`` points whose RMS
        is ``rms_px`` is rejected: ``max_reprojection_rms_px`` without a history, else the
        larger of it and ``reprojection_gate_factor`` times the median of ``noise_history``
        and this pose's own :func:`corner_noise_px`, converted back to an RMS of
        ``n_points``. The pose's own value counts so that a camera's first images are judged
        by their own noise (a gross error is caught once a few poses are known)."""
        if noise_history is None:
            return float(self.max_reprojection_rms_px)
        scale = corner_noise_px(1.0, n_points)
        noise = np.median(np.r_[np.asarray(noise_history, dtype=float).reshape(-1),
                                rms_px * scale])
        return float(max(self.max_reprojection_rms_px,
                         self.reprojection_gate_factor * noise / scale))

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


"""Detect every configured target -- single tags and boards, mixed -- in one image.

:class:`TargetDetector` runs ``cv2.aruco``'s marker detection once per marker kind in use (one
dictionary and border width: the single tags' family with one-bit borders, a Kalibr grid's
two-bit borders, a ChArUco board's ArUco dictionary), then hands each target its markers:

* single tags to :meth:`rwhec_ros.vision.detection.TagDetector.estimate_markers` (edge
  refinement, IPPE_SQUARE, flip check, gates, precision model of that module); a marker kind
  used by single tags only is searched by that detector's candidate search (decimated on large
  images, ``DetectorConfig.decimate``), kinds with boards at full resolution;
* boards to :func:`rwhec_ros.vision.board_detection.estimate_board`;
* chessboards and circle grids (no markers) are searched each by its own
  :class:`~rwhec_ros.vision.grid_detection.GridFinder` (OpenCV's grid detectors, labels fixed by
  the board's pattern or a predicted pose), then posed by
  :func:`~rwhec_ros.vision.board_detection.board_observation` like the marker boards.

Markers of no target are reported as ``not_in_configuration`` (by the kind they were found in);
markers of a board printed with another border width, found by the wrong pass, are ignored.

Kalibr's corner squares touch each grid tag at its corners; once blurred, the contact joins the
tag's black border to the squares and to the neighbouring tags, and aruco's contour search no
longer sees the tag as a quadrilateral (on rendered 6 cm tags at 2.2 m it found none of 20).
Raising aruco's ``adaptiveThreshConstant`` to about a quarter of the black-white contrast cuts
those contacts; since the contrast is not known beforehand, the marker kinds of such grids are
searched with several constants (``grid_threshold_constants``) and the results merged (a marker
found by several passes at the same place counts once).
Predicted poses (``T_cam_target`` by target name, from the current estimate) resolve pose flips
and place partial views of chessboards. A noise history (the corner noise of the camera's earlier
poses, :meth:`DetectorConfig.reprojection_limit`) scales the reprojection gate.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import replace

import cv2
import numpy as np

from .board_detection import board_observation, charuco_detector, estimate_board
from .boards import CharucoSpec, get_dictionary
from .detection import DetectorConfig, RejectReason, TagDetector, tag_object_points
from .grid_detection import GridFinder
from .intrinsics import CameraIntrinsics
from .targets import (
    TargetDetectionResult,
    TargetObservation,
    TargetRejection,
    TargetSpec,
    validate_targets,
)

__all__ = ["TargetDetector"]


class TargetDetector:
    """Detector of a set of targets (module docstring). Holds ``cv2`` detector objects: not
    thread-safe, use one per thread (like :class:`~rwhec_ros.vision.detection.TagDetector`).

    Parameters
    ----------
    targets : sequence of TargetSpec
        Checked by :func:`~rwhec_ros.vision.targets.validate_targets` against
        ``config.family`` (the family of the single tags).
    config : DetectorConfig, optional
        Refinement, gates, flip check and precision options, shared by all targets;
        ``tag_sizes`` / ``default_tag_size`` are replaced by the single-tag targets.
    grid_threshold_constants : sequence of float
        ``adaptiveThreshConstant`` values of the marker passes for AprilGrids printed with
        corner squares (default 7, 20, 40: aruco's default, and about a quarter of a contrast
        of 80 and of 160 grey levels).

    Raises
    ------
    ValueError
        For an invalid target set.
    """

    def __init__(
        self,
        targets: Sequence[TargetSpec],
        config: DetectorConfig | None = None,
        *,
        grid_threshold_constants: Sequence[float] = (7.0, 20.0, 40.0),
    ):
        config = DetectorConfig() if config is None else config
        constants = tuple(float(c) for c in grid_threshold_constants)
        if not constants or not all(np.isfinite(c) and c > 0 for c in constants):
            raise ValueError(f"grid_threshold_constants must be positive numbers, got "
                             f"{grid_threshold_constants!r}")
        self.targets = validate_targets(targets, config.family)
        singles = {t.tag_id: t for t in self.targets if t.board is None}
        self.config = replace(config, tag_sizes={i: t.tag_size for i, t in singles.items()},
                              default_tag_size=None)
        self._tags = TagDetector(self.config)
        self._single_names = {i: t.name for i, t in singles.items()}
        # Marker kinds in use: (dictionary, border bits) -> marker id -> target.
        self._groups: dict[tuple[str, int], dict[int, TargetSpec]] = {}
        for t in self.targets:
            if not t.has_markers:
                continue
            group = self._groups.setdefault((t.dictionary(self.config.family), t.border_bits()),
                                            {})
            for marker in t.marker_ids():
                group[marker] = t
        self._claimed = {(d, m) for (d, _), g in self._groups.items() for m in g}
        # A marker kind holding single tags only goes through TagDetector's candidate search
        # (decimated on large images, DetectorConfig.decimate); kinds with boards are searched
        # at full resolution (grid tags are small: decimation would lose them first).
        self._tag_search_only = {
            key for key, owners in self._groups.items()
            if all(t.board is None for t in owners.values())}
        self._detectors: dict[tuple[str, int], list[cv2.aruco.ArucoDetector]] = {}
        for (dictionary, bits), owners in self._groups.items():
            squares = any(getattr(t.board, "corner_squares", False) for t in owners.values())
            passes = []
            for c in constants if squares else (None,):
                params = self.config.aruco_parameters()
                params.markerBorderBits = int(bits)
                if c is not None:
                    params.adaptiveThreshConstant = c
                passes.append(cv2.aruco.ArucoDetector(get_dictionary(dictionary), params))
            if (dictionary, bits) not in self._tag_search_only:
                self._detectors[(dictionary, bits)] = passes
        self._charuco = {t.name: charuco_detector(t.board, self.config)
                         for t in self.targets if isinstance(t.board, CharucoSpec)}
        self._grids = {t.name: GridFinder(t, self.config)
                       for t in self.targets if not t.has_markers}

    def detect(
        self,
        gray: np.ndarray,
        intrinsics: CameraIntrinsics,
        predicted: Mapping[str, np.ndarray] | None = None,
        *,
        only: Collection[str] | None = None,
        noise_history: Sequence[float] | None = None,
    ) -> TargetDetectionResult:
        """Detect all targets in an 8-bit grayscale image.

        Parameters
        ----------
        gray : ndarray, shape (H, W), uint8
        intrinsics : CameraIntrinsics
            Its size must match the image.
        predicted : mapping of str to ndarray (4, 4), optional
            Predicted ``T_cam_target`` by target name (resolves pose flips).
        only : collection of str, optional
            Examine only these targets: the marker search runs on the whole image as always,
            but a target outside ``only`` gets no refinement, pose or gates and is listed in
            ``TargetDetectionResult.skipped`` (the live session's motion gate). Each target is
            examined on its own, so the observations of the targets examined are those of a
            full ``detect``. A chessboard or circle grid is always searched (its search is its
            marker search) and skipped after it.
        noise_history : sequence of float, optional
            Corner noise of the camera's earlier poses: scales the reprojection gate
            (:meth:`DetectorConfig.reprojection_limit`); None: the fixed floor. The noise of
            each pose solved here is in :attr:`TargetDetectionResult.corner_noise_px`.

        Returns
        -------
        TargetDetectionResult
            Observations in the order of the targets, rejections.

        Raises
        ------
        ValueError
            If ``gray`` is not a 2D uint8 array of the size of ``intrinsics``.
        """
        img = np.asarray(gray)
        if img.ndim != 2 or img.dtype != np.uint8:
            raise ValueError(
                f"gray must be a 2D uint8 array, got shape {img.shape} dtype {img.dtype}")
        if img.shape != (intrinsics.height, intrinsics.width):
            raise ValueError(f"gray shape {img.shape} does not match intrinsics (height, width) "
                             f"{(intrinsics.height, intrinsics.width)}")
        predicted = dict(predicted or {})
        result = TargetDetectionResult()
        found: dict[str, list[tuple[int, np.ndarray]]] = {t.name: [] for t in self.targets}
        single_ids: list[int] = []
        single_quads: list[np.ndarray] = []
        for (dictionary, bits), owners in self._groups.items():
            try:
                if (dictionary, bits) in self._tag_search_only:
                    markers = list(zip(*self._tags.detect_markers(img), strict=True))
                else:
                    markers = _merged_markers(self._detectors[(dictionary, bits)], img)
            except cv2.error as exc:  # an OpenCV failure on a valid image: report, do not raise
                result.rejections.append(TargetRejection(
                    "", RejectReason.DETECTOR_ERROR.value, str(exc).strip()[:200]))
                continue
            for marker_id, quad in markers:
                target = owners.get(marker_id)
                if target is None:
                    if (dictionary, marker_id) not in self._claimed:
                        result.rejections.append(TargetRejection(
                            "", RejectReason.NOT_IN_CONFIGURATION.value,
                            f"{dictionary} marker {marker_id} belongs to no target", marker_id))
                        result.markers.setdefault("", []).append((marker_id, quad))
                elif target.board is None:
                    single_ids.append(marker_id)
                    single_quads.append(quad)
                    found[target.name].append((marker_id, quad))
                else:
                    found[target.name].append((marker_id, quad))
        result.markers.update({n: m for n, m in found.items() if m})
        tag_predictions = {i: predicted[n] for i, n in self._single_names.items()
                           if n in predicted}
        only_ids = None if only is None else [i for i, n in self._single_names.items()
                                              if n in only]
        singles = self._tags.estimate_markers(img, single_ids, single_quads, intrinsics,
                                              tag_predictions, only_ids=only_ids,
                                              noise_history=noise_history)
        result.corner_noise_px.update({self._single_names[i]: v
                                       for i, v in singles.corner_noise_px.items()
                                       if i in self._single_names})
        result.skipped.extend(self._single_names[i] for i in singles.skipped)
        by_id = {o.tag_id: o for o in singles.observations}
        for r in singles.rejections:
            result.rejections.append(TargetRejection(
                self._single_names.get(r.tag_id, ""), r.reason, r.detail, r.tag_id))
        for t in self.targets:
            if t.board is None:
                o = by_id.get(t.tag_id)
                if o is not None:
                    result.observations.append(TargetObservation(
                        name=t.name, kind="tag", T_cam_target=o.T_cam_tag,
                        reprojection_rms_px=o.reprojection_rms_px,
                        obliquity_deg=o.obliquity_deg, marker_ids=(t.tag_id,),
                        image_points=o.corners, object_points=tag_object_points(t.tag_size),
                        sigma=o.sigma, kappa=o.kappa, pose_status=o.pose_status,
                        flip_ratio=o.flip_ratio))
                continue
            if not t.has_markers:
                self._grid(img, t, intrinsics, predicted.get(t.name), only, noise_history, result)
                continue
            if not found[t.name]:
                continue
            if only is not None and t.name not in only:
                result.skipped.append(t.name)
                continue
            obs, rejections = estimate_board(
                img, t, found[t.name], intrinsics, self.config,
                predicted=predicted.get(t.name), charuco=self._charuco.get(t.name),
                noise_history=noise_history, noise=result.corner_noise_px)
            result.rejections.extend(rejections)
            if obs is not None:
                result.observations.append(obs)
        return result


    def _grid(self, img: np.ndarray, target: TargetSpec, intrinsics: CameraIntrinsics,
              predicted: np.ndarray | None, only: Collection[str] | None,
              noise_history: Sequence[float] | None, result: TargetDetectionResult) -> None:
        """Search, label and pose one chessboard or circle grid into ``result``."""
        try:
            points, rejections, outline = self._grids[target.name].find(img, intrinsics,
                                                                        predicted)
        except cv2.error as exc:  # an OpenCV failure on a valid image: report, do not raise
            result.rejections.append(TargetRejection(
                target.name, RejectReason.DETECTOR_ERROR.value, str(exc).strip()[:200]))
            return
        if outline is None:
            return
        result.markers[target.name] = [(-1, outline)]
        if only is not None and target.name not in only:
            result.skipped.append(target.name)
            return
        result.rejections.extend(rejections)
        if points is None:
            return
        obs = board_observation(target, points.object_points, points.image_points, points.ideal,
                                intrinsics, self.config, result.rejections, predicted=predicted,
                                noise_history=noise_history, noise=result.corner_noise_px)
        if obs is not None:
            if points.how == "prediction":
                obs.pose_status = "resolved_by_prediction"
            result.observations.append(obs)


def _merged_markers(passes: Sequence[cv2.aruco.ArucoDetector],
                    gray: np.ndarray) -> list[tuple[int, np.ndarray]]:
    """``(id, corners (4, 2))`` found by any pass; the same id at the same place (centres less
    than half a side apart) once, from the first pass that found it."""
    out: list[tuple[int, np.ndarray]] = []
    img = np.ascontiguousarray(gray)
    for detector in passes:
        corners, ids, _ = detector.detectMarkers(img)
        if ids is None:
            continue
        for marker_id, quad in zip(np.asarray(ids).reshape(-1), corners, strict=True):
            quad = np.asarray(quad, dtype=float).reshape(4, 2)
            centre = quad.mean(axis=0)
            side = float(np.min(np.linalg.norm(quad - np.roll(quad, -1, axis=0), axis=1)))
            if not any(m == int(marker_id) and np.linalg.norm(q.mean(axis=0) - centre)
                       < 0.5 * side for m, q in out):
                out.append((int(marker_id), quad))
    return out

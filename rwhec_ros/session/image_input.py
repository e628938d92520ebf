"""The image path of the live session: pose first, then the motion gate, then decoding and tags.

:class:`ImageInput` is the part of :class:`~rwhec_ros.session.CalibrationSession` that takes one
camera image (:meth:`ImageInput.add_image`); it works on the session's state (lock, pose buffer,
pair accumulator, counters) and is kept in its own module only for size.

Order of the work for one image of camera ``c`` at stamp ``s``:

1. cheap checks (known camera, intrinsics, stamp; for an array its type and size);
2. ``A`` at ``s``: the given pose (tf), or the pose buffer. An image that no pose brackets yet
   waits, *undecoded*, for one (:mod:`rwhec_ros.session.image_wait`: as long as the pose stream's
   measured lateness needs, at most ``sync.max_pose_wait_s``, or while the stream may be at rest;
   the pose that brackets it processes it); where the buffer cannot serve ``s`` the stop-and-go
   rule of :mod:`rwhec_ros.sync.at_rest` may (counted ``pose_at_rest``); then ``capture.mode``
   and the pending captures (:mod:`rwhec_ros.session.capture`): in capture-only mode an image no
   capture takes is left out here, undecoded (``images_not_captured``); an image a capture takes
   skips the motion gate;
3. **motion gate** (``detection.motion_gate``): the keyframe test of
   :class:`~rwhec_ros.sync.accumulator.PairAccumulator` depends on the stamp and ``A`` only, so
   before any pixel is read the session asks every edge ``(target, c)`` whether it would keep a
   pair at ``(s, A)`` (:meth:`~rwhec_ros.sync.accumulator.PairAccumulator.would_keep`; an edge
   not seen yet always would). Targets out of view: an edge whose target left the view (or was
   never in it) would always keep a pair, which would hold the gate open wherever a camera sees
   a changing subset of the targets. So the session remembers, per camera, the pose ``A_c`` of
   its last searched image and the targets whose markers were found there; while ``A`` is within
   ``detection.discovery_step`` times the keyframe thresholds of ``A_c`` only those targets count
   (the view has hardly changed); beyond it every keepable target counts and the image is
   searched (discovery). No target that counts: the image is skipped, neither decoded nor
   searched (counted ``images_skipped_no_motion`` and per camera). Otherwise
4. the image is decoded (``image`` may be a callable, e.g. a JPEG decoder, called only now), the
   marker search runs on the whole image, and only the targets (single tags and boards) that
   could give a pair are refined and solved (:meth:`TargetDetector.detect(..., only=...)
   <rwhec_ros.vision.target_detector.TargetDetector.detect>`; the others are counted
   ``tags_skipped_no_motion``);
5. one pair per target -- a board is one ``B`` from all its corners -- is offered to the
   accumulator (which applies the same keyframe test again). The corner noise each pose
   measured goes to the camera's noise history, which scales the reprojection gate of its next
   images (:meth:`DetectorConfig.reprojection_limit
   <rwhec_ros.vision.detector_config.DetectorConfig.reprojection_limit>`). An image searched is
   counted once by what it gave: ``images_used``, ``images_no_new_pairs``,
   ``images_without_tags`` (no configured target found) or ``images_targets_rejected:<reason>``
   (targets found, all rejected: the first whole-target reason);
6. **look-back** (discovery step > 0): the targets this search found and the camera's previous
   search had not (they came into view meanwhile) are searched for in the images of the camera
   that the gate skipped in between (at most :data:`LOOK_BACK_IMAGES`, held undecoded), oldest
   first and only where such a target's edge would keep a pair, and their pairs offered before
   those of this image (counted ``images_searched_back``).

With ``detection.discovery_step: 0`` (every edge counts) the gate changes no pair: a tag left out
would have been refused by its edge (its edge's state, the stamp and ``A`` decide, not ``B``), and
each tag is refined and solved on its own, so the kept pairs are those of examining every tag of
every image, provided the images of one camera are added one at a time in stamp order (what the
node's per-camera queue and the ``bag`` replay do): an edge's decision depends on the pairs kept
before it. With a discovery step (default 0.5) a target coming into view between two searches is
found at the next search, at most that fraction of a keyframe step later; the look-back then
finds it in the skipped images since the previous search, so that its edge keeps its first pair
(and so all later ones) where examining every image would. What the discovery step still loses
is a target that enters and leaves the view between two searches, and one first seen more than
:data:`LOOK_BACK_IMAGES` skipped images back: in the camera-rate benchmark
(``benchmarks/session_load.md``, 8 cameras among 16 tags) the default searches 49 % of the
images (4 % of them searched back) and keeps exactly the pairs of examining every image (without
the look-back: 44 % searched, 1.7 % fewer pairs). What the gate also changes are the counters of
refused pairs (``pairs:skipped_no_motion`` counts only examined tags) and that a skipped image
is never decoded, so bad data in it goes unnoticed.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ..vision.detection import DetectorConfig, RejectReason
from ..vision.target_detector import TargetDetector
from .capture import NOT_CAPTURED
from .image_wait import NO_POSE_PREFIX, ImageWait
from .outcomes import ImageOutcome

__all__ = ["ImageInput", "ImageSource", "safe_int", "CAMERA_COUNTERS", "LOOK_BACK_IMAGES",
           "detector_config", "first_target_rejection", "no_pair_counter"]

#: An image as the session takes it: a (H, W) uint8 array, or a callable returning one (decoded
#: only when the motion gate lets the image through; ``ValueError``/``TypeError`` from it counts
#: as ``bad_image_message``).
ImageSource = np.ndarray | Callable[[], np.ndarray]

#: Skipped images of a camera held for the look-back (module docstring, step 6), newest kept:
#: references to the undecoded messages (at 30 Hz with the default discovery step a camera is
#: searched every 1-3 images; 8 covers a quarter of a second).
LOOK_BACK_IMAGES = 8
#: Verdicts of :meth:`ImageInput.gate_would_skip` remembered (then forgotten all at once): a
#: verdict holds while its camera's epoch (a pair kept for the camera, a search of it, a new
#: configuration, a reset) is unchanged; the queue asks again for the same images while full.
_GATE_MEMO_SIZE = 4096

#: Per-camera counters of :meth:`ImageInput.camera_counters` (all present from the start).
CAMERA_COUNTERS = ("images", "skipped_no_motion", "detected", "used", "rejected", "no_pose",
                   "pairs_kept")


def safe_int(value: Any) -> int | None:
    """``value`` as an int when it is an integral number (not a bool), else None."""
    try:
        if isinstance(value, bool):
            return None
        out = int(value)
        return out if out == value else None
    except (TypeError, ValueError, OverflowError):
        return None


def detector_config(config) -> DetectorConfig:
    """The detector settings of a :class:`~rwhec_ros.config.CalibratorConfig` (``tags.*``,
    ``detection.*``; the per-pose precision always estimated)."""
    return DetectorConfig(
        family=config.tags.family,
        tag_sizes=dict(config.tags.sizes),
        default_tag_size=None,
        unknown_scale=config.tags.unknown_scale,
        corner_refinement=config.detection.corner_refinement,
        max_reprojection_rms_px=config.detection.max_reprojection_rms_px,
        reprojection_gate_factor=config.detection.reprojection_gate_factor,
        chessboard_refinement=config.detection.chessboard_refinement,
        min_side_px=config.detection.min_side_px,
        max_obliquity_deg=config.detection.max_obliquity_deg,
        estimate_precision=True,
        decimate=config.detection.decimate,
    )


def no_pair_counter(detection) -> str:
    """The image counter of a search that found no configured target to pose
    (:data:`CAMERA_COUNTERS` aside): ``images_without_tags``, or
    ``images_targets_rejected:<reason>`` (:func:`first_target_rejection`)."""
    why = first_target_rejection(detection)
    return "images_without_tags" if why is None else f"images_targets_rejected:{why}"


def first_target_rejection(detection) -> str | None:
    """The reason an image whose configured targets were all rejected gave no pair: the first
    whole-target rejection of a configured target, else its first marker's; None when no
    configured target was found (markers of no target do not count)."""
    own = [r for r in detection.rejections if r.name]
    if not own:
        return None
    own.sort(key=lambda r: r.marker_id != -1)
    return own[0].reason


class ImageInput(ImageWait):
    """Mixin of :class:`~rwhec_ros.session.CalibrationSession`: the image path (see the module
    docstring; waiting for poses: :class:`~rwhec_ros.session.image_wait.ImageWait`). It uses the
    session's ``_lock``, ``_buffer``, ``_acc``, ``_tracker``,
    ``_pending``, ``_counters``, ``_camera_counts``, ``_rejections``, ``_intrinsics``,
    ``_corner_noise``,
    ``_data_version``, ``_x_names``, ``_target_specs``, ``_local``, ``_detector_config``,
    ``_capture``, ``config`` and
    ``_pose_to_A``."""

    # --- public --------------------------------------------------------------------------------
    def add_image(
        self,
        camera: str,
        stamp_ns: int,
        image: ImageSource,
        T_parent_child: np.ndarray | None = None,
        *,
        arrived_ns: int | None = None,
    ) -> ImageOutcome:
        """Take one image: pose, motion gate, tags, pairs (module docstring).

        Parameters
        ----------
        camera : str
            Camera name of the configuration.
        stamp_ns : int
            Image stamp [ns].
        image : ndarray (H, W) uint8, or callable returning one
            Grayscale image of the camera's intrinsics size; a callable is called only when the
            image is examined (a skipped image is never decoded).
        T_parent_child : ndarray (4, 4), optional
            The pose at exactly this stamp (e.g. a tf lookup); otherwise it is looked up in the
            pose buffer, and the image waits (bounded in time and memory,
            :mod:`~rwhec_ros.session.image_wait`) while no pose brackets the stamp yet.
        arrived_ns : int, optional
            When the image arrived, on the session's clock (:meth:`image_arrival`); default:
            now.

        Returns
        -------
        ImageOutcome
            Never raises for bad data; each rejection is counted by reason.
        """
        with self._lock:
            self._count("images")
            self._rejections.saw("images", str(camera))
            intrinsics = self._intrinsics.get(camera)
            known = camera in self.config.camera_names
            if known:
                self._camera_count(camera, "images")
        if not known:
            return self._reject(camera, safe_int(stamp_ns), "image_unknown_camera")
        if intrinsics is None:
            return self._reject(camera, safe_int(stamp_ns), "image_missing_camera_info",
                                words="no CameraInfo had arrived for this camera")
        stamp = self.pose_time(camera, stamp_ns)
        if stamp is None or stamp < 0:
            return self._reject(camera, stamp, "image_bad_stamp")
        if not callable(image):
            reason = self._gray_problem(image, intrinsics)
            if reason:
                return self._reject(camera, stamp, reason,
                                    words=self._gray_words(reason, image, intrinsics))
        if T_parent_child is not None:
            A = self._pose_to_A(T_parent_child)
            if A is None:
                return self._reject(camera, stamp, "image_bad_pose")
            return self._examine(camera, stamp, image, intrinsics, A)
        arrived = self.image_arrival(stamp) if arrived_ns is None else int(arrived_ns)
        overflow: list[tuple] = []
        with self._lock:
            state, A, reason = self._pose_at(stamp, arrived, final=False)
            if state == "wait":
                overflow = self._hold(camera, stamp, image, intrinsics, arrived)
        for item in overflow:  # the oldest waiting images get what the buffer has now
            self._finish_pending(item, final=True, cause="wait_memory")
        if state == "wait":
            self._serve_pending()  # the clock moved: others may be due
            return ImageOutcome(camera, stamp, "pending")
        if A is None:
            outcome = self._reject(camera, stamp, reason)
        else:
            outcome = self._examine(camera, stamp, image, intrinsics, A)
        self._serve_pending()
        return outcome

    def pose_time(self, camera: str, stamp_ns: Any) -> int | None:
        """An image stamp of ``camera`` [ns] on the pose stream's clock: plus
        ``sync.time_offset.<camera>`` (``t_pose = t_image + offset``; the session works in pose
        time). None for an invalid stamp. What callers give :meth:`pose_ready`,
        :meth:`image_arrival` and :meth:`gate_would_skip` for the image."""
        stamp = safe_int(stamp_ns)
        if stamp is None:
            return None
        return stamp + int(round(self.config.sync.time_offset_s(str(camera)) * 1e9))

    def image_time(self, camera: str, pose_ns: int) -> int:
        """The inverse of :meth:`pose_time`: a time of ``camera``'s images on the pose stream's
        clock (an :class:`~.outcomes.ImageOutcome`'s ``stamp_ns``) back on the camera's own
        clock (what its image header said), e.g. for the annotated image ``~/detections``."""
        return int(pose_ns) - int(round(self.config.sync.time_offset_s(str(camera)) * 1e9))

    def gate_would_skip(self, camera: str, stamp_ns: int) -> bool:
        """True when the motion gate would skip an image of ``camera`` stamped ``stamp_ns``
        if it were examined now (its pose is in the buffer; nothing is counted or changed).
        False whenever that is not known (gate off, unknown camera, invalid stamp, the pose not
        there yet). The node's image queue uses it to drop such an image first when a camera's
        queue is full, rather than the oldest one, which might give a pair."""
        stamp = safe_int(stamp_ns)
        if (not self.config.detection.motion_gate or stamp is None or stamp < 0
                or camera not in self.config.camera_names):
            return False
        with self._lock:
            epoch = self._gate_epochs[camera]
            memo = self._gate_memo.get((camera, stamp))
            if memo is not None and memo[0] == epoch:
                return memo[1]
            if memo is not None:
                A = memo[2]  # the pose at a bracketed stamp does not change
            else:
                newest = self._buffer.newest_ns
                A = (self._buffer.lookup(stamp, count=False)
                     if newest is not None and stamp <= newest else None)
                if A is None:  # the pose is not there (yet): not known
                    return False
            skip = not self._worth_searching(camera, A, self._keepable_targets(camera, stamp, A))
            if len(self._gate_memo) >= _GATE_MEMO_SIZE:
                self._gate_memo.clear()
            self._gate_memo[(camera, stamp)] = (epoch, skip, A)
            return skip

    def camera_counters(self) -> dict[str, dict[str, int]]:
        """Per camera (configuration order): ``images`` taken, ``skipped_no_motion`` (motion
        gate: not decoded, not searched), ``detected`` (searched for tags), ``used`` (at least
        one pair kept), ``rejected`` (any reason) and ``pairs_kept``."""
        with self._lock:
            return {c: dict(self._camera_counts[c]) for c in self.config.camera_names}

    # --- gate, decode, detect, offer -------------------------------------------------------------
    def _keepable_targets(self, camera: str, stamp: int, A: np.ndarray) -> list[str]:
        """Targets (X names) whose edge with ``camera`` would keep a pair at ``(stamp, A)``
        (lock held)."""
        return [x for x in self._x_names if self._acc.would_keep(x, camera, stamp, A)]

    def _worth_searching(self, camera: str, A: np.ndarray, wanted: list[str]) -> bool:
        """The motion gate's verdict for an image of ``camera`` at ``A`` whose keepable targets
        are ``wanted`` (lock held; module docstring, step 3)."""
        if not wanted:
            return False
        step = self.config.detection.discovery_step
        view = self._views.get(camera) if step > 0 else None
        if view is None or self._acc.moved(view[0], A, step):
            return True
        return not view[1].isdisjoint(wanted)

    def _remember_view(self, camera: str, A: np.ndarray, detection) -> None:
        """The configured targets whose markers the search of an image of ``camera`` at ``A``
        found (lock held)."""
        self._views[camera] = (A, frozenset(name for name in detection.markers if name))
        self._gate_epochs[camera] += 1

    def _examine(self, camera: str, stamp: int, image: ImageSource, intrinsics,
                 A: np.ndarray) -> ImageOutcome:
        """An image whose ``A`` is known (lock NOT held): first ``capture.mode`` and the pending
        captures (:class:`~rwhec_ros.session.capture.CaptureGate`): left out in capture-only
        mode, or taken by a capture (searched without the motion gate, its outcome delivered);
        then steps 3-5 of the module docstring."""
        with self._lock:
            take = self._capture.decide(camera, stamp, A, self.config)
            if take == NOT_CAPTURED:
                self._count("images_not_captured")
        if take == NOT_CAPTURED:
            return ImageOutcome(camera, stamp, "skipped", reasons=["images_not_captured"])
        outcome = self._search(camera, stamp, image, intrinsics, A, gate=take is None)
        for request in take or ():
            request.deliver(camera, outcome)
        return outcome

    def _search(self, camera: str, stamp: int, image: ImageSource, intrinsics,
                A: np.ndarray, *, gate: bool) -> ImageOutcome:
        """Steps 3-5 of the module docstring (the motion gate only with ``gate``)."""
        gate = gate and self.config.detection.motion_gate
        with self._lock:
            wanted = self._keepable_targets(camera, stamp, A) if gate else None
            if gate and not self._worth_searching(camera, A, wanted):
                self._count("images_skipped_no_motion")
                self._camera_count(camera, "skipped_no_motion")
                if self.config.detection.discovery_step > 0:
                    self._skipped_since_search[camera].append((stamp, A, image, intrinsics))
                return ImageOutcome(camera, stamp, "skipped")
            view = self._views.get(camera)
            skipped = list(self._skipped_since_search.pop(camera, ()))
        gray, reason, detail, words = self._decoded(image, intrinsics)
        if gray is None:
            return self._reject(camera, stamp, reason, detail, words=words)
        with self._lock:
            history = tuple(self._corner_noise[camera])
        try:  # outside the lock: detection is the expensive part
            detection = self._detector().detect(gray, intrinsics, only=wanted,
                                                noise_history=history)
        except Exception as exc:  # noqa: BLE001 - the live path never raises
            return self._reject(camera, stamp, f"image_detector_error:{type(exc).__name__}",
                                str(exc))
        if view is not None and skipped and self.config.detection.discovery_step > 0:
            new = {name for name in detection.markers if name} - view[1]
            if new:
                self._look_back(camera, skipped, new)
        outcome = self._offer_detection(camera, stamp, A, detection)
        self._hold_for_second_look(camera, stamp, image, intrinsics, A, detection, outcome)
        outcome.image = gray
        return outcome

    def _decoded(self, image: ImageSource, intrinsics) -> tuple[np.ndarray | None, str, str, str]:
        """``(gray, "", "", "")``, or ``(None, reason, detail, words)`` for :meth:`_reject` when
        ``image`` (an array, or a callable decoding one) is unusable (lock NOT held)."""
        if not callable(image):
            return image, "", "", ""
        try:
            gray = image()
        except (ValueError, TypeError, AttributeError) as exc:
            return None, "bad_image_message", str(exc), ""
        reason = self._gray_problem(gray, intrinsics)
        if reason:
            return None, reason, "", self._gray_words(reason, gray, intrinsics)
        return gray, "", "", ""

    def _look_back(self, camera: str, skipped: list[tuple], new: set[str]) -> None:
        """Search the images of ``camera`` that the gate skipped since its last search for the
        targets ``new`` that the search after them found and the one before them had not
        (lock NOT held; module docstring, step 6): oldest first, an image only where the edge
        of one of them would keep a pair. Counted ``images_searched_back``; an image that cannot
        be decoded now is counted ``look_back_bad_image`` (it was counted skipped)."""
        for stamp, A, image, intrinsics in skipped:
            with self._lock:
                wanted = [x for x in self._x_names
                          if x in new and self._acc.would_keep(x, camera, stamp, A)]
            if not wanted:
                continue
            gray, *_ = self._decoded(image, intrinsics)
            with self._lock:
                history = tuple(self._corner_noise[camera])
            try:
                detection = (None if gray is None
                             else self._detector().detect(gray, intrinsics, only=wanted,
                                                          noise_history=history))
            except Exception:  # noqa: BLE001 - the live path never raises
                detection = None
            with self._lock:
                if detection is None:
                    self._count("look_back_bad_image")
                    continue
                self._count("images_searched_back")
                self._corner_noise[camera].extend(detection.corner_noise_px.values())
                kept = self._offer(camera, stamp, A, detection.observations)
                self._camera_count(camera, "pairs_kept", len(kept))

    def _offer_detection(self, camera: str, stamp: int, A: np.ndarray, detection) -> ImageOutcome:
        reasons: list[str] = []
        with self._lock:
            self._camera_count(camera, "detected")
            self._remember_view(camera, A, detection)
            self._corner_noise[camera].extend(detection.corner_noise_px.values())
            for r in detection.rejections:
                key = (
                    "tag_not_in_config"
                    if r.reason == RejectReason.NOT_IN_CONFIGURATION.value
                    else f"tag_rejected:{r.reason}"
                )
                self._count(key)
                reasons.append(key)
            if detection.skipped:
                self._count("tags_skipped_no_motion", len(detection.skipped))
            obs = detection.observations
            self._count("tags_detected", len(obs))
            if not obs and not detection.skipped:
                self._count(no_pair_counter(detection))
                return ImageOutcome(camera, stamp, "no_tags", reasons=reasons,
                                    detection=detection)
            names = self._offer(camera, stamp, A, obs)
            kept = len(names)
            self._count("images_used" if kept else "images_no_new_pairs")
            if kept:
                self._camera_count(camera, "used")
                self._camera_count(camera, "pairs_kept", kept)
            return ImageOutcome(camera, stamp, "used" if kept else "no_new_pairs", len(obs),
                                kept, reasons, detection=detection, kept=tuple(names))

    def _offer(self, camera: str, stamp: int, A: np.ndarray, observations: list) -> list[str]:
        """Offer the pairs of one image, one per target (a board is one pair: one ``B`` from
        all its corners) (lock held); returns the targets whose pair was kept."""
        noise = self.config.noise
        kept = []
        for o in observations:
            if noise.from_reprojection and o.sigma is not None and o.kappa is not None:
                sigma, kappa = float(o.sigma), float(o.kappa)
            else:
                sigma, kappa = noise.sigma_start, noise.kappa_start
            x = o.name
            # the data set keeps each pair's corners (reprojection error, focal check): a
            # tag's four, or a board's seen corners with their board-frame points
            points = None if o.kind == "tag" else o.object_points
            ok = self._acc.offer(x, camera, stamp, A, o.T_cam_target, sigma, kappa,
                                 corners_px=o.image_points, corner_points_m=points)
            self._count("pairs_offered")
            if ok:
                kept.append(x)
                # a turn-symmetric board's view as labelled like the edge's first (None: its
                # turn not told yet; the solve's identifiability sees it once told)
                B = self._acc.tracker_B(x, camera, stamp, o.T_cam_target)
                if self._tracker is not None and B is not None:
                    try:
                        self._tracker.add_pair(x, camera, A, B, sigma, kappa)
                    except ValueError:
                        self._count("identifiability_rejected_pair")
        self._count("pairs_kept", len(kept))
        if kept:
            self._track.mark(stamp)  # the pose stream around it (time offsets)
            self._data_version += 1
            self._gate_epochs[camera] += 1
        return kept

    # --- helpers -------------------------------------------------------------------------------
    @staticmethod
    def _gray_problem(gray: Any, intrinsics) -> str:
        """The counter key of what is wrong with a decoded image, or ``""``."""
        if not isinstance(gray, np.ndarray) or gray.ndim != 2 or gray.dtype != np.uint8:
            return "image_not_gray_uint8"
        if gray.shape != (intrinsics.height, intrinsics.width):
            return "image_size_mismatch"
        return ""

    @staticmethod
    def _gray_words(reason: str, gray: Any, intrinsics) -> str:
        """What :meth:`_gray_problem` found, in words for the rejection log (``""``: not logged)."""
        if reason != "image_size_mismatch":
            return ""
        return (f"{gray.shape[1]}x{gray.shape[0]} images, CameraInfo says "
                f"{intrinsics.width}x{intrinsics.height}")

    def _camera_count(self, camera: str, key: str, n: int = 1) -> None:
        """Count per camera (lock held; unknown cameras are not counted)."""
        counts = self._camera_counts.get(camera)
        if counts is not None:
            counts[key] += n

    def _reject(self, camera: str, stamp: int | None, reason: str,
                detail: str = "", *, words: str = "") -> ImageOutcome:
        """Count a rejected image; ``words`` (what was wrong, with the numbers) also go to the
        session's :class:`~rwhec_ros.session.rejections.RejectionLog`."""
        with self._lock:
            if reason.startswith(NO_POSE_PREFIX):
                self._count_no_pose(str(camera), reason[len(NO_POSE_PREFIX):])
                return ImageOutcome(camera, stamp, "rejected", reasons=[reason], detail=detail)
            self._count(reason)
            self._camera_count(camera, "rejected")
            if words:
                self._rejections.reject(reason, str(camera), words)
        return ImageOutcome(camera, stamp, "rejected", reasons=[reason], detail=detail)

    def _detector(self) -> TargetDetector:
        det = getattr(self._local, "detector", None)
        if det is None:  # one detector per thread: cv2 detector objects are not shared
            det = self._local.detector = TargetDetector(self._target_specs,
                                                        self._detector_config)
        return det

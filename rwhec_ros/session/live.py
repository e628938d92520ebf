"""The live session, :class:`CalibrationSession`: poses and images in, certified extrinsics out.

See :mod:`rwhec_ros.session` for the pipeline, the live-path promise and the threading model.
"""

from __future__ import annotations

import collections
import datetime as _dt
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..config import CalibratorConfig
from ..core.lie import invert_transform
from ..core.result import CalibrationResult
from ..core.verdict import Verdict
from ..data.results import FrameNaming, new_output_dir, plain, result_document, utc_stamp
from ..errors import describe_os_error
from ..sync.accumulator import PairAccumulator
from ..sync.buffer import LookupStatus, PoseBuffer
from ..vision.detection import DetectorConfig, RejectReason, TagDetector
from ..vision.intrinsics import CameraIntrinsics
from .outcomes import ImageOutcome, SolveOutcome, edge_rows
from .outputs import publishable, session_dataset, summary, write_session_outputs
from .rejections import RejectionLog
from .solving import make_tracker, report_dict, solve_and_assess, verdict_options

__all__ = ["CalibrationSession"]

_NS_PER_S = 1_000_000_000


class CalibrationSession:
    """Accumulate synchronised measurement pairs live and calibrate on request.

    Parameters
    ----------
    config : CalibratorConfig
        Validated configuration (:func:`rwhec_ros.config.load_config` or
        :meth:`CalibratorConfig.from_parameters`).
    now : callable returning datetime, optional
        Clock for the timestamped output names (default: current UTC time); injectable for tests.

    Notes
    -----
    Frame names: Y variables are the camera names of the configuration, X variables the tag frame
    names ``<tags.frame_prefix><id>``; results are published as ``(parent, child)`` from
    :meth:`CalibratorConfig.published_frames`.
    """

    def __init__(
        self,
        config: CalibratorConfig,
        *,
        now: Callable[[], _dt.datetime] | None = None,
    ) -> None:
        self.config = config
        self._now = now if now is not None else (lambda: _dt.datetime.now(_dt.timezone.utc))
        self._lock = threading.Lock()
        self._solve_lock = threading.Lock()
        self._local = threading.local()
        self._detector_config = DetectorConfig(
            family=config.tags.family,
            tag_sizes=dict(config.tags.sizes),
            default_tag_size=None,
            unknown_scale=config.tags.unknown_scale,
            corner_refinement=config.detection.corner_refinement,
            max_reprojection_rms_px=config.detection.max_reprojection_rms_px,
            min_side_px=config.detection.min_side_px,
            max_obliquity_deg=config.detection.max_obliquity_deg,
            estimate_precision=True,
        )
        self._tag_names = {t: config.tags.frame_name(t) for t in config.tags.ids}
        self._intrinsics: dict[str, CameraIntrinsics] = {}
        self._last_outcome: SolveOutcome | None = None
        self._init_data()

    # --- state -------------------------------------------------------------------------------
    def _init_data(self) -> None:
        """(Re)create the data-holding parts; call with the lock held (or from __init__)."""
        c = self.config
        self._buffer = PoseBuffer(
            capacity=c.sync.pose_buffer_size,
            max_gap_ns=max(1, int(round(c.sync.max_gap_s * _NS_PER_S))),
            extrapolation_tol_ns=int(round(c.sync.extrapolation_tolerance_s * _NS_PER_S)),
        )
        self._acc = PairAccumulator(
            keyframe_rotation_rad=c.keyframe.min_rotation_rad,
            keyframe_translation_m=c.keyframe.min_translation_m,
            max_pairs_per_edge=c.keyframe.max_pairs_per_edge,
            max_edges=max(1, len(c.cameras) * len(c.tags.ids)),
        )
        self._tracker = make_tracker(c.tags.unknown_scale)
        self._pending: collections.deque = collections.deque()
        self._counters: collections.Counter = collections.Counter()
        self._rejections = RejectionLog()

    def _count(self, key: str, n: int = 1) -> None:
        self._counters[key] += n

    def record(self, reason: str, n: int = 1) -> None:
        """Count an event seen outside the session (e.g. a message the node could not convert,
        ``"bad_image_message"``). Thread-safe; never raises."""
        with self._lock:
            self._count(str(reason), int(n))

    # --- inputs ------------------------------------------------------------------------------
    def set_camera_info(self, camera: str, intrinsics: CameraIntrinsics) -> bool:
        """Set (or replace) the intrinsics of ``camera``; False (counted) for an unknown camera."""
        with self._lock:
            if camera not in self.config.camera_names:
                self._count("camera_info_unknown_camera")
                return False
            if not isinstance(intrinsics, CameraIntrinsics):
                self._count("camera_info_invalid")
                return False
            if self._intrinsics.get(camera) != intrinsics:
                self._count("camera_info_updates")
            self._intrinsics[camera] = intrinsics
            return True

    def has_camera_info(self, camera: str) -> bool:
        with self._lock:
            return camera in self._intrinsics

    def _pose_to_A(self, T_parent_child: Any) -> np.ndarray | None:
        try:
            T = np.asarray(T_parent_child, dtype=float)
        except (TypeError, ValueError):
            return None
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            return None
        return invert_transform(T) if self.config.pose_source.invert else T.copy()

    def add_pose(
        self, stamp_ns: int, T_parent_child: np.ndarray, source: str | None = None
    ) -> bool:
        """Add one sample ``T_parent_child`` of the pose stream at ``stamp_ns`` [ns].

        ``source`` is the message's parent frame (``header.frame_id``); a non-empty value that is
        not ``pose_source.parent`` is rejected (counted ``pose_rejected_frame_id``). The sample is
        stored as ``A = T_<camera carrier>_<tag carrier>``. Images waiting for this pose are
        processed. Returns True when the sample was stored. Never raises for bad data.
        """
        with self._lock:
            self._count("poses")
            self._rejections.saw("poses")
            if source and source != self.config.pose_source.parent:
                self._count("pose_rejected_frame_id")
                self._rejections.reject(
                    "pose_rejected_frame_id", str(source),
                    f"frame_id {str(source)!r}, configured pose_source.parent "
                    f"{self.config.pose_source.parent!r}")
                return False
            A = self._pose_to_A(T_parent_child)
            if A is None:
                self._count("pose_rejected_invalid")
                return False
            try:
                ok = self._buffer.add(stamp_ns, A)
            except (TypeError, ValueError):
                ok = False
            if not ok:
                self._count("pose_rejected_buffer")
            if self._pending:
                self._process_pending()
            return bool(ok)

    def add_image(
        self,
        camera: str,
        stamp_ns: int,
        gray: np.ndarray,
        T_parent_child: np.ndarray | None = None,
    ) -> ImageOutcome:
        """Detect tags in one image and offer the ``(A, B)`` pairs.

        Parameters
        ----------
        camera : str
            Camera name of the configuration.
        stamp_ns : int
            Image stamp [ns].
        gray : ndarray, shape (H, W), uint8
            Grayscale image of the camera's intrinsics size.
        T_parent_child : ndarray (4, 4), optional
            The pose at exactly this stamp (e.g. a tf lookup); otherwise it is looked up in the
            pose buffer, and detections wait (bounded, ``sync.max_pending_images``) when the
            buffer has no pose after the stamp yet.

        Returns
        -------
        ImageOutcome
            Never raises for bad data; each rejection is counted by reason.
        """
        reasons: list[str] = []

        def reject(reason: str) -> ImageOutcome:
            with self._lock:
                self._count(reason)
            reasons.append(reason)
            return ImageOutcome(camera, safe_int(stamp_ns), "rejected", reasons=reasons)

        with self._lock:
            self._count("images")
            self._rejections.saw("images", str(camera))
            intrinsics = self._intrinsics.get(camera)
        if camera not in self.config.camera_names:
            return reject("image_unknown_camera")
        if intrinsics is None:
            self._log_rejection("image_missing_camera_info", camera,
                                "no CameraInfo had arrived for this camera")
            return reject("image_missing_camera_info")
        stamp = safe_int(stamp_ns)
        if stamp is None:
            return reject("image_bad_stamp")
        img = np.asarray(gray) if isinstance(gray, np.ndarray) else None
        if img is None or img.ndim != 2 or img.dtype != np.uint8:
            return reject("image_not_gray_uint8")
        if img.shape != (intrinsics.height, intrinsics.width):
            self._log_rejection("image_size_mismatch", camera,
                                f"{img.shape[1]}x{img.shape[0]} images, CameraInfo says "
                                f"{intrinsics.width}x{intrinsics.height}")
            return reject("image_size_mismatch")

        try:  # outside the lock: detection is the expensive part
            detection = self._detector().detect(img, intrinsics)
        except Exception as exc:  # noqa: BLE001 - the live path never raises
            return reject(f"image_detector_error:{type(exc).__name__}")

        with self._lock:
            for r in detection.rejections:
                key = (
                    "tag_not_in_config"
                    if r.reason == RejectReason.NOT_IN_CONFIGURATION.value
                    else f"tag_rejected:{r.reason}"
                )
                self._count(key)
                reasons.append(key)
            obs = [o for o in detection.observations if o.tag_id in self._tag_names]
            self._count("tags_detected", len(obs))
            if not obs:
                self._count("images_without_tags")
                return ImageOutcome(camera, stamp, "no_tags", reasons=reasons)
            if T_parent_child is not None:
                A = self._pose_to_A(T_parent_child)
                if A is None:
                    self._count("image_bad_pose")
                    reasons.append("image_bad_pose")
                    return ImageOutcome(camera, stamp, "rejected", len(obs), reasons=reasons)
                kept = self._offer(camera, stamp, A, obs)
            else:
                state, kept, reason = self._resolve(camera, stamp, obs, final=False)
                if state == "wait":
                    if self.config.sync.max_pending_images == 0:
                        state, kept, reason = self._resolve(camera, stamp, obs, final=True)
                    else:
                        if len(self._pending) >= self.config.sync.max_pending_images:
                            self._resolve(*self._pending.popleft(), final=True)
                        self._pending.append((camera, stamp, obs))
                        self._count("images_pending")
                        return ImageOutcome(camera, stamp, "pending", len(obs), reasons=reasons)
                if state == "rejected":
                    reasons.append(reason)
                    return ImageOutcome(camera, stamp, "rejected", len(obs), reasons=reasons)
                return ImageOutcome(camera, stamp, state, len(obs), kept, reasons)
            self._count("images_used" if kept else "images_no_new_pairs")
            return ImageOutcome(
                camera, stamp, "used" if kept else "no_new_pairs", len(obs), kept, reasons
            )

    def _log_rejection(self, reason: str, source: str, text: str) -> None:
        with self._lock:
            self._rejections.reject(reason, source, text)

    def rejections(self) -> list[str]:
        """Data rejected wholesale (at least half of a camera's images or of the poses), in
        words with the numbers, e.g. ``all 599 images of cam0 rejected: 1280x960 images,
        CameraInfo says 640x480`` (:class:`~rwhec_ros.session.rejections.RejectionLog`)."""
        with self._lock:
            return self._rejections.sentences()

    def _resolve(self, camera: str, stamp: int, obs: list, *, final: bool):
        """Pose lookup for one detected image (lock held): ``(state, kept, reason)`` with state
        ``used``/``no_new_pairs``/``rejected``/``wait``.

        An image newer than the newest pose waits (``wait``) for a pose after its stamp, so that
        ``A`` is interpolated rather than held from the previous sample, unless ``final`` (the
        image leaves the pending queue) or the gap already exceeds ``sync.max_gap_s``.
        """
        newest = self._buffer.newest_ns
        status = self._buffer.lookup_status(stamp)
        bracketed = newest is not None and stamp <= newest
        if not final and not bracketed and (status.retry or status is LookupStatus.OK):
            return "wait", 0, ""
        if status is LookupStatus.OK:
            kept = self._offer(camera, stamp, self._buffer.lookup(stamp), obs)
            state = "used" if kept else "no_new_pairs"
            self._count("images_" + state)
            return state, kept, ""
        reason = f"no_pose_at_stamp:{status.value}"
        self._count(reason)
        return "rejected", 0, reason

    def _detector(self) -> TagDetector:
        det = getattr(self._local, "detector", None)
        if det is None:  # one detector per thread: cv2 detector objects are not shared
            det = self._local.detector = TagDetector(self._detector_config)
        return det

    def _offer(self, camera: str, stamp: int, A: np.ndarray, observations: list) -> int:
        """Offer the pairs of one image (lock held); returns the number kept."""
        noise = self.config.noise
        kept = 0
        for o in observations:
            if noise.from_reprojection and o.sigma is not None and o.kappa is not None:
                sigma, kappa = float(o.sigma), float(o.kappa)
            else:
                sigma, kappa = noise.sigma, noise.kappa
            x = self._tag_names[o.tag_id]
            ok = self._acc.offer(x, camera, stamp, A, o.T_cam_tag, sigma, kappa)
            self._count("pairs_offered")
            if ok:
                kept += 1
                if self._tracker is not None:
                    try:
                        self._tracker.add_pair(x, camera, A, o.T_cam_tag, sigma, kappa)
                    except ValueError:
                        self._count("identifiability_rejected_pair")
        self._count("pairs_kept", kept)
        return kept

    def _process_pending(self) -> None:
        """Retry images waiting for a pose (lock held)."""
        still = collections.deque()
        while self._pending:
            camera, stamp, obs = self._pending.popleft()
            if self._resolve(camera, stamp, obs, final=False)[0] == "wait":
                still.append((camera, stamp, obs))
        self._pending = still

    # --- monitoring --------------------------------------------------------------------------
    def counters(self) -> dict[str, int]:
        """Event counts by reason (session, pose buffer ``buffer:*`` and accumulator
        ``pairs:*``)."""
        with self._lock:
            out = dict(self._counters)
            out.update({f"buffer:{k}": v for k, v in self._buffer.counters().items() if v})
            out.update({f"pairs:{k}": v for k, v in self._acc.counters().items() if v})
            out["pending_images"] = len(self._pending)
            return out

    def report(self):
        """The incremental identifiability report (``IdentifiabilityReport``) of the kept pairs
        (per edge, per component; cf. paper Section 6), or None before the first pair."""
        with self._lock:
            return self._tracker_report()

    def _tracker_report(self):
        if self._tracker is None:
            return None
        try:
            return self._tracker.report()
        except ValueError:  # no pairs yet
            return None

    def diagnostics(self) -> list[dict[str, Any]]:
        """One dict per observed edge: ``x``, ``y``, ``pairs``, ``status``, ``identifiable``
        (bool, or None when unknown) and ``reasons`` (list of str)."""
        with self._lock:
            counts = self._acc.counts()
            report = self._tracker_report()
        return edge_rows(counts, report, self.config.solver.min_pairs)

    @property
    def last_outcome(self) -> SolveOutcome | None:
        """The outcome of the latest :meth:`calibrate`."""
        with self._lock:
            return self._last_outcome

    # --- solve -------------------------------------------------------------------------------
    def calibrate(self, output_dir: str | Path | None = None, *,
                  force: bool = False) -> SolveOutcome:
        """Solve with the data so far and write the outputs; never discards data.

        Parameters
        ----------
        output_dir : str or Path, optional
            Write the files exactly into this directory (created if needed; existing files are
            refused unless ``force``). Default: a new timestamped directory under
            ``output.directory``, never reused.
        force : bool
            Overwrite existing files in ``output_dir``.

        Returns
        -------
        SolveOutcome
            ``success=False`` with the reason when there are not enough pairs or the solver
            raised; otherwise the result, a short summary and the written files.
        """
        with self._solve_lock:
            outcome = self._calibrate(output_dir, force)
        with self._lock:
            self._last_outcome = outcome
        return outcome

    def _snapshot(self):
        """Problem, excluded edges, identifiability and data set, copied under the lock."""
        c = self.config
        with self._lock:
            report = self._tracker_report()
            try:
                problem, excluded = self._acc.to_problem(
                    x_names=c.x_names, y_names=c.y_names, unknown_scale=c.tags.unknown_scale,
                    min_pairs=c.solver.min_pairs,
                )
                err = None
            except ValueError as exc:
                problem, excluded, err = None, {}, str(exc)
            dataset = self._dataset_locked()
            counts = self._acc.counts()
        return problem, excluded, err, report, dataset, counts

    def _calibrate(self, output_dir: str | Path | None, force: bool) -> SolveOutcome:
        c = self.config
        problem, excluded, err, report, dataset, counts = self._snapshot()
        ident = report_dict(report)
        excl = {f"({x}, {y})": r for (x, y), r in excluded.items()}
        if problem is None:
            n = sum(counts.values())
            if n == 0:
                why = self.rejections() or [
                    "no tag was detected in an image with a pose at its stamp (see the "
                    "counters)"]
                message = "no measurement pairs: " + "; ".join(why)
            else:
                message = (f"not enough data: {n} pairs on {len(counts)} edges, no edge has "
                           f"solver.min_pairs={c.solver.min_pairs} pairs ({err}); the {n} "
                           "pairs are kept: record more and calibrate again")
            return SolveOutcome(False, message, excluded=excl, identifiability=ident)
        try:
            solved = solve_and_assess(
                problem, mode=c.solver.mode, reject_outliers=c.solver.reject_outliers,
                priors=c.priors.entries, unobservable_std_m=c.solver.unobservable_std_m,
                min_scale=c.solver.min_scale, thresholds=verdict_options(c.verdict),
                expected_x=c.x_names, expected_y=c.y_names, excluded=excl,
                carriers=(c.camera_carrier.frame, c.tag_carrier.frame))
        except Exception as exc:  # noqa: BLE001 - reported to the caller, data kept
            return SolveOutcome(
                False, f"the solver failed ({type(exc).__name__}: {exc}); all data kept: try "
                "again with solver.mode sdp, or with more data",
                excluded=excl, identifiability=ident,
            )
        result, verdict = solved.result, solved.verdict
        excl.update(solved.dropped)
        ident = solved.identifiability_dict or ident
        text = yaml.safe_dump(self.result_document(result, excl, ident, verdict),
                              sort_keys=False)
        try:
            files = self._write_outputs(result, text, dataset, output_dir, force, verdict)
            write_error = ""
        except OSError as exc:
            files, write_error = {}, f"\nWRITING THE OUTPUTS FAILED: {describe_os_error(exc)}"
        message = summary(result, solved.problem, excl, self.config, verdict) + write_error
        return SolveOutcome(True, message, result, excl, files, ident, text, verdict)

    # --- outputs -----------------------------------------------------------------------------
    def published_transforms(self, result: CalibrationResult, verdict: Verdict | None = None
                             ) -> list[tuple[str, str, np.ndarray]]:
        """``(parent, child, T_parent_child)`` for every estimated frame of ``result`` that may be
        published: with a ``verdict``, only its usable frames unless
        ``output.publish_unusable`` (see :meth:`left_out`)."""
        return self._publishable(result, verdict)[0]

    def left_out(self, result: CalibrationResult, verdict: Verdict | None) -> dict[str, str]:
        """Frames of ``result`` not published because the ``verdict`` finds them unusable, and
        why (empty with ``output.publish_unusable``)."""
        return self._publishable(result, verdict)[1]

    def _publishable(self, result: CalibrationResult, verdict: Verdict | None):
        names = list(result.y_names) + list(result.x_names)
        return publishable(FrameNaming.from_config(self.config).transforms(result), names,
                           verdict, publish_unusable=self.config.output.publish_unusable)

    def result_document(
        self,
        result: CalibrationResult,
        excluded: dict[str, str] | None = None,
        identifiability: dict | None = None,
        verdict: Verdict | None = None,
    ) -> dict[str, Any]:
        """The result YAML as a mapping (:func:`rwhec_ros.data.results.result_document`:
        ``certified``, ``suboptimality_bound``, ``scale``, ``frames`` with published
        ``parent``/``child``, ``timing_s``, ``identifiability``, ``excluded_edges``, ``config``)
        plus this session's ``counters``."""
        doc = result_document(result, FrameNaming.from_config(self.config), excluded=excluded,
                              identifiability=identifiability,
                              config=self.config.to_parameters(), source={"type": "session"},
                              verdict=verdict)
        doc["counters"] = plain(self.counters())
        return doc

    def _output_dir(self, kind: str) -> Path:
        """A new directory ``<output.directory>/<kind>_<UTC stamp>[_n]`` (never reused)."""
        return new_output_dir(self.config.output.directory, kind, now=self._now())

    def _write_outputs(self, result: CalibrationResult, text: str, dataset,
                       output_dir: str | Path | None = None, force: bool = False,
                       verdict: Verdict | None = None) -> dict[str, str]:
        if output_dir is None:
            out = self._output_dir("calibration")
            created = out.name.split("_", 1)[1]
        else:
            out, created = Path(output_dir), utc_stamp(self._now())
        transforms, left_out = self._publishable(result, verdict)
        return write_session_outputs(out, transforms, result, text, dataset, created=created,
                                     force=force, verdict=verdict, left_out=left_out)

    def _dataset_locked(self):
        """A data-set object of the kept pairs (lock held), or None if unavailable."""
        return session_dataset(self._acc, self.config)

    def save_dataset(self, path: str | Path | None = None) -> str:
        """Save the kept pairs (format of :mod:`rwhec_ros.data.dataset`) and return the path.

        Default path: a new timestamped directory under ``output.directory``. Raises
        ``ValueError`` when there is nothing to save or the data-set module is unavailable.
        """
        with self._lock:
            dataset = self._dataset_locked()
            n = sum(self._acc.counts().values())
        if dataset is None or n == 0:
            raise ValueError(f"save_dataset: nothing to save ({n} pairs)")
        target = Path(path) if path is not None else self._output_dir("dataset") / "dataset.yaml"
        saved = dataset.save(target)
        return str(saved if saved is not None else target)

    def reset(self) -> None:
        """Forget poses, pairs, pending images and counters (intrinsics are kept)."""
        with self._lock:
            self._init_data()



def safe_int(value: Any) -> int | None:
    try:
        if isinstance(value, bool):
            return None
        out = int(value)
        return out if out == value else None
    except (TypeError, ValueError, OverflowError):
        return None


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

from ..config import CalibratorConfig
from ..config.live_parameters import restart_only_differences
from ..core.lie import invert_transform
from ..core.result import CalibrationResult
from ..core.verdict import Verdict
from ..data.corners import corner_data
from ..data.fingerprint import dataset_fingerprint
from ..data.results import (
    FrameNaming,
    dump_document,
    new_output_dir,
    plain,
    result_document,
    utc_stamp,
)
from ..errors import describe_os_error
from ..sync.accumulator import PairAccumulator
from ..sync.board_turns import turn_document, turn_lines
from ..sync.buffer import PoseBuffer
from ..sync.pose_track import PoseTrack, track_window_ns
from ..sync.pose_wait import PoseLatency
from ..vision.intrinsics import CameraIntrinsics
from .accuracy import AccuracyOptions
from .capture import CaptureGate, CaptureMixin
from .image_input import CAMERA_COUNTERS, LOOK_BACK_IMAGES, ImageInput, detector_config
from .live_solve import LiveSolver, PairsSnapshot
from .outcomes import SolveOutcome, edge_rows, no_pairs_words, too_few_pairs_words
from .outputs import publishable, session_dataset, summary, write_session_outputs
from .paths import plain_output_root
from .rejections import RejectionLog
from .second_look import SecondLookMixin, new_held_views, second_look_lines
from .solving import config_noise, make_tracker, report_dict, solve_and_assess, verdict_options
from .time_offsets import add_offset_reasons, correct_time_offsets, offsets_then_assess

__all__ = ["CalibrationSession"]

_NS_PER_S = 1_000_000_000
#: Poses per camera whose corner noise scales the reprojection gate (the median of the latest).
NOISE_HISTORY = 64


class CalibrationSession(SecondLookMixin, ImageInput, CaptureMixin):
    """Accumulate synchronised measurement pairs live and calibrate on request.

    Images go in through :meth:`add_image` (:class:`~rwhec_ros.session.image_input.ImageInput`:
    pose, motion gate, tags, pairs), poses through :meth:`add_pose`; :meth:`capture` takes a
    view now (:class:`~rwhec_ros.session.capture.CaptureMixin`, ``capture.mode``).

    Parameters
    ----------
    config : CalibratorConfig
        Validated configuration (:func:`rwhec_ros.config.load_config` or
        :meth:`CalibratorConfig.from_parameters`).
    now : callable returning datetime, optional
        Clock for the timestamped output names (default: current UTC time); injectable for tests.
    output_root : str or Path, optional
        Directory under which :meth:`calibrate` and :meth:`save_dataset` create their output
        directories (the node passes :func:`~rwhec_ros.session.paths.node_output_root`);
        default :func:`~rwhec_ros.session.paths.plain_output_root` of ``output.directory``.
    live_solve : callable, optional
        The live re-solve of :attr:`live` (default
        :func:`~rwhec_ros.session.live_solve.solve_with_uncertainty`); injectable for tests.
    clock : callable returning int, optional
        The time [ns] on the clock of the stamps (the node: its ROS clock), for the images
        waiting for their pose (:mod:`rwhec_ros.session.image_wait`); default: the newest stamp
        received.

    Attributes
    ----------
    live : LiveSolver
        The background re-solve and convergence verdict (:mod:`rwhec_ros.session.live_solve`);
        driven by its ``tick()`` (the node's timer, the bag replay), stopped by :meth:`close`.

    Notes
    -----
    Frame names: Y variables are the camera names of the configuration, X variables the tag frame
    names ``<tags.frame_prefix><id>`` and the named targets (``targets.names``: boards); results
    are published as ``(parent, child)`` from
    :meth:`CalibratorConfig.published_frames`.
    """

    def __init__(
        self,
        config: CalibratorConfig,
        *,
        now: Callable[[], _dt.datetime] | None = None,
        output_root: str | Path | None = None,
        live_solve: Callable | None = None,
        clock: Callable[[], int] | None = None,
    ) -> None:
        self.config = config
        self._clock = clock
        self.output_root = (Path(output_root) if output_root is not None
                            else plain_output_root(config.output.directory))
        self._now = now if now is not None else (lambda: _dt.datetime.now(_dt.timezone.utc))
        self._lock = threading.Lock()
        self._solve_lock = threading.Lock()
        self._local = threading.local()
        self._detector_config = detector_config(config)
        self._target_specs = config.target_specs()
        self._x_names = config.x_names
        self._intrinsics: dict[str, CameraIntrinsics] = {}
        self._last_outcome: SolveOutcome | None = None
        self._capture = CaptureGate()  # capture.mode and ~/capture (rwhec_ros.session.capture)
        self._saved_sha = ""  # fingerprint of the pairs last written (unsaved_pairs)
        # never reset: the live solver compares them across resets
        self._data_version = 0
        self._calibrations = 0
        self._resets = 0
        self._init_data()
        self.live = LiveSolver(self, solve_fn=live_solve)

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
            max_edges=max(1, len(c.cameras) * len(c.x_names)),
            board_corners=max((t.board.n_corners for t in self._target_specs
                               if t.board is not None), default=0),
            turnable=[t.name for t in self._target_specs if t.turn_symmetric],
        )
        self._tracker = make_tracker(c.tags.unknown_scale)
        # the pose stream around the kept pairs, for time offsets (rwhec_ros.sync.pose_track)
        self._track = PoseTrack(track_window_ns(c.sync.time_offset_range_s),
                                self._buffer.max_gap_ns, recent=c.sync.pose_buffer_size)
        self._pending: collections.deque = collections.deque()
        self._pending_bytes = 0
        self._latency = PoseLatency()  # the pose stream's ages (image_wait)
        self._proxy_now = 0  # the clock without one: the newest stamp received
        self._no_pose: dict[str, collections.Counter] = {}  # camera -> cause -> images
        self._views: dict = {}  # camera -> (A, targets found) of its last searched image
        # the motion gate's remembered verdicts (image_input.gate_would_skip), valid while the
        # camera's epoch is unchanged: (camera, stamp) -> (epoch, skip, A at the stamp)
        self._gate_memo: dict = {}
        self._gate_epochs = collections.Counter()
        # camera -> (stamp, A, image, intrinsics) the gate skipped since its last search
        self._skipped_since_search = collections.defaultdict(
            lambda: collections.deque(maxlen=LOOK_BACK_IMAGES))
        self._held_views = new_held_views()  # camera -> images for the second look
        # camera -> corner noise [px] of its latest poses (the scaled reprojection gate)
        self._corner_noise = collections.defaultdict(
            lambda: collections.deque(maxlen=NOISE_HISTORY))
        self._counters: collections.Counter = collections.Counter()
        self._camera_counts = {name: collections.Counter(dict.fromkeys(CAMERA_COUNTERS, 0))
                               for name in c.camera_names}
        self._rejections = RejectionLog()

    def update_config(self, config: CalibratorConfig, *,
                      output_root: str | Path | None = None) -> None:
        """Use ``config`` from now on; it may differ from the current one in live parameters only
        (:mod:`rwhec_ros.config.live_parameters`), else ``ValueError`` naming them.

        ``solver.*`` and ``output.*`` are read at the next :meth:`calibrate` (``solver.
        live_period_s`` at the next live tick); new ``convergence.*`` limits make the next live
        tick re-solve; new ``noise.sigma``
        and ``noise.kappa`` go at once to every kept pair (unless ``noise.from_reprojection``)
        and the identifiability tracker is rebuilt with them; new keyframe thresholds apply to
        the pairs offered from now on. ``output_root`` replaces the output root (default: the
        plain-Python root of the new ``output.directory`` if it changed).
        """
        fixed = restart_only_differences(self.config, config)
        if fixed:
            raise ValueError(f"{fixed[0]}: cannot change in a running session "
                             f"(restart-only parameters changed: {fixed})")
        with self._lock:
            old, self.config = self.config, config
            if output_root is not None:
                self.output_root = Path(output_root)
            elif old.output.directory != config.output.directory:
                self.output_root = plain_output_root(config.output.directory)
            if old.convergence != config.convergence:
                self._data_version += 1  # the live re-solve judges again with the new limits
            self._gate_memo.clear()  # new keyframe thresholds or gate settings
            self._acc.keyframe_rotation_rad = config.keyframe.min_rotation_rad
            self._acc.keyframe_translation_m = config.keyframe.min_translation_m
            noise = config.noise
            if (noise.estimate, noise.groups) != (old.noise.estimate, old.noise.groups):
                self._data_version += 1  # the live re-solve estimates (or not) again
            if not noise.from_reprojection and (noise.sigma, noise.kappa) != (
                    old.noise.sigma, old.noise.kappa):
                self._acc.set_precisions(noise.sigma_start, noise.kappa_start)
                self._data_version += 1
                self._tracker = make_tracker(config.tags.unknown_scale)
                for e in self._acc.edges().values():
                    try:
                        self._tracker.add_pairs(e.x, e.y, e.A, e.B, e.sigma, e.kappa)
                    except ValueError:
                        self._count("identifiability_rejected_pair", e.n)

    def _count(self, key: str, n: int = 1) -> None:
        self._counters[key] += n

    def record(self, reason: str, n: int = 1) -> None:
        """Count an event seen outside the session (``"bad_image_message"``); thread-safe."""
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
        processed (gated, decoded and searched here, outside the lock). Returns True when the
        sample was stored. Never raises for bad data.
        """
        ok = self._store_pose(stamp_ns, T_parent_child, source)
        self._serve_pending()
        return ok

    def add_stream_pose(self, stamp_ns: int, T_parent_child: np.ndarray) -> bool:
        """A pose-stream sample kept for the time offsets only (``bag`` with a tf pose source:
        its chain at its links' stamps); images still take their pose as given."""
        with self._lock:
            A = self._pose_to_A(T_parent_child)
            if A is not None:
                self._track.add(int(stamp_ns), A)
            return A is not None

    def _store_pose(self, stamp_ns: int, T_parent_child: Any, source: str | None) -> bool:
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
            resets = self._buffer.resets
            try:
                ok = self._buffer.add(stamp_ns, A)
            except (TypeError, ValueError):
                ok = False
            if not ok:
                self._count("pose_rejected_buffer")
            else:
                self._track.add(int(stamp_ns), A)
            if ok or resets != self._buffer.resets:
                self._note_pose(int(stamp_ns), bool(ok), resets)
            return bool(ok)

    def rejections(self) -> list[str]:
        """Data rejected wholesale (at least half of a camera's images or of the poses), in
        words with the numbers, e.g. ``all 599 images of cam0 rejected: 1280x960 images,
        CameraInfo says 640x480`` (:class:`~rwhec_ros.session.rejections.RejectionLog`)."""
        with self._lock:
            return self._rejections.sentences()

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
                  force: bool = False,
                  on_phase: Callable[[str], None] | None = None) -> SolveOutcome:
        """Solve with the data so far and write the outputs; never discards data.

        Never waits for a live re-solve (:attr:`live`); one that overlaps it is dropped.

        Parameters
        ----------
        output_dir : str or Path, optional
            Write the files exactly into this directory (created if needed; existing files are
            refused unless ``force``). Default: a new timestamped directory under
            ``output.directory``, never reused.
        force : bool
            Overwrite existing files in ``output_dir``.
        on_phase : callable, optional
            Called with ``"analysing"`` once the solver returned and ``"writing"`` before the
            files are written (the CLI's progress and interrupt messages).

        Returns
        -------
        SolveOutcome
            ``success=False`` with the reason when there are not enough pairs or the solver
            raised; otherwise the result, a short summary and the written files.
        """
        with self._solve_lock:
            with self._lock:
                self._calibrations += 1
            outcome = self._calibrate(output_dir, force, on_phase)
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
            counts, turns = self._acc.counts(), self._acc.turn_report()
        return problem, excluded, err, report, dataset, counts, turns

    def _calibrate(self, output_dir: str | Path | None, force: bool,
                   on_phase: Callable[[str], None] | None = None,
                   looked: tuple[int, int] | None = None) -> SolveOutcome:
        from .solving import solver_alternatives
        c = self.config
        problem, excluded, err, report, dataset, counts, turns = self._snapshot()
        ident = report_dict(report)
        excl = {f"({x}, {y})": r for (x, y), r in excluded.items()}
        if problem is None:
            n = sum(counts.values())
            if n == 0:
                searched = sum(v.get("detected", 0) for v in self.camera_counters().values())
                message = no_pairs_words(self.counters(), searched, c, self.rejections())
            else:
                message = too_few_pairs_words(counts, c.solver.min_pairs, "solver.min_pairs") \
                    + f"; the {n} pairs are kept" + "".join(f"\n{t}" for t in turn_lines(turns))
            return SolveOutcome(False, message, excluded=excl, identifiability=ident)
        def estimate(p, d):
            return correct_time_offsets(
                p, d, c, mode=c.solver.mode, priors=c.priors.entries,
                unobservable_std_m=c.solver.unobservable_std_m, min_scale=c.solver.min_scale,
                reject_outliers=c.solver.reject_outliers, noise=config_noise(c))

        def assess(p, d):
            return solve_and_assess(
                p, mode=c.solver.mode, reject_outliers=c.solver.reject_outliers,
                priors=c.priors.entries, unobservable_std_m=c.solver.unobservable_std_m,
                min_scale=c.solver.min_scale, sdp_backend=c.solver.sdp_backend,
                thresholds=verdict_options(c.verdict),
                expected_x=c.x_names, expected_y=c.y_names, excluded=excl,
                carriers=(c.camera_carrier.frame, c.tag_carrier.frame),
                accuracy=AccuracyOptions.from_config(c), corners=corner_data(d),
                noise=config_noise(c), on_phase=on_phase, refine=c.solver.refine)
        try:
            problem, dataset, offsets, solved = offsets_then_assess(problem, dataset, estimate,
                                                                    assess)
        except Exception as exc:  # noqa: BLE001 - reported to the caller, data kept
            return SolveOutcome(
                False, f"the solver stopped with an error in mode {c.solver.mode} "
                f"({type(exc).__name__}: {str(exc).split('. ')[0]}); all data kept: "
                + solver_alternatives(c.solver.mode, c.solver.reject_outliers,
                                      "solver.mode", "solver.reject_outliers"),
                excluded=excl, identifiability=ident,
            )
        result, verdict = solved.result, solved.verdict
        if looked is None and verdict.level != "unusable" and self.held_views():
            looked = self.second_look(result)  # (module second_look) then solve with them
            if looked[1]:
                return self._calibrate(output_dir, force, on_phase, looked)
        add_offset_reasons(verdict, offsets)
        excl.update(solved.dropped)
        ident = solved.identifiability_dict or ident
        doc = self.result_document(
            result, excl, ident, verdict, solved.accuracy, solved.rejected_pairs,
            fingerprint=None if dataset is None else dataset_fingerprint(dataset))
        doc = offsets.into(doc)
        text = dump_document({**doc, "board_turns": turn_document(turns)} if turns else doc)
        if on_phase is not None:
            on_phase("writing")
        try:
            files = self._write_outputs(result, text, dataset, output_dir, force, verdict)
            write_error = ""
            if dataset is not None and "dataset" in files:
                self._saved_sha = dataset_fingerprint(dataset)["sha256"]
        except OSError as exc:
            files, write_error = {}, describe_os_error(exc)
        message = "\n".join([summary(result, solved.problem, excl, self.config, verdict,
                                      solved.accuracy), *offsets.lines(),
                             *turn_lines(turns), *second_look_lines(looked)]) + (
            f"\nWRITING THE OUTPUTS FAILED: {write_error}" if write_error else "")
        return SolveOutcome(True, message, result, excl, files, ident, text, verdict,
                            solved.accuracy, write_error, time_offsets=offsets)

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
        accuracy=None,
        rejected_pairs: dict[str, list[int]] | None = None,
        fingerprint: dict[str, Any] | None = None,
    ) -> dict[str, Any]:
        """The result YAML as a mapping (:func:`rwhec_ros.data.results.result_document`:
        ``certified``, ``suboptimality_bound``, ``scale``, ``frames`` with published
        ``parent``/``child``, ``timing_s``, ``identifiability``, ``excluded_edges``,
        ``rejected_pairs``, ``config``)
        plus this session's ``counters``; with an ``accuracy``
        (:class:`~rwhec_ros.session.accuracy.Accuracy`) the uncertainty, cross-validation and
        guidance keys."""
        doc = result_document(result, FrameNaming.from_config(self.config), excluded=excluded,
                              identifiability=identifiability,
                              config=self.config.to_parameters(), source={"type": "session"},
                              verdict=verdict, accuracy=accuracy,
                              rejected_pairs=rejected_pairs, fingerprint=fingerprint)
        doc["counters"] = plain(self.counters())
        return doc

    def _output_dir(self, kind: str) -> Path:
        """A new directory ``<output root>/<kind>_<UTC stamp>[_n]`` (never reused)."""
        return new_output_dir(self.output_root, kind, now=self._now())

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
        return session_dataset(self._acc, self.config, self._intrinsics,
                               pose_stream=self._track.data())

    def save_dataset(self, path: str | Path | None = None) -> str:
        """Save the kept pairs (format of :mod:`rwhec_ros.data.dataset`) and return the path.

        Default path: a new timestamped directory under :attr:`output_root`. Raises
        ``ValueError`` when there is nothing to save or the data-set module is unavailable.
        """
        with self._lock:
            dataset = self._dataset_locked()
            n = sum(self._acc.counts().values())
        if dataset is None or n == 0:
            raise ValueError(f"save_dataset: nothing to save ({n} pairs)")
        target = Path(path) if path is not None else self._output_dir("dataset") / "dataset.yaml"
        saved = dataset.save(target)
        self._saved_sha = dataset_fingerprint(dataset)["sha256"]
        return str(saved if saved is not None else target)

    def dataset(self):
        """The kept pairs as a :class:`~rwhec_ros.data.dataset.Dataset` (a copy), or None
        when there is none."""
        with self._lock:
            if not sum(self._acc.counts().values()):
                return None
            return self._dataset_locked()

    def unsaved_pairs(self) -> int:
        """How many pairs the session holds that no :meth:`save_dataset` or :meth:`calibrate`
        wrote (all of them when the kept pairs changed since the last write; 0 when they are
        the pairs last written, or when there are none)."""
        dataset = self.dataset()
        if dataset is None or dataset_fingerprint(dataset)["sha256"] == self._saved_sha:
            return 0
        return dataset.n_pairs

    def reset(self) -> None:
        """Forget poses, pairs, pending images, counters and the live estimate (intrinsics are
        kept)."""
        with self._lock:
            self._init_data()
            self._capture.forget()
            self._data_version += 1
            self._resets += 1
        self.live.forget()

    def close(self, timeout: float | None = 1.0) -> None:
        """Stop the live re-solve's worker thread, waiting up to ``timeout`` s for a running
        re-solve (a daemon thread: it never keeps the process alive); the data stay and
        :meth:`calibrate` still works."""
        self.live.stop(timeout)

    # --- live re-solve (rwhec_ros.session.live_solve) ----------------------------------------
    def pairs_snapshot(self) -> PairsSnapshot:
        """The kept pairs per edge and the data version, taken under the lock (read-only views
        or copies of the arrays that never change afterwards,
        :meth:`~rwhec_ros.sync.accumulator.PairAccumulator.kept_pairs`: build the problem
        outside, :func:`~rwhec_ros.sync.accumulator.problem_from_edges`)."""
        with self._lock:
            return PairsSnapshot(self._data_version, self._acc.kept_pairs(),
                                 self._acc.rotation_tol, self._track.data())

    def live_counts(self) -> tuple[int, int, int, bool]:
        """``(data version, calibrations, resets, calibrate running)``: is a re-solve due?"""
        with self._lock:
            return (self._data_version, self._calibrations, self._resets,
                    self._solve_lock.locked())

"""The ROS-free live calibration session: poses and images in, certified extrinsics out.

:class:`CalibrationSession` is a thin layer over the pipeline: the pose stream goes into a
:class:`~rwhec_ros.sync.buffer.PoseBuffer` (as ``A = T_<camera carrier>_<tag carrier>``, inverted
from ``T_parent_child`` where the configuration says so); each image is searched for the
targets, single tags and boards (:class:`~rwhec_ros.vision.target_detector.TargetDetector`,
``B = T_cam_target``, one per target), ``A`` is looked up at the
image stamp, and every ``(A, B)`` pair is offered to a
:class:`~rwhec_ros.sync.accumulator.PairAccumulator` whose kept pairs feed an incremental
:class:`~rwhec_ros.core.identifiability.IdentifiabilityTracker`.
:meth:`CalibrationSession.calibrate` solves the paper's MLE (``A_i X_j = Y_k B_i``, eq. (7))
with :func:`rwhec_ros.core.solve.solve` and writes the result YAML, the data set and a
static-transform launch file.

Live-path promise: :meth:`~CalibrationSession.add_pose` and :meth:`~CalibrationSession.add_image`
never raise for bad data (missing intrinsics, wrong image size, unknown tags, no pose at the
stamp, ...): every rejection is counted by reason (:meth:`~CalibrationSession.counters`).

Threading: the ROS node calls ``add_pose``/``add_image`` from worker threads and ``calibrate``
from a service thread. Shared state is protected by one lock that is never held during tag
detection or the solve (the data are copied under the lock, then processed).
:class:`FairImageQueue` and :class:`QueueWorker` move detection off the caller's thread: one
bounded queue per camera, served round-robin, one image per camera at a time (the motion gate of
:mod:`.image_input` needs a camera's images in order); both are plain Python and testable
without ROS.

Modules: :mod:`.live` (:class:`CalibrationSession`), :mod:`.image_input` (its image path: pose,
motion gate, lazy decoding, tags, pairs), :mod:`.outcomes` (what it answers), :mod:`.solving`
(the solve step shared with the CLI, identifiability at the solution and the verdict,
:func:`~rwhec_ros.core.verdict.assess`), :mod:`.outputs` (summary, launch file, what is published,
data set and output files), :mod:`.rejections` (data rejected wholesale, in words),
:mod:`.info_wait` (images held for their camera's first CameraInfo), :mod:`.image_queue`
(:class:`ImageQueue`, :class:`FairImageQueue`, :class:`QueueWorker`), :mod:`.camera_monitor`
(transport loss from the stamps' spacing, per-camera ``/diagnostics`` rows), :mod:`.replay`
(recorded messages into a session on several threads, for ``rwhec-calibrate bag``),
:mod:`.live_solve` (:class:`~rwhec_ros.session.live_solve.LiveSolver`, the session's ``live``:
background re-solves while data arrive, off the sensor path and never blocking ``calibrate``),
:mod:`.convergence` (its convergence verdict and the ``~/estimate`` document),
:mod:`.capture` (``capture.mode`` and the ``~/capture`` service's view at rest),
:mod:`.paths` (the output root), :mod:`.responses` (the service answers) and :mod:`.handlers`
(:class:`MessageHandlers`: one ROS message, rclpy's or rosbags', into the session).
"""

from .handlers import MessageHandlers
from .image_queue import FairImageQueue, ImageQueue, QueueWorker
from .live import CalibrationSession
from .outcomes import ImageOutcome, SolveOutcome
from .outputs import static_transforms_launch, summary
from .solving import solve_problem

__all__ = [
    "ImageOutcome",
    "SolveOutcome",
    "CalibrationSession",
    "ImageQueue",
    "FairImageQueue",
    "QueueWorker",
    "MessageHandlers",
    "static_transforms_launch",
    "solve_problem",
    "summary",
]

"""The typed sections of the calibrator configuration (one frozen dataclass per section)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = [
    "CarrierConfig",
    "PoseSourceConfig",
    "CameraConfig",
    "TagsConfig",
    "TargetsConfig",
    "NoiseConfig",
    "SyncConfig",
    "KeyframeConfig",
    "DetectionConfig",
    "SolverConfig",
    "ConvergenceConfig",
    "OutputConfig",
    "RosConfig",
    "AccuracyConfig",
    "CaptureConfig",
]


@dataclass(frozen=True)
class CarrierConfig:
    """A frame that carries the cameras or the tags; ``moving`` relative to the other carrier."""

    frame: str
    moving: bool


@dataclass(frozen=True)
class PoseSourceConfig:
    """Where ``T_parent_child`` comes from: a PoseStamped ``topic`` or a ``tf`` lookup.

    ``invert`` is derived: ``A = T_parent_child`` if ``parent`` is the camera carrier (False),
    ``A = T_parent_child^-1`` if it is the tag carrier (True).
    """

    type: str
    topic: str
    parent: str
    child: str
    invert: bool


@dataclass(frozen=True)
class CameraConfig:
    """One camera (a Y variable): topics, optical frame and published frame name.

    ``image_transport`` is ``"raw"`` (``sensor_msgs/Image`` on ``image_topic``) or
    ``"compressed"`` (``sensor_msgs/CompressedImage`` on :attr:`subscribed_topic`).
    """

    name: str
    image_topic: str
    camera_info_topic: str
    frame: str
    calibrated_frame: str
    image_transport: str = "raw"

    @property
    def subscribed_topic(self) -> str:
        """The topic the images come on: ``image_topic``, or ``<image_topic>/compressed`` with
        ``image_transport: compressed`` (``image_transport``'s naming)."""
        if self.image_transport == "compressed":
            return self.image_topic + "/compressed"
        return self.image_topic


@dataclass(frozen=True)
class TagsConfig:
    """The AprilTags (X variables). ``sizes`` maps every id in ``ids`` to its edge length [m]."""

    family: str
    ids: tuple[int, ...]
    sizes: dict[int, float]
    default_size: float | None
    frame_prefix: str
    unknown_scale: bool

    def frame_name(self, tag_id: int) -> str:
        """Name of tag ``tag_id``'s frame, ``<frame_prefix><id>`` (the X-variable name)."""
        return f"{self.frame_prefix}{int(tag_id)}"


@dataclass(frozen=True)
class TargetsConfig:
    """The named targets (``targets.names``, :mod:`rwhec_ros.config.targets`): boards and
    single tags with their own frame names, as
    :class:`~rwhec_ros.vision.targets.TargetSpec` (``name`` = frame = X variable)."""

    specs: tuple[Any, ...] = ()

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(t.name for t in self.specs)


@dataclass(frozen=True)
class NoiseConfig:
    """Measurement precisions of ``B`` (paper eq. (14), (16)); ``from_reprojection`` overrides."""

    sigma: float
    kappa: float
    from_reprojection: bool


@dataclass(frozen=True)
class SyncConfig:
    """Pose/image time matching. Seconds here; the session converts to integer nanoseconds.

    ``image_queue_size`` counts per camera; ``detection_threads`` is an integer or ``"auto"``
    (see :meth:`rwhec_ros.config.CalibratorConfig.detection_thread_count`); an image waits for
    the pose at its stamp at most ``max_pose_wait_s``, the waiting images of one holder take at
    most ``max_waiting_mb`` megabytes (:mod:`rwhec_ros.sync.pose_wait`). ``at_rest_*``: the
    stop-and-go rule of :mod:`rwhec_ros.sync.at_rest`.
    """

    max_gap_s: float
    extrapolation_tolerance_s: float
    pose_buffer_size: int
    image_queue_size: int
    detection_threads: int | str
    tf_timeout_s: float
    at_rest_max_gap_s: float = 2.0
    at_rest_translation_m: float = 0.0005
    at_rest_rotation_rad: float = 0.001
    max_pose_wait_s: float = 1.0
    max_waiting_mb: float = 256.0


@dataclass(frozen=True)
class KeyframeConfig:
    """Thresholds for keeping a new measurement pair on an edge."""

    min_rotation_rad: float
    min_translation_m: float
    max_pairs_per_edge: int


@dataclass(frozen=True)
class DetectionConfig:
    """Gates of the tag detector (:class:`rwhec_ros.vision.detection.DetectorConfig`), its
    decimation (an integer or ``"auto"``) and the motion gate of the live session."""

    corner_refinement: str
    max_reprojection_rms_px: float
    min_side_px: float
    max_obliquity_deg: float
    decimate: int | str = "auto"
    motion_gate: bool = True
    discovery_step: float = 0.5
    reprojection_gate_factor: float = 4.0
    chessboard_refinement: str = "sb"


@dataclass(frozen=True)
class SolverConfig:
    """Solver mode (``fast``/``sdp``/``local``), minimum pairs per edge, outlier switch, and
    when a translation direction or the scale counts as not determined by the data."""

    mode: str
    min_pairs: int
    reject_outliers: bool
    unobservable_std_m: float = 1.0
    min_scale: float = 0.01
    live_period_s: float = 2.0
    sdp_backend: str = "auto"
    refine: bool = True


@dataclass(frozen=True)
class ConvergenceConfig:
    """When the live estimate (:mod:`rwhec_ros.session.live_solve`) counts as converged: every
    configured frame estimated and its standard deviations at or below these (translation [m]
    per axis, rotation [deg] per axis; the larger of predicted and a posteriori)."""

    max_std_translation_m: float = 0.005
    max_std_rotation_deg: float = 0.25


@dataclass(frozen=True)
class PriorsConfig:
    """Known translation components ``(frame, axis, value_m)`` that fix unobservable directions
    (:class:`rwhec_ros.core.model.gauge.TranslationPrior`; the axis is of the frame's carrier)."""

    entries: tuple[tuple[str, str, float], ...] = ()


@dataclass(frozen=True)
class OutputConfig:
    """Output directory (as configured: the front end resolves it, see
    :mod:`rwhec_ros.session.paths`) and publication settings."""

    directory: str
    frame_suffix: str
    publish_tf: bool
    publish_uncertified: bool
    publish_unusable: bool = False


@dataclass(frozen=True)
class RosConfig:
    """Settings only the node uses (ignored by the CLI)."""

    image_qos: str
    diagnostics_period_s: float
    image_queue_depth: int = 5
    detections_rate_hz: float = 2.0


@dataclass(frozen=True)
class AccuracyConfig:
    """What the calibrate step computes besides the per-frame uncertainty (always): the k-fold
    cross-validation (``cross_validation_folds``, 0 for none) and the next-motion guidance
    (:mod:`rwhec_ros.session.accuracy`)."""

    cross_validation_folds: int = 5
    guidance: bool = True


@dataclass(frozen=True)
class CaptureConfig:
    """Which images become candidate views (:mod:`rwhec_ros.session.capture`): ``mode``
    ``"continuous"``, ``"capture"`` or ``"both"``; a capture takes each camera's next image
    whose pose has been at rest for ``rest_s`` and answers after at most ``timeout_s``."""

    mode: str = "continuous"
    rest_s: float = 0.5
    timeout_s: float = 10.0


@dataclass(frozen=True)
class CheckConfig:
    """The bring-up check (:mod:`rwhec_ros.session.bringup`, the node's ``~/check``): the
    ``reference`` (a file, ``"tf"`` or ``""``), the tolerance, the false-alarm rate, the gauge
    (``hold``), the test's ``noise``, where frames are looked up (``tf_frames``) and the node's
    checking period (``period_s``, 0: only on ``~/check``)."""

    reference: str = ""
    tolerance_translation_m: float = 0.002
    tolerance_rotation_deg: float = 0.2
    false_alarm_rate: float = 0.01
    hold: str = "none"
    noise: str = "data"
    tf_frames: str = "calibrated"
    period_s: float = 0.0

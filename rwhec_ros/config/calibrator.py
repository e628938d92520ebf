"""The validated calibrator configuration, :class:`CalibratorConfig` (node and CLI alike), and how
its typed sections are built from checked parameter values (:func:`build_sections`)."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import yaml

from ..vision.detector_config import CHESSBOARD_REFINEMENTS
from .sections import (
    AccuracyConfig,
    CameraConfig,
    CaptureConfig,
    CarrierConfig,
    CheckConfig,
    ConvergenceConfig,
    DetectionConfig,
    KeyframeConfig,
    NoiseConfig,
    OutputConfig,
    PoseSourceConfig,
    PriorsConfig,
    RosConfig,
    SolverConfig,
    SyncConfig,
    TagsConfig,
    TargetsConfig,
)
from .specs import (
    CAPTURE_MODES,
    CHECK_HOLDS,
    CHECK_NOISE,
    GLOBAL_SPECS,
    IMAGE_QOS,
    IMAGE_TRANSPORTS,
    NOISE_GROUPS,
    POSE_SOURCE_TYPES,
    SDP_BACKENDS,
    SOLVER_MODES,
)
from .targets import build_targets
from .validation import (
    check_choice,
    check_frame,
    check_int_or_auto,
    check_positive,
    check_positive_int,
    check_topic,
    typed_parameters,
)

__all__ = ["CalibratorConfig", "build_sections"]


@dataclass(frozen=True)
class CalibratorConfig:
    """The validated calibrator configuration (file format: :mod:`rwhec_ros.config`).

    Build it with :meth:`from_parameters` (flat dotted names -> values) or :func:`load_config`.
    ``verdict`` holds the ``verdict.*`` thresholds by their short names (the fields of
    :class:`rwhec_ros.core.verdict.VerdictOptions`).
    """

    camera_carrier: CarrierConfig
    tag_carrier: CarrierConfig
    pose_source: PoseSourceConfig
    cameras: tuple[CameraConfig, ...]
    tags: TagsConfig
    noise: NoiseConfig
    sync: SyncConfig
    keyframe: KeyframeConfig
    detection: DetectionConfig
    solver: SolverConfig
    output: OutputConfig
    ros: RosConfig
    verdict: dict[str, Any] = field(default_factory=dict, compare=False)
    parameters: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)
    priors: PriorsConfig = field(default_factory=PriorsConfig)
    accuracy: AccuracyConfig = field(default_factory=AccuracyConfig)
    convergence: ConvergenceConfig = field(default_factory=ConvergenceConfig)
    targets: TargetsConfig = field(default_factory=TargetsConfig)
    capture: CaptureConfig = field(default_factory=CaptureConfig)
    check: CheckConfig = field(default_factory=CheckConfig)

    # --- names ------------------------------------------------------------------------------
    @property
    def camera_names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.cameras)

    def camera(self, name: str) -> CameraConfig:
        for c in self.cameras:
            if c.name == name:
                return c
        raise KeyError(f"no camera named {name!r}; have {list(self.camera_names)}")

    @property
    def x_names(self) -> tuple[str, ...]:
        """X-variable names in configuration order: the frames of ``tags.ids``, then the named
        targets (``targets.names``)."""
        return tuple(self.tags.frame_name(i) for i in self.tags.ids) + self.targets.names

    def target_specs(self) -> tuple:
        """Every target as a :class:`~rwhec_ros.vision.targets.TargetSpec`, in :attr:`x_names`
        order: one per tag of ``tags.ids`` (frame ``<tags.frame_prefix><id>``, its size), then
        the named targets (boards and tags)."""
        from ..vision.targets import TargetSpec

        singles = tuple(TargetSpec(self.tags.frame_name(i), tag_id=i, tag_size=self.tags.sizes[i])
                        for i in self.tags.ids)
        return singles + self.targets.specs

    @property
    def target_kinds(self) -> tuple[tuple[str, str], ...]:
        """``(target name, kind)`` of every target (``"tag"``, ``"chessboard"``, ...,
        :attr:`~rwhec_ros.vision.targets.TargetSpec.kind`): the noise groups split a camera
        whose targets are of several kinds (:mod:`rwhec_ros.core.noise.groups`)."""
        return tuple((t.name, t.kind) for t in self.target_specs())

    @property
    def y_names(self) -> tuple[str, ...]:
        """Y-variable names (cameras) in configuration order."""
        return self.camera_names

    def published_frames(self) -> dict[str, tuple[str, str]]:
        """Variable name -> (parent frame, child frame) under which its estimate is published.

        Cameras: ``(camera carrier, calibrated_frame)``; tags: ``(tag carrier,
        <tag frame><output.frame_suffix>)``, the same for the named targets.
        """
        out = {c.name: (self.camera_carrier.frame, c.calibrated_frame) for c in self.cameras}
        for name in self.x_names:
            out[name] = (self.tag_carrier.frame, name + self.output.frame_suffix)
        return out

    def detection_thread_count(self, available_cores: int | None = None) -> int:
        """Threads for tag detection: ``sync.detection_threads``, or for ``"auto"`` the cores
        available to this process (``os.sched_getaffinity``; ``available_cores`` overrides it)
        but at most one per camera: the images of one camera are examined in order, one at a
        time (the motion gate needs the previous image's pairs), so more threads than cameras
        would idle."""
        n = self.sync.detection_threads
        if n != "auto":
            return int(n)
        if available_cores is None:
            try:
                available_cores = len(os.sched_getaffinity(0))
            except (AttributeError, OSError):  # not on every platform
                available_cores = os.cpu_count() or 1
        return max(1, min(int(available_cores), len(self.cameras)))

    # --- construction ---------------------------------------------------------------------
    @staticmethod
    def from_parameters(flat: Mapping[str, Any]) -> CalibratorConfig:
        """Validate flat parameters (dotted name -> value) and build the configuration.

        Used by :func:`load_config` (after flattening the YAML) and by the node (with the values
        of its declared parameters). ``None`` values count as absent (a ROS parameter declared
        by type only). Parameters managed by ROS itself (``use_sim_time``, ``qos_overrides.*``,
        ``start_type_description_service``) are ignored.

        Raises
        ------
        ValueError
            Naming the dotted parameter and its value: unknown name (with the closest known
            names), missing required parameter, wrong type, or invalid value (negative size,
            unknown mode, carriers that do not match the pose source, ...).
        """
        return CalibratorConfig(**build_sections(*typed_parameters(flat)))

    def to_parameters(self) -> dict[str, Any]:
        """Flat dotted parameters (plain Python values) that rebuild this configuration."""
        return dict(self.parameters)

    def to_yaml(self, node_name: str = "/**") -> str:
        """The configuration as a ROS 2 parameter file (nested mappings) under the section key
        ``node_name`` (default ``/**``: any node in any namespace)."""
        nested: dict[str, Any] = {}
        for key, value in self.to_parameters().items():
            node = nested
            parts = key.split(".")
            for p in parts[:-1]:
                node = node.setdefault(p, {})
            node[parts[-1]] = value
        return yaml.safe_dump({node_name: {"ros__parameters": nested}}, sort_keys=False)


def build_sections(v: dict[str, Any], names: tuple[str, ...]) -> dict[str, Any]:
    """Semantic validation of typed values ``v`` (every schema name present): the keyword
    arguments of :class:`CalibratorConfig`."""
    cam_carrier = CarrierConfig(check_frame(v, "camera_carrier.frame"), v["camera_carrier.moving"])
    tag_carrier = CarrierConfig(check_frame(v, "tag_carrier.frame"), v["tag_carrier.moving"])
    if cam_carrier.frame == tag_carrier.frame:
        raise ValueError(
            f"tag_carrier.frame: {tag_carrier.frame!r} equals camera_carrier.frame; cameras and "
            "tags must be carried by two different frames that move relative to each other"
        )
    if not cam_carrier.moving and not tag_carrier.moving:
        raise ValueError(
            f"camera_carrier.moving: both carriers are fixed (camera_carrier.moving = False, "
            f"tag_carrier.moving = False): without relative motion between "
            f"{cam_carrier.frame!r} and {tag_carrier.frame!r} nothing can be calibrated"
        )

    ptype = check_choice(v, "pose_source.type", POSE_SOURCE_TYPES)
    parent = check_frame(v, "pose_source.parent")
    child = check_frame(v, "pose_source.child")
    carriers = {cam_carrier.frame, tag_carrier.frame}
    if {parent, child} != carriers:
        bad = "pose_source.parent" if parent not in carriers else "pose_source.child"
        raise ValueError(
            f"{bad}: the pose source must relate the two carriers directly, got "
            f"(parent {parent!r}, child {child!r}) but the carriers are camera_carrier.frame "
            f"{cam_carrier.frame!r} and tag_carrier.frame {tag_carrier.frame!r}; with no "
            "relative pose source between them A = T_<camera carrier>_<tag carrier> is unknown"
        )
    topic = check_topic(v, "pose_source.topic") if ptype == "topic" else v["pose_source.topic"]
    pose = PoseSourceConfig(ptype, topic, parent, child, invert=(parent == tag_carrier.frame))

    cameras = []
    for n in names:
        p = f"cameras.{n}."
        frame = check_frame(v, p + "frame", allow_empty=True) or n
        cal = check_frame(v, p + "calibrated_frame", allow_empty=True)
        cameras.append(
            CameraConfig(
                name=n,
                image_topic=check_topic(v, p + "image_topic"),
                camera_info_topic=check_topic(v, p + "camera_info_topic"),
                frame=frame,
                calibrated_frame=cal or frame + v["output.frame_suffix"],
                image_transport=check_choice(v, p + "image_transport", IMAGE_TRANSPORTS),
            )
        )

    tags = _build_tags(v)
    targets = TargetsConfig(build_targets(v, tags.family, tags.ids))
    if not tags.ids and not targets.specs:
        raise ValueError("tags.ids: at least one target is required: a tag id in tags.ids or a "
                         "named target in targets.names, got none")
    # X names (tags, targets), Y names (cameras) and published frames must not collide.
    tag_frames = [tags.frame_name(i) for i in tags.ids]
    for n in targets.names:
        if n in tag_frames or n in names:
            raise ValueError(f"targets.names: target {n!r} has the name of a "
                             f"{'tag frame' if n in tag_frames else 'camera'}")
    var_names = tag_frames + list(names)
    dup = sorted({n for n in var_names if var_names.count(n) > 1})
    if dup:
        raise ValueError(
            f"tags.frame_prefix: tag frame names {dup} collide with camera names {list(names)}"
        )
    published = [c.calibrated_frame for c in cameras] + [
        x + v["output.frame_suffix"] for x in tag_frames + list(targets.names)
    ]
    dup = sorted({n for n in published if published.count(n) > 1})
    if dup:
        raise ValueError(f"output.frame_suffix: published frame names collide: {dup}")
    if set(published) & carriers:
        raise ValueError(
            f"output.frame_suffix: a published frame equals a carrier frame: "
            f"{sorted(set(published) & carriers)}"
        )

    noise = NoiseConfig(
        sigma=check_positive(v, "noise.sigma", allow_zero=True),
        kappa=check_positive(v, "noise.kappa", allow_zero=True),
        from_reprojection=v["noise.from_reprojection"],
        estimate=v["noise.estimate"],
        groups=check_choice(v, "noise.groups", NOISE_GROUPS),
    )
    sync = SyncConfig(
        max_gap_s=check_positive(v, "sync.max_gap_s"),
        extrapolation_tolerance_s=check_positive(v, "sync.extrapolation_tolerance_s",
                                                 allow_zero=True),
        pose_buffer_size=check_positive_int(v, "sync.pose_buffer_size", 2),
        image_queue_size=check_positive_int(v, "sync.image_queue_size", 1),
        detection_threads=check_int_or_auto(v, "sync.detection_threads", 1),
        tf_timeout_s=check_positive(v, "sync.tf_timeout_s", allow_zero=True),
        at_rest_max_gap_s=check_positive(v, "sync.at_rest_max_gap_s", allow_zero=True),
        at_rest_translation_m=check_positive(v, "sync.at_rest_translation_m", allow_zero=True),
        at_rest_rotation_rad=check_positive(v, "sync.at_rest_rotation_rad", allow_zero=True),
        max_pose_wait_s=check_positive(v, "sync.max_pose_wait_s", allow_zero=True),
        max_waiting_mb=check_positive(v, "sync.max_waiting_mb"),
        estimate_time_offset=v["sync.estimate_time_offset"],
        time_offset_range_s=_check_range(v, "sync.time_offset_range_s"),
        time_offset_max_std_s=check_positive(v, "sync.time_offset_max_std_s"),
        time_offsets=tuple((n, _check_offset(v, f"sync.time_offset.{n}")) for n in names),
    )
    capture = CaptureConfig(
        mode=check_choice(v, "capture.mode", CAPTURE_MODES),
        rest_s=check_positive(v, "capture.rest_s", allow_zero=True),
        timeout_s=check_positive(v, "capture.timeout_s"),
    )
    keyframe = KeyframeConfig(
        min_rotation_rad=check_positive(v, "keyframe.min_rotation_rad"),
        min_translation_m=check_positive(v, "keyframe.min_translation_m"),
        max_pairs_per_edge=check_positive_int(v, "keyframe.max_pairs_per_edge", 2),
    )
    detection = DetectionConfig(
        corner_refinement=check_choice(
            v, "detection.corner_refinement", ("edge", "subpix", "apriltag", "contour", "none")
        ),
        max_reprojection_rms_px=check_positive(v, "detection.max_reprojection_rms_px"),
        reprojection_gate_factor=_gate_factor(v),
        chessboard_refinement=check_choice(v, "detection.chessboard_refinement",
                                           CHESSBOARD_REFINEMENTS),
        min_side_px=check_positive(v, "detection.min_side_px", allow_zero=True),
        max_obliquity_deg=check_positive(v, "detection.max_obliquity_deg"),
        decimate=check_int_or_auto(v, "detection.decimate", 1),
        motion_gate=v["detection.motion_gate"],
        discovery_step=check_positive(v, "detection.discovery_step", allow_zero=True),
    )
    if detection.max_obliquity_deg > 90.0:
        raise ValueError(
            f"detection.max_obliquity_deg: must be in (0, 90], got {detection.max_obliquity_deg!r}"
        )
    solver = SolverConfig(
        mode=check_choice(v, "solver.mode", SOLVER_MODES),
        min_pairs=check_positive_int(v, "solver.min_pairs", 1),
        reject_outliers=v["solver.reject_outliers"],
        unobservable_std_m=check_positive(v, "solver.unobservable_std_m"),
        min_scale=check_positive(v, "solver.min_scale"),
        live_period_s=check_positive(v, "solver.live_period_s", allow_zero=True),
        sdp_backend=check_choice(v, "solver.sdp_backend", SDP_BACKENDS),
        refine=v["solver.refine"],
    )
    convergence = ConvergenceConfig(
        max_std_translation_m=check_positive(v, "convergence.max_std_translation_m"),
        max_std_rotation_deg=check_positive(v, "convergence.max_std_rotation_deg"),
    )
    priors = _build_priors(v, names, tag_frames + list(targets.names))
    output = OutputConfig(
        directory=v["output.directory"],
        frame_suffix=v["output.frame_suffix"],
        publish_tf=v["output.publish_tf"],
        publish_uncertified=v["output.publish_uncertified"],
        publish_unusable=v["output.publish_unusable"],
    )
    ros = RosConfig(
        image_qos=check_choice(v, "ros.image_qos", IMAGE_QOS),
        diagnostics_period_s=check_positive(v, "ros.diagnostics_period_s"),
        image_queue_depth=check_positive_int(v, "ros.image_queue_depth", 1),
        detections_rate_hz=check_positive(v, "ros.detections_rate_hz", allow_zero=True),
    )
    check = _build_check(v)
    folds = v["accuracy.cross_validation_folds"]
    if folds < 0 or folds == 1:
        raise ValueError(f"accuracy.cross_validation_folds: must be 0 (off) or >= 2, got "
                         f"{folds!r}")
    accuracy = AccuracyConfig(cross_validation_folds=int(folds), guidance=v["accuracy.guidance"])
    plain = {k: (list(x) if isinstance(x, tuple) else x) for k, x in v.items() if x is not None}
    return dict(
        camera_carrier=cam_carrier,
        tag_carrier=tag_carrier,
        pose_source=pose,
        cameras=tuple(cameras),
        tags=tags,
        noise=noise,
        sync=sync,
        keyframe=keyframe,
        detection=detection,
        solver=solver,
        output=output,
        ros=ros,
        verdict=_build_verdict(v),
        parameters=plain,
        priors=priors,
        accuracy=accuracy,
        convergence=convergence,
        targets=targets,
        capture=capture,
        check=check,
    )


def _build_check(v: dict[str, Any]) -> CheckConfig:
    """``check.*``: tolerances >= 0, a false-alarm rate in (0, 1), the choices."""
    rate = float(v["check.false_alarm_rate"])
    if not (math.isfinite(rate) and 0.0 < rate < 1.0):
        raise ValueError(f"check.false_alarm_rate: must be in (0, 1), got {rate!r}")
    return CheckConfig(
        reference=str(v["check.reference"]),
        tolerance_translation_m=check_positive(v, "check.tolerance_translation_m",
                                               allow_zero=True),
        tolerance_rotation_deg=check_positive(v, "check.tolerance_rotation_deg",
                                              allow_zero=True),
        false_alarm_rate=rate,
        hold=check_choice(v, "check.hold", CHECK_HOLDS),
        noise=check_choice(v, "check.noise", CHECK_NOISE),
        tf_frames=check_choice(v, "check.tf_frames", ("calibrated", "sensor")),
        period_s=check_positive(v, "check.period_s", allow_zero=True),
    )


def _gate_factor(v: dict[str, Any]) -> float:
    """``detection.reprojection_gate_factor``: finite and >= 1 (a gate below the camera's own
    median noise would reject most of its images)."""
    x = v["detection.reprojection_gate_factor"]
    if not (math.isfinite(x) and x >= 1.0):
        raise ValueError(f"detection.reprojection_gate_factor: must be finite and >= 1, got "
                         f"{x!r}")
    return x


def _check_range(v: dict[str, Any], name: str) -> float:
    """A time offset search range: > 0 and at most 1 s (the pairs' recorded stream windows grow
    with it)."""
    x = check_positive(v, name)
    if x > 1.0:
        raise ValueError(f"{name}: must be at most 1.0 s, got {x!r}")
    return x


def _check_offset(v: dict[str, Any], name: str) -> float:
    """A known time offset: finite, at most 10 s either way (a larger one is a clock problem)."""
    x = v[name]
    if not (math.isfinite(x) and abs(x) <= 10.0):
        raise ValueError(f"{name}: must be finite and within +-10 s, got {x!r}")
    return float(x)


def _build_priors(v: dict[str, Any], camera_names: tuple[str, ...], x_names: list[str]
                  ) -> PriorsConfig:
    """``priors.frames/axes/values_m``: parallel arrays of the same length, axes x/y/z, frames
    among the cameras and the tag frames, finite values."""
    frames, axes, values = v["priors.frames"], v["priors.axes"], v["priors.values_m"]
    if not (len(frames) == len(axes) == len(values)):
        raise ValueError(
            f"priors.axes: priors.frames, priors.axes and priors.values_m must have the same "
            f"length, got {len(frames)}, {len(axes)} and {len(values)}")
    known = list(camera_names) + list(x_names)
    entries = []
    for i, (f, a, x) in enumerate(zip(frames, axes, values, strict=True)):
        if f not in known:
            raise ValueError(f"priors.frames[{i}]: {f!r} is neither a camera nor a tag frame; "
                             f"known: {known}")
        if a not in ("x", "y", "z"):
            raise ValueError(f"priors.axes[{i}]: expected 'x', 'y' or 'z', got {a!r}")
        if not math.isfinite(x):
            raise ValueError(f"priors.values_m[{i}]: must be finite, got {x!r}")
        if (f, a) in {(e[0], e[1]) for e in entries}:
            raise ValueError(f"priors.frames[{i}]: {f}.{a} given twice")
        entries.append((f, a, float(x)))
    return PriorsConfig(tuple(entries))


def _build_verdict(v: dict[str, Any]) -> dict[str, Any]:
    """``verdict.*`` by short name: every threshold > 0, caution levels not above unusable
    ones (the fields of :class:`rwhec_ros.core.verdict.VerdictOptions`)."""
    values = {}
    for spec in GLOBAL_SPECS:
        if not spec.name.startswith("verdict."):
            continue
        short = spec.name[len("verdict."):]
        if spec.kind == "bool":
            values[short] = v[spec.name]
        elif spec.kind == "int":
            values[short] = check_positive_int(v, spec.name, 2 if short == "min_edges" else 1)
        else:
            values[short] = check_positive(v, spec.name)
    for name in ("significance", "noise_confidence"):
        if values[name] >= 1:
            raise ValueError(f"verdict.{name}: must be < 1, got {values[name]!r}")
    for name in ("fit_caution_ratio", "edge_ratio", "edge_noisy_ratio", "reprojection_ratio",
                 "noise_group_ratio"):
        if values[name] < 1:
            raise ValueError(f"verdict.{name}: must be >= 1, got {values[name]!r}")
    for name in ("exclusion_max_share", "exclusion_rejected_share"):
        if values[name] >= 1:
            raise ValueError(f"verdict.{name}: must be < 1 (a share of the pairs), got "
                             f"{values[name]!r}")
    for low, high in (("fit_caution_ratio", "fit_unusable_ratio"),
                      ("scale_caution", "scale_unusable"),
                      ("caution_std_translation_m", "unusable_std_translation_m"),
                      ("caution_std_rotation_deg", "unusable_std_rotation_deg"),
                      ("caution_scale_rel_std", "unusable_scale_rel_std")):
        if values[low] > values[high]:
            raise ValueError(f"verdict.{low}: {values[low]!r} is above verdict.{high} "
                             f"{values[high]!r}")
    return values


def _build_tags(v: dict[str, Any]) -> TagsConfig:
    ids = v["tags.ids"]
    for i, t in enumerate(ids):
        if t < 0:
            raise ValueError(f"tags.ids[{i}]: tag ids are >= 0, got {t}")
    if len(set(ids)) != len(ids):
        dup = sorted({t for t in ids if ids.count(t) > 1})
        raise ValueError(f"tags.ids: duplicated ids {dup}")
    if not v["tags.family"]:
        raise ValueError("tags.family: must not be empty")
    from ..vision.families import dictionary_key

    try:
        dictionary_key(v["tags.family"])
    except ValueError as exc:
        raise ValueError(f"tags.family: {exc} (AprilTag families tag16h5, tag25h9, tag36h10, "
                         "tag36h11, or an ArUco dictionary such as DICT_6X6_250)") from None
    size_ids, size_values = v["tags.sizes.ids"], v["tags.sizes.values"]
    if len(size_ids) != len(size_values):
        raise ValueError(
            f"tags.sizes.values: {len(size_values)} values for {len(size_ids)} ids in "
            f"tags.sizes.ids {list(size_ids)}"
        )
    sizes: dict[int, float] = {}
    for i, (t, s) in enumerate(zip(size_ids, size_values, strict=True)):
        if t not in ids:
            raise ValueError(f"tags.sizes.ids[{i}]: id {t} is not in tags.ids {list(ids)}")
        if t in sizes:
            raise ValueError(f"tags.sizes.ids[{i}]: id {t} given twice")
        if not (math.isfinite(s) and s > 0):
            raise ValueError(f"tags.sizes.values[{i}]: size of tag {t} must be > 0, got {s!r}")
        sizes[t] = s
    default = v["tags.default_size"]
    if default is not None:
        default = check_positive(v, "tags.default_size")
    unknown_scale = v["tags.unknown_scale"]
    for t in ids:
        if t not in sizes:
            if default is not None:
                sizes[t] = default
            elif unknown_scale:
                sizes[t] = 1.0  # nominal: the common scale is estimated (Problem 3)
            else:
                raise ValueError(
                    f"tags.default_size: tag {t} has no size (not in tags.sizes.ids and no "
                    "tags.default_size); give one or set tags.unknown_scale: true"
                )
    return TagsConfig(
        family=v["tags.family"],
        ids=tuple(ids),
        sizes=sizes,
        default_size=default,
        frame_prefix=v["tags.frame_prefix"],
        unknown_scale=unknown_scale,
    )

"""Calibrator configuration: ONE file format, a ROS 2 parameter YAML, read with or without ROS.

The same file serves ``ros2 run rwhec_ros calibrator --ros-args --params-file FILE`` and the CLI's
``--config FILE``::

    calibrator:                 # node name (or "/**" for any node)
      ros__parameters:
        camera_carrier: {frame: rig, moving: true}
        ...

Nested mappings are dotted parameter names (``camera_carrier.frame``), exactly as the ROS 2
parameter-file parser flattens them. ROS parameters are scalars or homogeneous arrays only (no
lists of mappings), hence the scheme used here:

* cameras: ``cameras.names: [cam0, cam1]`` (string array) and, per name,
  ``cameras.<name>.image_topic``, ``cameras.<name>.camera_info_topic``, ``cameras.<name>.frame``
  (optical frame) and optionally ``cameras.<name>.calibrated_frame``;
* tag sizes: parallel arrays ``tags.sizes.ids: [0, 1]`` (integers) and
  ``tags.sizes.values: [0.16, 0.08]`` (metres) plus ``tags.default_size`` for every other id.

Frame convention (paper eq. (1)/(7), ``A_i X_j = Y_k B_i``): cameras are the Y variables, tags the
X variables::

    B   = T_cam_tag                             (PnP of one tag in one image, noisy)
    Y_k = T_<camera carrier>_cam_k              (unknown, estimated)
    X_j = T_<tag carrier>_tag_j                 (unknown, estimated)
    A   = T_<camera carrier>_<tag carrier>      (pose stream, taken as noise-free)

The pose source delivers ``T_parent_child`` (a ``geometry_msgs/PoseStamped`` whose
``header.frame_id`` is ``parent`` and whose pose is that of the ``child`` body, or a tf lookup
``parent <- child``); ``{parent, child}`` must be the two carrier frames. ``A = T_parent_child``
when ``parent`` is the camera carrier, and ``A = (T_parent_child)^-1`` when it is the tag carrier
(e.g. motion capture gives ``T_world_rig`` with cameras on the rig and tags in the world, so
``A = T_rig_world``).

Types are as strict as in ROS: a ``double`` parameter must be written with a decimal point
(``1.0``, not ``1``), because ``ros2`` rejects an integer for a double parameter; the loader
enforces the same rule so that a file accepted here is accepted by the node.
Units: metres, seconds, radians (suffixes ``_m``, ``_s``, ``_rad`` in the names).
"""

from __future__ import annotations

import array
import difflib
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

__all__ = [
    "ParamSpec",
    "CarrierConfig",
    "PoseSourceConfig",
    "CameraConfig",
    "TagsConfig",
    "NoiseConfig",
    "SyncConfig",
    "KeyframeConfig",
    "DetectionConfig",
    "SolverConfig",
    "OutputConfig",
    "RosConfig",
    "CalibratorConfig",
    "GLOBAL_SPECS",
    "CAMERA_SPECS",
    "parameter_specs",
    "is_valid_name",
    "load_config",
    "read_parameter_file",
    "flatten_parameters",
    "DEFAULT_NODE_NAME",
]

#: Node name used by the console script, the launch files and the example configurations.
DEFAULT_NODE_NAME = "calibrator"

#: Parameters that ROS itself declares on every node; accepted in a file and ignored here.
ROS_MANAGED_PARAMETERS = ("use_sim_time", "start_type_description_service")
#: Prefixes of parameters managed by ROS (QoS overrides); accepted and ignored.
ROS_MANAGED_PREFIXES = ("qos_overrides.",)

#: Parameter kinds, named after ``rclpy.Parameter.Type`` (see ``rwhec_ros.ros.params``).
KINDS = ("bool", "int", "double", "string", "int_array", "double_array", "string_array")

_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
_FRAME_RE = re.compile(r"^[A-Za-z0-9_/.\-]+$")
_TOPIC_RE = re.compile(r"^[~/A-Za-z_][A-Za-z0-9_/~{}]*$")

SOLVER_MODES = ("fast", "sdp", "local")
POSE_SOURCE_TYPES = ("topic", "tf")
IMAGE_QOS = ("sensor_data", "reliable")


@dataclass(frozen=True)
class ParamSpec:
    """One parameter of the schema.

    Attributes
    ----------
    name : str
        Dotted parameter name (per-camera specs: the part after ``cameras.<name>.``).
    kind : str
        One of :data:`KINDS`.
    default : object
        Value when absent; ``None`` with ``required=False`` means "unset" (optional).
    required : bool
        Absent -> ``ValueError``.
    doc : str
        One-line description (also used as the ROS parameter description).
    """

    name: str
    kind: str
    default: Any = None
    required: bool = False
    doc: str = ""


GLOBAL_SPECS: tuple[ParamSpec, ...] = (
    ParamSpec("camera_carrier.frame", "string", required=True,
              doc="frame the cameras are rigidly attached to (Y_k = T_<this>_cam_k)"),
    ParamSpec("camera_carrier.moving", "bool", required=True,
              doc="true if the camera carrier moves relative to the tag carrier"),
    ParamSpec("tag_carrier.frame", "string", required=True,
              doc="frame the tags are rigidly attached to (X_j = T_<this>_tag_j)"),
    ParamSpec("tag_carrier.moving", "bool", required=True,
              doc="true if the tag carrier moves relative to the camera carrier"),
    ParamSpec("pose_source.type", "string", "topic",
              doc="'topic' (geometry_msgs/PoseStamped) or 'tf' (lookup at each image stamp)"),
    ParamSpec("pose_source.topic", "string", "",
              doc="PoseStamped topic (type 'topic'); header.frame_id must be pose_source.parent"),
    ParamSpec("pose_source.parent", "string", required=True,
              doc="parent frame of the pose stream T_parent_child (one of the carriers)"),
    ParamSpec("pose_source.child", "string", required=True,
              doc="child frame of the pose stream T_parent_child (the other carrier)"),
    ParamSpec("cameras.names", "string_array", required=True,
              doc="camera names; each needs cameras.<name>.* parameters"),
    ParamSpec("tags.family", "string", "tag36h11", doc="AprilTag family"),
    ParamSpec("tags.ids", "int_array", required=True,
              doc="ids of the tags to calibrate; any other id is ignored (and counted)"),
    ParamSpec("tags.default_size", "double", None,
              doc="edge length [m] (black square) of every tag not in tags.sizes.ids"),
    ParamSpec("tags.sizes.ids", "int_array", (), doc="ids with an individual size"),
    ParamSpec("tags.sizes.values", "double_array", (),
              doc="sizes [m] of tags.sizes.ids, same order and length"),
    ParamSpec("tags.frame_prefix", "string", "tag_", doc="tag frame names are <prefix><id>"),
    ParamSpec("tags.unknown_scale", "bool", False,
              doc="estimate a common scale (monocular, paper Problem 3): sizes may be nominal"),
    ParamSpec("noise.sigma", "double", 0.01,
              doc="translation standard deviation of B [m] (paper sigma, eq. (14))"),
    ParamSpec("noise.kappa", "double", 125.0,
              doc="Langevin concentration of the rotation of B (paper kappa, eq. (16))"),
    ParamSpec("noise.from_reprojection", "bool", False,
              doc="use per-detection sigma/kappa from the PnP reprojection error instead"),
    ParamSpec("sync.max_gap_s", "double", 0.1,
              doc="largest pose gap [s] bridged by interpolation at an image stamp"),
    ParamSpec("sync.extrapolation_tolerance_s", "double", 0.01,
              doc="how far [s] an image stamp may lie outside the pose buffer"),
    ParamSpec("sync.pose_buffer_size", "int", 4000, doc="poses kept for lookups"),
    ParamSpec("sync.image_queue_size", "int", 8,
              doc="images waiting for detection; the oldest is dropped (and counted)"),
    ParamSpec("sync.detection_threads", "int", 1,
              doc="worker threads running tag detection (node only; >1 for many cameras)"),
    ParamSpec("sync.max_pending_images", "int", 32,
              doc="detected images waiting for a later pose to bracket their stamp"),
    ParamSpec("sync.tf_timeout_s", "double", 0.2,
              doc="wait [s] for tf at an image stamp (pose_source.type 'tf')"),
    ParamSpec("keyframe.min_rotation_rad", "double", 0.05,
              doc="a new pair needs this rotation [rad] from the last kept one (same edge)"),
    ParamSpec("keyframe.min_translation_m", "double", 0.02,
              doc="... or this translation [m]"),
    ParamSpec("keyframe.max_pairs_per_edge", "int", 300, doc="cap on kept pairs per edge"),
    ParamSpec("detection.corner_refinement", "string", "edge",
              doc="corner refinement: 'edge' (sub-pixel edge-line fit, the most accurate "
                  "measured, see benchmarks/perception.md), or cv2.aruco's 'subpix', "
                  "'apriltag', 'contour', 'none'"),
    ParamSpec("detection.max_reprojection_rms_px", "double", 1.0,
              doc="reject a tag whose RMS corner reprojection error exceeds this [px]"),
    ParamSpec("detection.min_side_px", "double", 20.0,
              doc="reject a tag whose shortest side is below this [px]"),
    ParamSpec("detection.max_obliquity_deg", "double", 70.0,
              doc="reject a tag seen more obliquely than this [deg] (0 = face-on)"),
    ParamSpec("solver.mode", "string", "fast", doc="'fast', 'sdp' or 'local'"),
    ParamSpec("solver.min_pairs", "int", 3, doc="edges with fewer pairs are left out"),
    ParamSpec("solver.reject_outliers", "bool", False,
              doc="outlier rejection: per-edge RANSAC on eq. (70) (paper Sec. 9.1), then a "
                  "GNC-TLS robust solve, re-certified on the inlier set"),
    ParamSpec("output.directory", "string", "rwhec_output",
              doc="results, data sets and static-tf launch files go here (never overwritten)"),
    ParamSpec("output.frame_suffix", "string", "_calibrated",
              doc="published child frame = <frame><suffix> unless set per camera"),
    ParamSpec("output.publish_tf", "bool", True, doc="publish results on /tf_static"),
    ParamSpec("output.publish_uncertified", "bool", False,
              doc="also publish results the certificate does not prove optimal"),
    ParamSpec("ros.image_qos", "string", "sensor_data",
              doc="image/camera_info QoS: 'sensor_data' (best effort) or 'reliable'"),
    ParamSpec("ros.diagnostics_period_s", "double", 1.0, doc="period of /diagnostics [s]"),
)

CAMERA_SPECS: tuple[ParamSpec, ...] = (
    ParamSpec("image_topic", "string", required=True, doc="sensor_msgs/Image topic"),
    ParamSpec("camera_info_topic", "string", required=True, doc="sensor_msgs/CameraInfo topic"),
    ParamSpec("frame", "string", "", doc="optical frame name (default: the camera name)"),
    ParamSpec("calibrated_frame", "string", "",
              doc="published child frame (default: <frame><output.frame_suffix>)"),
)


def is_valid_name(name: str) -> bool:
    """True for a camera name usable in parameter names (letter, then letters, digits, ``_``)."""
    return bool(_NAME_RE.match(str(name)))


def parameter_specs(camera_names: tuple[str, ...] | list[str] = ()) -> list[ParamSpec]:
    """The full schema with per-camera specs expanded to ``cameras.<name>.<key>``."""
    out = list(GLOBAL_SPECS)
    for name in camera_names:
        for s in CAMERA_SPECS:
            out.append(ParamSpec(f"cameras.{name}.{s.name}", s.kind, s.default, s.required, s.doc))
    return out


# --------------------------------------------------------------------------------------------
# typed sections


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
    """One camera (a Y variable): topics, optical frame and published frame name."""

    name: str
    image_topic: str
    camera_info_topic: str
    frame: str
    calibrated_frame: str


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
class NoiseConfig:
    """Measurement precisions of ``B`` (paper eq. (14), (16)); ``from_reprojection`` overrides."""

    sigma: float
    kappa: float
    from_reprojection: bool


@dataclass(frozen=True)
class SyncConfig:
    """Pose/image time matching. Seconds here; the session converts to integer nanoseconds."""

    max_gap_s: float
    extrapolation_tolerance_s: float
    pose_buffer_size: int
    image_queue_size: int
    detection_threads: int
    max_pending_images: int
    tf_timeout_s: float


@dataclass(frozen=True)
class KeyframeConfig:
    """Thresholds for keeping a new measurement pair on an edge."""

    min_rotation_rad: float
    min_translation_m: float
    max_pairs_per_edge: int


@dataclass(frozen=True)
class DetectionConfig:
    """Gates of the tag detector (:class:`rwhec_ros.vision.detection.DetectorConfig`)."""

    corner_refinement: str
    max_reprojection_rms_px: float
    min_side_px: float
    max_obliquity_deg: float


@dataclass(frozen=True)
class SolverConfig:
    """Solver mode (``fast``/``sdp``/``local``), minimum pairs per edge, outlier switch."""

    mode: str
    min_pairs: int
    reject_outliers: bool


@dataclass(frozen=True)
class OutputConfig:
    """Output directory and publication settings."""

    directory: str
    frame_suffix: str
    publish_tf: bool
    publish_uncertified: bool


@dataclass(frozen=True)
class RosConfig:
    """Settings only the node uses (ignored by the CLI)."""

    image_qos: str
    diagnostics_period_s: float


@dataclass(frozen=True)
class CalibratorConfig:
    """The validated calibrator configuration (see the module docstring for the file format).

    Build it with :meth:`from_parameters` (flat dotted names -> values) or :func:`load_config`.
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
    parameters: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)

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
        """X-variable names (tags) in configuration order."""
        return tuple(self.tags.frame_name(i) for i in self.tags.ids)

    @property
    def y_names(self) -> tuple[str, ...]:
        """Y-variable names (cameras) in configuration order."""
        return self.camera_names

    def published_frames(self) -> dict[str, tuple[str, str]]:
        """Variable name -> (parent frame, child frame) under which its estimate is published.

        Cameras: ``(camera carrier, calibrated_frame)``; tags: ``(tag carrier,
        <tag frame><output.frame_suffix>)``.
        """
        out = {c.name: (self.camera_carrier.frame, c.calibrated_frame) for c in self.cameras}
        for name in self.x_names:
            out[name] = (self.tag_carrier.frame, name + self.output.frame_suffix)
        return out

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
        params = {
            str(k): v
            for k, v in flat.items()
            if v is not None
            and str(k) not in ROS_MANAGED_PARAMETERS
            and not str(k).startswith(ROS_MANAGED_PREFIXES)
        }
        reader = _Reader(params)
        names = reader.get(_spec("cameras.names"))
        if len(names) == 0:
            raise ValueError("cameras.names: at least one camera is required, got []")
        for i, n in enumerate(names):
            if not _NAME_RE.match(n):
                raise ValueError(
                    f"cameras.names[{i}]: {n!r} is not a valid name (letter, then letters, "
                    "digits or '_')"
                )
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise ValueError(f"cameras.names: duplicated names {dup} in {list(names)}")
        specs = {s.name: s for s in parameter_specs(names)}
        unknown = sorted(k for k in params if k not in specs)
        if unknown:
            k = unknown[0]
            hint = difflib.get_close_matches(k, list(specs), n=3)
            more = f" (also unknown: {unknown[1:]})" if len(unknown) > 1 else ""
            hint_s = f"; did you mean {hint}?" if hint else ""
            if k.startswith("cameras.") and k.split(".")[1] not in names:
                hint_s += f"; camera {k.split('.')[1]!r} is not in cameras.names {list(names)}"
            raise ValueError(f"{k}: unknown parameter (value {params[k]!r}){hint_s}{more}")
        v = {name: reader.get(s) for name, s in specs.items()}
        return _build(v, names)

    def to_parameters(self) -> dict[str, Any]:
        """Flat dotted parameters (plain Python values) that rebuild this configuration."""
        return dict(self.parameters)

    def to_yaml(self, node_name: str = DEFAULT_NODE_NAME) -> str:
        """The configuration as a ROS 2 parameter file (nested mappings)."""
        nested: dict[str, Any] = {}
        for key, value in self.to_parameters().items():
            node = nested
            parts = key.split(".")
            for p in parts[:-1]:
                node = node.setdefault(p, {})
            node[parts[-1]] = value
        return yaml.safe_dump({node_name: {"ros__parameters": nested}}, sort_keys=False)


# --------------------------------------------------------------------------------------------
# validation helpers


def _spec(name: str) -> ParamSpec:
    for s in GLOBAL_SPECS:
        if s.name == name:
            return s
    raise KeyError(name)


_ARRAY_TYPES = (list, tuple, array.array, np.ndarray)


def _kind_error(name: str, value: Any, kind: str) -> ValueError:
    hint = ""
    if kind == "double" and isinstance(value, int) and not isinstance(value, bool):
        hint = f" (write {float(value)!r}: ROS does not accept an integer for a double)"
    if kind == "double_array" and isinstance(value, _ARRAY_TYPES):
        hint = " (write every element with a decimal point, e.g. 1.0)"
    return ValueError(f"{name}: expected {kind}, got {type(value).__name__} {_show(value)}{hint}")


def _show(value: Any) -> str:
    if isinstance(value, (array.array, np.ndarray)):
        value = list(value)
    return repr(value)


def _check_kind(name: str, value: Any, kind: str) -> Any:
    """Convert ``value`` to the plain Python type of ``kind`` or raise naming ``name``."""
    if kind == "bool":
        if isinstance(value, (bool, np.bool_)):
            return bool(value)
    elif kind == "int":
        if isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)):
            return int(value)
    elif kind == "double":
        if isinstance(value, (float, np.floating)):
            return float(value)
    elif kind == "string":
        if isinstance(value, str):
            return value
    else:
        if not isinstance(value, _ARRAY_TYPES) or (
            isinstance(value, np.ndarray) and value.ndim != 1
        ):
            raise _kind_error(name, value, kind)
        elem = kind[: -len("_array")]
        out = []
        for i, item in enumerate(value):
            try:
                out.append(_check_kind(f"{name}[{i}]", item, elem))
            except ValueError as exc:
                raise ValueError(f"{exc} in {name} = {_show(value)}") from None
        return tuple(out)
    raise _kind_error(name, value, kind)


class _Reader:
    """Typed access to the flat parameters, with defaults and required checks."""

    def __init__(self, params: Mapping[str, Any]) -> None:
        self._params = params

    def get(self, spec: ParamSpec) -> Any:
        if spec.name not in self._params:
            if spec.required:
                raise ValueError(f"{spec.name}: missing required parameter ({spec.doc})")
            return spec.default
        return _check_kind(spec.name, self._params[spec.name], spec.kind)


def _positive(v: dict[str, Any], name: str, *, allow_zero: bool = False) -> float:
    x = v[name]
    ok = math.isfinite(x) and (x >= 0 if allow_zero else x > 0)
    if not ok:
        rel = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name}: must be finite and {rel}, got {x!r}")
    return x


def _choice(v: dict[str, Any], name: str, choices: tuple[str, ...]) -> str:
    if v[name] not in choices:
        raise ValueError(f"{name}: must be one of {list(choices)}, got {v[name]!r}")
    return v[name]


def _frame(v: dict[str, Any], name: str, *, allow_empty: bool = False) -> str:
    x = v[name]
    if x == "" and allow_empty:
        return x
    if not _FRAME_RE.match(x) or x.startswith("/"):
        raise ValueError(
            f"{name}: {x!r} is not a valid frame name (non-empty, no leading '/', letters, "
            "digits, '_', '-', '.', '/')"
        )
    return x


def _topic(v: dict[str, Any], name: str) -> str:
    x = v[name]
    if not x:
        raise ValueError(f"{name}: missing topic (empty string)")
    if not _TOPIC_RE.match(x) or "//" in x or x.endswith("/"):
        raise ValueError(f"{name}: {x!r} is not a valid ROS topic name")
    return x


def _build(v: dict[str, Any], names: tuple[str, ...]) -> CalibratorConfig:
    """Semantic validation of typed values ``v`` (every schema name present)."""
    cam_carrier = CarrierConfig(_frame(v, "camera_carrier.frame"), v["camera_carrier.moving"])
    tag_carrier = CarrierConfig(_frame(v, "tag_carrier.frame"), v["tag_carrier.moving"])
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

    ptype = _choice(v, "pose_source.type", POSE_SOURCE_TYPES)
    parent = _frame(v, "pose_source.parent")
    child = _frame(v, "pose_source.child")
    carriers = {cam_carrier.frame, tag_carrier.frame}
    if {parent, child} != carriers:
        bad = "pose_source.parent" if parent not in carriers else "pose_source.child"
        raise ValueError(
            f"{bad}: the pose source must relate the two carriers directly, got "
            f"(parent {parent!r}, child {child!r}) but the carriers are camera_carrier.frame "
            f"{cam_carrier.frame!r} and tag_carrier.frame {tag_carrier.frame!r}; with no "
            "relative pose source between them A = T_<camera carrier>_<tag carrier> is unknown"
        )
    topic = _topic(v, "pose_source.topic") if ptype == "topic" else v["pose_source.topic"]
    pose = PoseSourceConfig(ptype, topic, parent, child, invert=(parent == tag_carrier.frame))

    cameras = []
    for n in names:
        p = f"cameras.{n}."
        frame = _frame(v, p + "frame", allow_empty=True) or n
        cal = _frame(v, p + "calibrated_frame", allow_empty=True)
        cameras.append(
            CameraConfig(
                name=n,
                image_topic=_topic(v, p + "image_topic"),
                camera_info_topic=_topic(v, p + "camera_info_topic"),
                frame=frame,
                calibrated_frame=cal or frame + v["output.frame_suffix"],
            )
        )

    tags = _build_tags(v)
    # X names (tags), Y names (cameras) and published frames must not collide.
    var_names = [tags.frame_name(i) for i in tags.ids] + list(names)
    dup = sorted({n for n in var_names if var_names.count(n) > 1})
    if dup:
        raise ValueError(
            f"tags.frame_prefix: tag frame names {dup} collide with camera names {list(names)}"
        )
    published = [c.calibrated_frame for c in cameras] + [
        tags.frame_name(i) + v["output.frame_suffix"] for i in tags.ids
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
        sigma=_positive(v, "noise.sigma"),
        kappa=_positive(v, "noise.kappa"),
        from_reprojection=v["noise.from_reprojection"],
    )
    sync = SyncConfig(
        max_gap_s=_positive(v, "sync.max_gap_s"),
        extrapolation_tolerance_s=_positive(v, "sync.extrapolation_tolerance_s", allow_zero=True),
        pose_buffer_size=_positive_int(v, "sync.pose_buffer_size", 2),
        image_queue_size=_positive_int(v, "sync.image_queue_size", 1),
        detection_threads=_positive_int(v, "sync.detection_threads", 1),
        max_pending_images=_positive_int(v, "sync.max_pending_images", 0),
        tf_timeout_s=_positive(v, "sync.tf_timeout_s", allow_zero=True),
    )
    keyframe = KeyframeConfig(
        min_rotation_rad=_positive(v, "keyframe.min_rotation_rad"),
        min_translation_m=_positive(v, "keyframe.min_translation_m"),
        max_pairs_per_edge=_positive_int(v, "keyframe.max_pairs_per_edge", 2),
    )
    detection = DetectionConfig(
        corner_refinement=_choice(
            v, "detection.corner_refinement", ("edge", "subpix", "apriltag", "contour", "none")
        ),
        max_reprojection_rms_px=_positive(v, "detection.max_reprojection_rms_px"),
        min_side_px=_positive(v, "detection.min_side_px", allow_zero=True),
        max_obliquity_deg=_positive(v, "detection.max_obliquity_deg"),
    )
    if detection.max_obliquity_deg > 90.0:
        raise ValueError(
            f"detection.max_obliquity_deg: must be in (0, 90], got {detection.max_obliquity_deg!r}"
        )
    solver = SolverConfig(
        mode=_choice(v, "solver.mode", SOLVER_MODES),
        min_pairs=_positive_int(v, "solver.min_pairs", 1),
        reject_outliers=v["solver.reject_outliers"],
    )
    if not v["output.directory"]:
        raise ValueError("output.directory: must not be empty")
    output = OutputConfig(
        directory=v["output.directory"],
        frame_suffix=v["output.frame_suffix"],
        publish_tf=v["output.publish_tf"],
        publish_uncertified=v["output.publish_uncertified"],
    )
    ros = RosConfig(
        image_qos=_choice(v, "ros.image_qos", IMAGE_QOS),
        diagnostics_period_s=_positive(v, "ros.diagnostics_period_s"),
    )
    plain = {k: (list(x) if isinstance(x, tuple) else x) for k, x in v.items() if x is not None}
    return CalibratorConfig(
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
        parameters=plain,
    )


def _positive_int(v: dict[str, Any], name: str, minimum: int) -> int:
    if v[name] < minimum:
        raise ValueError(f"{name}: must be >= {minimum}, got {v[name]!r}")
    return v[name]


def _build_tags(v: dict[str, Any]) -> TagsConfig:
    ids = v["tags.ids"]
    if len(ids) == 0:
        raise ValueError("tags.ids: at least one tag id is required, got []")
    for i, t in enumerate(ids):
        if t < 0:
            raise ValueError(f"tags.ids[{i}]: tag ids are >= 0, got {t}")
    if len(set(ids)) != len(ids):
        dup = sorted({t for t in ids if ids.count(t) > 1})
        raise ValueError(f"tags.ids: duplicated ids {dup}")
    if not v["tags.family"]:
        raise ValueError("tags.family: must not be empty")
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
        default = _positive(v, "tags.default_size")
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


# --------------------------------------------------------------------------------------------
# files


class _ParamLoader(yaml.SafeLoader):
    """SafeLoader that also reads ``1e-3`` as a float (YAML 1.2 / rcl_yaml_param_parser)."""


_ParamLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
        |\.[0-9_]+(?:[eE][-+][0-9]+)?
        |[-+]?\.(?:inf|Inf|INF)
        |\.(?:nan|NaN|NAN))$""",
        re.X,
    ),
    list("-+0123456789."),
)


def flatten_parameters(tree: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Flatten nested mappings into dotted names, as the ROS 2 parameter-file parser does.

    Lists stay values; a list containing mappings or mixed types raises ``ValueError`` (ROS
    arrays are homogeneous scalars).
    """
    out: dict[str, Any] = {}
    for key, value in tree.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            out.update(flatten_parameters(value, name + "."))
            continue
        if isinstance(value, list):
            kinds = {type(x).__name__ for x in value}
            if any(isinstance(x, (Mapping, list)) for x in value):
                raise ValueError(
                    f"{name}: ROS parameters cannot hold lists of mappings or nested lists, "
                    f"got {value!r}; use dotted names (see the config module docstring)"
                )
            if len(kinds) > 1:
                raise ValueError(f"{name}: ROS arrays must be homogeneous, got {value!r}")
        if value is None:
            raise ValueError(f"{name}: empty value (null) is not a ROS parameter value")
        out[name] = value
    return out


def read_parameter_file(path: str | Path, node_name: str | None = None) -> dict[str, Any]:
    """Read a ROS 2 parameter YAML and return the flat parameters of one node.

    Sections apply in the order the ROS parser applies them: ``/**`` (every node) first, then
    ``/**/<node_name>``, ``<node_name>`` / ``/<node_name>`` or a namespaced ``/ns/<node_name>``.
    With ``node_name=None`` a file with one section uses it, otherwise the sections for
    :data:`DEFAULT_NODE_NAME` (``calibrator``) are used.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ValueError(f"config file {str(path)!r}: cannot read ({exc})") from None
    try:
        doc = yaml.load(text, Loader=_ParamLoader)  # noqa: S506 - SafeLoader subclass
    except yaml.YAMLError as exc:
        raise ValueError(f"config file {str(path)!r}: invalid YAML ({exc})") from None
    if not isinstance(doc, Mapping) or not doc:
        raise ValueError(
            f"config file {str(path)!r}: expected '<node_name>: ros__parameters: ...' at top level"
        )
    keys = [str(k) for k in doc]
    if node_name is None and len(keys) == 1:
        selected = keys
    else:
        node_name = DEFAULT_NODE_NAME if node_name is None else node_name
        bare = node_name.strip("/").split("/")[-1]

        def rank(k: str) -> int | None:
            if k == "/**":
                return 0
            if k == f"/**/{bare}":
                return 1
            if k.strip("/") == bare or k.endswith("/" + bare):
                return 2
            return None

        selected = sorted((k for k in keys if rank(k) is not None), key=rank)
        if not selected:
            raise ValueError(
                f"config file {str(path)!r}: no section for node {node_name!r}; sections: {keys}"
            )
    flat: dict[str, Any] = {}
    for k in selected:
        section = doc[k]
        if not isinstance(section, Mapping) or "ros__parameters" not in section:
            raise ValueError(
                f"config file {str(path)!r}: section {k!r} must contain 'ros__parameters'"
            )
        extra = [str(x) for x in section if x != "ros__parameters"]
        if extra:
            raise ValueError(f"config file {str(path)!r}: section {k!r}: unknown keys {extra}")
        params = section["ros__parameters"]
        if not isinstance(params, Mapping):
            raise ValueError(f"config file {str(path)!r}: {k}.ros__parameters must be a mapping")
        flat.update(flatten_parameters(params))
    return flat


def load_config(path: str | Path, node_name: str | None = None) -> CalibratorConfig:
    """Load and validate a configuration file without ROS (see the module docstring).

    Raises ``ValueError`` naming the file and the dotted parameter for any problem.
    """
    flat = read_parameter_file(path, node_name)
    try:
        return CalibratorConfig.from_parameters(flat)
    except ValueError as exc:
        raise ValueError(f"config file {str(path)!r}: {exc}") from None

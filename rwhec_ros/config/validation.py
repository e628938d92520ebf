"""Validation of flat parameters: types as strict as ROS, values checked, errors name the parameter.

Types are as strict as in ROS: a ``double`` parameter must be written with a decimal point
(``1.0``, not ``1``), because ``ros2`` rejects an integer for a double parameter; the checks here
enforce the same rule so that a file accepted here is accepted by the node.
"""

from __future__ import annotations

import array
import difflib
import math
import re
from collections.abc import Mapping
from typing import Any

import numpy as np

from .sections import (
    CameraConfig,
    CarrierConfig,
    DetectionConfig,
    KeyframeConfig,
    NoiseConfig,
    OutputConfig,
    PoseSourceConfig,
    RosConfig,
    SolverConfig,
    SyncConfig,
    TagsConfig,
)
from .specs import (
    IMAGE_QOS,
    POSE_SOURCE_TYPES,
    ROS_MANAGED_PARAMETERS,
    ROS_MANAGED_PREFIXES,
    SOLVER_MODES,
    ParamSpec,
    global_spec,
    is_valid_name,
    parameter_specs,
)

__all__ = ["typed_parameters", "build_sections", "check_kind"]

_FRAME_RE = re.compile(r"^[A-Za-z0-9_/.\-]+$")
_TOPIC_RE = re.compile(r"^[~/A-Za-z_][A-Za-z0-9_/~{}]*$")


def typed_parameters(flat: Mapping[str, Any]) -> tuple[dict[str, Any], tuple[str, ...]]:
    """Check names and types of flat parameters (dotted name -> value).

    ``None`` values count as absent (a ROS parameter declared by type only); parameters managed
    by ROS itself are ignored. Returns every schema name -> its typed value (defaults filled
    in) and the camera names. ``ValueError`` names the parameter: unknown name (with the closest
    known names), missing required parameter or wrong type.
    """
    params = {
        str(k): v
        for k, v in flat.items()
        if v is not None
        and str(k) not in ROS_MANAGED_PARAMETERS
        and not str(k).startswith(ROS_MANAGED_PREFIXES)
    }
    reader = _Reader(params)
    names = reader.get(global_spec("cameras.names"))
    if len(names) == 0:
        raise ValueError("cameras.names: at least one camera is required, got []")
    for i, n in enumerate(names):
        if not is_valid_name(n):
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
    return v, names


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


def check_kind(name: str, value: Any, kind: str) -> Any:
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
                out.append(check_kind(f"{name}[{i}]", item, elem))
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
        return check_kind(spec.name, self._params[spec.name], spec.kind)


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


def build_sections(v: dict[str, Any], names: tuple[str, ...]) -> dict[str, Any]:
    """Semantic validation of typed values ``v`` (every schema name present): the keyword
    arguments of :class:`~rwhec_ros.config.calibrator.CalibratorConfig`."""
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


"""The validated calibrator configuration, :class:`CalibratorConfig` (node and CLI alike)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import yaml

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
from .specs import DEFAULT_NODE_NAME
from .validation import build_sections, typed_parameters

__all__ = ["CalibratorConfig"]


@dataclass(frozen=True)
class CalibratorConfig:
    """The validated calibrator configuration (file format: :mod:`rwhec_ros.config`).

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
        return CalibratorConfig(**build_sections(*typed_parameters(flat)))

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


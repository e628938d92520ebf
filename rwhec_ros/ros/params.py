"""Declaring the calibrator's ROS parameters and building its configuration from them.

The schema lives in :mod:`rwhec_ros.config` (one source for the node and the CLI). The node is
created with ``automatically_declare_parameters_from_overrides=True``, so every parameter of the
``--params-file`` is declared with the type written in the file (unknown names included, which
:meth:`CalibratorConfig.from_parameters` then rejects by name); :func:`declare_parameters` then
declares every remaining schema parameter with its typed default, so that
``ros2 param list/describe`` shows the whole schema; each description ends with what a change
at run time does (:mod:`rwhec_ros.config.live_parameters`). No parameter is declared read-only:
the node's parameter callback accepts the live ones and refuses the others with the reason
(rclpy's read-only refusal would not say why). Parameters without a default (required ones,
empty arrays, ``tags.default_size``) are declared by type only (``Parameter.Type.*``): their value
stays unset (``None``), which the configuration reads as "absent".

Per-camera parameters (``cameras.<name>.*``) and per-target parameters (``targets.<name>.*``)
are declared after ``cameras.names`` and ``targets.names`` are known.
Only :func:`declare_parameters` and :func:`config_from_node` touch rclpy (imported lazily); the
planning function :func:`declaration_plan` is plain Python and tested without ROS.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from typing import Any

from ..config import CalibratorConfig, is_valid_name, parameter_specs
from ..config.live_parameters import live_effect

__all__ = [
    "ROS_TYPE_NAMES",
    "change_note",
    "declaration_plan",
    "declare_parameters",
    "config_from_node",
]

#: Schema kind -> name of the ``rclpy.Parameter.Type`` member.
ROS_TYPE_NAMES = {
    "bool": "BOOL",
    "int": "INTEGER",
    "double": "DOUBLE",
    "string": "STRING",
    "int_array": "INTEGER_ARRAY",
    "double_array": "DOUBLE_ARRAY",
    "string_array": "STRING_ARRAY",
    "int_or_auto": "STRING",  # default "auto"; a file's integer is declared INTEGER from it
}


def declaration_plan(
    camera_names: Sequence[str], declared: Collection[str], target_names: Sequence[str] = ()
) -> list[tuple[str, str, Any, str]]:
    """Parameters still to declare: ``(name, ros_type_name, default_or_None, description)``.

    ``default`` is None when the parameter must be declared by type only (no default, an empty
    array, or a required parameter); otherwise a plain Python value of the right type.
    """
    plan = []
    for spec in parameter_specs(tuple(camera_names), tuple(target_names)):
        if spec.name in declared:
            continue
        default = spec.default
        if spec.required or default is None or (isinstance(default, tuple) and not default):
            default = None
        elif isinstance(default, tuple):
            default = list(default)
        doc = spec.doc + (" (required)" if spec.required else "") + " " + change_note(spec.name)
        plan.append((spec.name, ROS_TYPE_NAMES[spec.kind], default, doc))
    return plan


def change_note(name: str) -> str:
    """``[live: <effect>]`` or ``[restart to change]``, appended to each description."""
    effect = live_effect(name)
    return "[restart the node to change]" if effect is None else f"[live: {effect}]"


def _declare(node: Any, plan: list[tuple[str, str, Any, str]]) -> None:
    from rcl_interfaces.msg import ParameterDescriptor
    from rclpy.parameter import Parameter

    for name, type_name, default, doc in plan:
        value = default if default is not None else getattr(Parameter.Type, type_name)
        node.declare_parameter(name, value, ParameterDescriptor(description=doc))


def declare_parameters(node: Any) -> dict[str, Any]:
    """Declare the schema on ``node`` (see the module docstring) and return every parameter's
    value by name (``None`` for parameters declared by type only)."""
    declared = set(node.get_parameters_by_prefix("").keys())
    lists = ("cameras.names", "targets.names")
    _declare(node, [p for p in declaration_plan((), declared) if p[0] in lists])
    valid = []
    for list_name in lists:
        param = node.get_parameters_by_prefix("").get(list_name)
        value = None if param is None else param.value
        names = [str(n) for n in value] if isinstance(value, (list, tuple)) else []
        valid.append([n for n in names if is_valid_name(n)])  # invalid: reported by the config
    declared = set(node.get_parameters_by_prefix("").keys())
    _declare(node, declaration_plan(valid[0], declared, valid[1]))
    return {name: p.value for name, p in node.get_parameters_by_prefix("").items()}


def config_from_node(node: Any) -> CalibratorConfig:
    """Declare the parameters and validate them into a :class:`CalibratorConfig`.

    Raises ``ValueError`` naming the dotted parameter (see
    :meth:`CalibratorConfig.from_parameters`).
    """
    return CalibratorConfig.from_parameters(declare_parameters(node))

"""Reading a ROS 2 parameter file without ROS, as the ROS 2 parameter-file parser reads it."""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from ..errors import describe_os_error, describe_yaml_error
from .calibrator import CalibratorConfig
from .specs import DEFAULT_NODE_NAME

__all__ = ["flatten_parameters", "read_parameter_file", "load_config"]


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
        raise ValueError(f"config file {str(path)!r}: cannot read it "
                         f"({describe_os_error(exc)})") from None
    try:
        doc = yaml.load(text, Loader=_ParamLoader)  # noqa: S506 - SafeLoader subclass
    except yaml.YAMLError as exc:
        raise ValueError(f"config file {describe_yaml_error(path, exc)}") from None
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
    """Load and validate a configuration file without ROS (format: :mod:`rwhec_ros.config`).

    Raises ``ValueError`` naming the file and the dotted parameter for any problem.
    """
    flat = read_parameter_file(path, node_name)
    try:
        return CalibratorConfig.from_parameters(flat)
    except ValueError as exc:
        raise ValueError(f"config file {str(path)!r}: {exc}") from None

"""Reading a ROS 2 parameter file without ROS, as the ROS 2 parameter-file parser reads it."""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from .calibrator import CalibratorConfig
from .specs import DEFAULT_NODE_NAME

__all__ = [
    "flatten_parameters",
    "fully_qualified_name",
    "section_pattern",
    "matching_sections",
    "read_parameter_file",
    "load_config",
]


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


def fully_qualified_name(node_name: str = DEFAULT_NODE_NAME, namespace: str = "") -> str:
    """The node's fully qualified name as ROS forms it: ``/<namespace>/<node_name>``.

    A ``node_name`` that starts with ``/`` is taken as fully qualified already (``namespace``
    must then be empty). Raises ``ValueError`` for an empty name or a name with a wildcard.
    """
    name = str(node_name).strip()
    ns = str(namespace or "").strip().strip("/")
    if not name or not name.strip("/") or "*" in name or "*" in ns:
        raise ValueError(
            f"node name: expected a node name such as 'calibrator' or '/rig1/calibrator', "
            f"got node_name={node_name!r}, namespace={namespace!r}"
        )
    if name.startswith("/"):
        if ns:
            raise ValueError(
                f"node name: {node_name!r} is fully qualified; do not also give namespace "
                f"{namespace!r}"
            )
        return "/" + name.strip("/")
    return "/" + "/".join(part for part in (ns, name.strip("/")) if part)


def section_pattern(key: str) -> re.Pattern:
    """The regular expression ROS matches a parameter-file section key against.

    As rclpy/rclcpp do: the key gets a leading ``/``; ``/**`` stands for any number of
    namespace levels (``(/\\w+)*``) and ``/*`` for exactly one (``(/\\w+)``); the rest is
    literal and must match the whole fully qualified node name.
    """
    k = str(key)
    if not k.startswith("/"):
        k = "/" + k
    out, i = "", 0
    while i < len(k):
        if k.startswith("/**", i):
            out, i = out + r"(/\w+)*", i + 3
        elif k.startswith("/*", i):
            out, i = out + r"(/\w+)", i + 2
        else:
            out, i = out + re.escape(k[i]), i + 1
    return re.compile(out)


def matching_sections(keys: Sequence[str], fqn: str) -> list[str]:
    """The section keys of a parameter file that apply to the node ``fqn``, in file order (ROS
    applies them in this order: a later section overrides an earlier one)."""
    return [k for k in keys if section_pattern(k).fullmatch(fqn)]


def read_parameter_file(path: str | Path, node_name: str | None = None,
                        namespace: str = "") -> dict[str, Any]:
    """Read a ROS 2 parameter YAML and return the flat parameters of one node.

    The sections are chosen by ROS's own rule (:func:`section_pattern`): for the node
    ``/<namespace>/<node_name>`` every section whose key matches its fully qualified name applies,
    in file order, a later one overriding an earlier one. ``/**`` matches every node,
    ``/**/calibrator`` a ``calibrator`` in any namespace, ``calibrator`` (= ``/calibrator``) only
    the node without namespace and ``/rig1/calibrator`` only that one. ``node_name`` may also be
    fully qualified (``/rig1/calibrator``). With ``node_name=None`` and ``namespace`` empty, a
    file with exactly one section uses that section whatever its key; otherwise the node is
    :data:`DEFAULT_NODE_NAME` (``/calibrator``).
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
    if node_name is None and not namespace and len(keys) == 1:
        selected = keys
    else:
        fqn = fully_qualified_name(DEFAULT_NODE_NAME if node_name is None else node_name,
                                   namespace)
        selected = matching_sections(keys, fqn)
        if not selected:
            raise ValueError(
                f"config file {str(path)!r}: no section applies to node {fqn!r} (sections: "
                f"{keys}); ROS applies a section named '/**' (any node), "
                f"'/**/{fqn.rsplit('/', 1)[-1]}' (that name in any namespace) or {fqn!r}"
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


def load_config(path: str | Path, node_name: str | None = None,
                namespace: str = "") -> CalibratorConfig:
    """Load and validate a configuration file without ROS (format: :mod:`rwhec_ros.config`),
    with the sections that apply to the node ``/<namespace>/<node_name>``
    (:func:`read_parameter_file`).

    Raises ``ValueError`` naming the file and the dotted parameter for any problem.
    """
    flat = read_parameter_file(path, node_name, namespace)
    try:
        return CalibratorConfig.from_parameters(flat)
    except ValueError as exc:
        raise ValueError(f"config file {str(path)!r}: {exc}") from None

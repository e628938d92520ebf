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

from .specs import (
    ROS_MANAGED_PARAMETERS,
    ROS_MANAGED_PREFIXES,
    ParamSpec,
    global_spec,
    is_valid_name,
    parameter_specs,
)

__all__ = [
    "typed_parameters",
    "check_kind",
    "check_positive",
    "check_positive_int",
    "check_int_or_auto",
    "check_choice",
    "check_frame",
    "check_topic",
]

#: Parameters that no longer exist, and what replaced them (said when a file still sets one).
RETIRED_PARAMETERS = {
    "sync.max_pending_images": "retired (issue 39): images wait for their pose as long as the "
    "pose stream's measured lateness needs, bounded by sync.max_pose_wait_s and "
    "sync.max_waiting_mb; remove it from the file",
}

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
    names = _names(reader, "cameras.names")
    if len(names) == 0:
        raise ValueError("cameras.names: at least one camera is required, got []")
    targets = _names(reader, "targets.names")
    specs = {s.name: s for s in parameter_specs(names, targets)}
    unknown = sorted(k for k in params if k not in specs)
    if unknown:
        k = unknown[0]
        hint = difflib.get_close_matches(k, list(specs), n=3)
        more = f" (also unknown: {unknown[1:]})" if len(unknown) > 1 else ""
        hint_s = f"; did you mean {hint}?" if hint else ""
        for section, listed, what in (("cameras", names, "camera"),
                                      ("targets", targets, "target")):
            if k.startswith(section + ".") and k.split(".")[1] not in listed:
                hint_s += (f"; {what} {k.split('.')[1]!r} is not in {section}.names "
                           f"{list(listed)}")
        if k in RETIRED_PARAMETERS:
            hint_s = f"; {RETIRED_PARAMETERS[k]}"
        raise ValueError(f"{k}: unknown parameter (value {params[k]!r}){hint_s}{more}")
    v = {name: reader.get(s) for name, s in specs.items()}
    return v, names


def _names(reader: _Reader, param: str) -> tuple[str, ...]:
    """The names of ``cameras.names`` / ``targets.names``: valid parameter-name parts, unique."""
    names = tuple(reader.get(global_spec(param)))
    for i, n in enumerate(names):
        if not is_valid_name(n):
            raise ValueError(
                f"{param}[{i}]: {n!r} is not a valid name (letter, then letters, "
                "digits or '_')"
            )
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise ValueError(f"{param}: duplicated names {dup} in {list(names)}")
    return names


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
    elif kind == "int_or_auto":
        if isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)):
            return int(value)
        if isinstance(value, str) and value.strip().lower() == "auto":
            return "auto"
        raise ValueError(f"{name}: expected 'auto' or an integer, got {_show(value)}")
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


def check_positive(v: dict[str, Any], name: str, *, allow_zero: bool = False) -> float:
    """``v[name]`` if finite and > 0 (``>= 0`` with ``allow_zero``), else ``ValueError``."""
    x = v[name]
    ok = math.isfinite(x) and (x >= 0 if allow_zero else x > 0)
    if not ok:
        rel = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name}: must be finite and {rel}, got {x!r}")
    return x


def check_choice(v: dict[str, Any], name: str, choices: tuple[str, ...]) -> str:
    """``v[name]`` if it is one of ``choices``, else ``ValueError`` listing them."""
    if v[name] not in choices:
        raise ValueError(f"{name}: must be one of {list(choices)}, got {v[name]!r}")
    return v[name]


def check_frame(v: dict[str, Any], name: str, *, allow_empty: bool = False) -> str:
    """``v[name]`` if it is a valid tf frame name (or empty with ``allow_empty``)."""
    x = v[name]
    if x == "" and allow_empty:
        return x
    if not _FRAME_RE.match(x) or x.startswith("/"):
        raise ValueError(
            f"{name}: {x!r} is not a valid frame name (non-empty, no leading '/', letters, "
            "digits, '_', '-', '.', '/')"
        )
    return x


def check_topic(v: dict[str, Any], name: str) -> str:
    """``v[name]`` if it is a valid, non-empty ROS topic name."""
    x = v[name]
    if not x:
        raise ValueError(f"{name}: missing topic (empty string)")
    if not _TOPIC_RE.match(x) or "//" in x or x.endswith("/"):
        raise ValueError(f"{name}: {x!r} is not a valid ROS topic name")
    return x


def check_int_or_auto(v: dict[str, Any], name: str, minimum: int) -> int | str:
    """``v[name]`` if it is ``"auto"`` or an integer ``>= minimum``, else ``ValueError``."""
    if v[name] == "auto":
        return "auto"
    return check_positive_int(v, name, minimum)


def check_positive_int(v: dict[str, Any], name: str, minimum: int) -> int:
    """``v[name]`` if it is ``>= minimum``, else ``ValueError``."""
    if v[name] < minimum:
        raise ValueError(f"{name}: must be >= {minimum}, got {v[name]!r}")
    return v[name]

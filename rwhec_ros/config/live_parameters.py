"""Which parameters may change while the node runs, what a change does, and why the others may not.

``ros2 param set /calibrator solver.min_pairs 10`` reaches the node's parameter callback, which
asks :func:`review_changes`: a change of a *live* parameter (:data:`LIVE_PARAMETERS`) is
validated like a parameter file (same messages, naming the parameter) and, if valid, becomes the
node's new configuration, used from then on; any other change is refused with the reason
(``restart the node to change cameras.names: ...``), so nothing is ever silently accepted and
ignored. Setting a parameter to the value it already has is always accepted (``ros2 param load``
of the file the node was started with), and so are the parameters ROS itself manages
(``use_sim_time``, ``qos_overrides.*``).

What a live change does (the text also goes into the callback's answer and the log):

* ``solver.*``, ``priors.*``, ``accuracy.*`` -- used by the next ``calibrate`` (the three
  ``priors.*`` arrays are parallel: to add or remove a prior, set them together, atomically);
* ``noise.sigma``, ``noise.kappa`` -- given at once to every kept pair (unless
  ``noise.from_reprojection``, where they only fill in detections without their own precision),
  so the next ``calibrate``, ``save_dataset`` and ``/diagnostics`` use them (0: not stated,
  the start value); ``noise.estimate``, ``noise.groups`` -- used by the next ``calibrate`` and
  live re-solve;
* ``keyframe.min_rotation_rad``, ``keyframe.min_translation_m`` -- used for the pairs offered
  from now on (pairs already kept stay);
* ``output.*`` -- used by the next ``calibrate`` / ``save_dataset``;
* ``solver.live_period_s`` (0 turns the live re-solve off), ``convergence.*`` -- used by the next
  live re-solve (:mod:`rwhec_ros.session.live_solve`);
* ``capture.*`` -- used for the images from now on (:mod:`rwhec_ros.session.capture`), so an
  arm's operator can switch between continuous keyframing and ``~/capture``;
* ``check.*`` -- used by the next ``~/check`` (a new ``check.reference`` is read then, and the
  looks start again at 1).

Everything else is read once at start-up (subscriptions, queues, worker threads, detectors, the
frames of the problem) and needs a restart. A new parameter is restart-only until it is added to
:data:`LIVE_PARAMETERS` together with the code that applies it (the node's
``CalibrationSession.update_config``).
"""

from __future__ import annotations

import array
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from .calibrator import CalibratorConfig
from .specs import ROS_MANAGED_PARAMETERS, ROS_MANAGED_PREFIXES, parameter_specs

__all__ = [
    "LIVE_PARAMETERS",
    "RESTART_REASONS",
    "ParameterReview",
    "live_effect",
    "restart_reason",
    "review_changes",
    "restart_only_differences",
]

_NEXT_SOLVE = "used by the next calibrate"

#: Live parameter (exact name, or a section prefix ending in ``.``) -> what a change does.
LIVE_PARAMETERS: dict[str, str] = {
    "solver.": _NEXT_SOLVE,
    "solver.live_period_s": "used at once by the live re-solve (0 turns it off)",
    "convergence.": "used by the next live re-solve",
    "noise.sigma": "given to every kept pair now (unless noise.from_reprojection), so the next "
                   "calibrate uses it",
    "noise.kappa": "given to every kept pair now (unless noise.from_reprojection), so the next "
                   "calibrate uses it",
    "noise.estimate": "used by the next calibrate and live re-solve",
    "noise.groups": "used by the next calibrate and live re-solve",
    "keyframe.min_rotation_rad": "used for the pairs offered from now on",
    "keyframe.min_translation_m": "used for the pairs offered from now on",
    "priors.": _NEXT_SOLVE,
    "accuracy.": _NEXT_SOLVE,
    "capture.": "used for the images from now on (a running ~/capture keeps its cameras)",
    "check.": "used by the next ~/check (a new reference starts the looks again)",
    "output.directory": "used by the next calibrate and save_dataset",
    "output.": _NEXT_SOLVE,
}

#: Restart-only parameter (exact name or section prefix) -> why it needs a restart.
RESTART_REASONS: dict[str, str] = {
    "cameras.": "the camera list and the image subscriptions are set up at start-up",
    "pose_source.": "the pose subscription or tf lookup is set up at start-up",
    "camera_carrier.": "the frames of the problem are fixed at start-up",
    "tag_carrier.": "the frames of the problem are fixed at start-up",
    "tags.": "the tag detector and the tag frames are set up at start-up",
    "targets.": "the target detector and the target frames are set up at start-up",
    "detection.": "the tag detectors are built at start-up",
    "sync.": "the pose buffer, the image queue and the worker threads are created at start-up",
    "keyframe.max_pairs_per_edge": "the pair store is sized at start-up",
    "noise.from_reprojection": "it decides the precision stored with every pair",
    "ros.": "the subscriptions, their QoS and the timers are created at start-up",
}
_DEFAULT_REASON = "it is read once at start-up"


def _lookup(table: Mapping[str, str], name: str) -> str | None:
    """The entry of ``table`` for ``name``: its exact name first, then its longest prefix."""
    if name in table:
        return table[name]
    prefixes = [k for k in table if k.endswith(".") and name.startswith(k)]
    return table[max(prefixes, key=len)] if prefixes else None


def live_effect(name: str) -> str | None:
    """What a change of parameter ``name`` does while the node runs, or None if it needs a
    restart."""
    return _lookup(LIVE_PARAMETERS, str(name))


def restart_reason(name: str) -> str:
    """The refusal for a running node: ``restart the node to change <name>: <why>``."""
    why = _lookup(RESTART_REASONS, str(name)) or _DEFAULT_REASON
    return f"restart the node to change {name}: {why}"


def _is_ros_managed(name: str) -> bool:
    return name in ROS_MANAGED_PARAMETERS or name.startswith(ROS_MANAGED_PREFIXES)


def _plain(value: Any) -> Any:
    """Parameter values compared as plain Python: arrays (``array.array``, tuple) as lists."""
    if isinstance(value, (array.array, tuple, list)):
        return [_plain(v) for v in value]
    return value


def _same(a: Any, b: Any) -> bool:
    a, b = _plain(a), _plain(b)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return type(a) is type(b) and a == b


@dataclass(frozen=True)
class ParameterReview:
    """The verdict on a set of parameter changes.

    Attributes
    ----------
    accepted : bool
        True when the node may store the new values.
    reason : str
        Refusal: why (naming the parameter). Acceptance: what happens, one
        ``name=value (effect)`` per changed parameter, ``; ``-separated (empty when nothing
        changes).
    config : CalibratorConfig or None
        The configuration with the changes applied (the old one when nothing changes); None when
        refused.
    changed : tuple of str
        Names of the schema parameters whose value changes.
    """

    accepted: bool
    reason: str
    config: CalibratorConfig | None = None
    changed: tuple[str, ...] = ()


def review_changes(
    config: CalibratorConfig,
    changes: Mapping[str, Any],
    current: Mapping[str, Any] | None = None,
) -> ParameterReview:
    """Decide on setting the parameters ``changes`` (name -> new value) of a running node.

    Parameters
    ----------
    config : CalibratorConfig
        The node's configuration in use.
    changes : mapping of str to value
        The parameters being set, as ``rclpy.Parameter`` values (``array.array`` for numeric
        arrays, ``None`` for an unset value).
    current : mapping of str to value, optional
        The node's current parameter values (default ``config.to_parameters()``); a change to
        the current value is no change.

    Returns
    -------
    ParameterReview
        Refused, naming the first offending parameter, when a parameter is unknown, unset,
        restart-only (:func:`restart_reason`) or invalid (the message of
        :meth:`CalibratorConfig.from_parameters`); otherwise accepted with the new configuration.
    """
    current = config.to_parameters() if current is None else dict(current)
    known = {s.name for s in parameter_specs(config.camera_names)}
    effective: dict[str, Any] = {}
    for name, value in changes.items():
        name = str(name)
        if _is_ros_managed(name):
            continue
        if name not in known:
            return ParameterReview(False, f"{name}: not a parameter of this node")
        if name in current and _same(value, current[name]):
            continue
        if value is None:
            return ParameterReview(False, f"{name}: cannot be unset; {restart_reason(name)}")
        effective[name] = _plain(value)
    if not effective:
        return ParameterReview(True, "", config)
    for name in effective:
        if live_effect(name) is None:
            return ParameterReview(False, restart_reason(name))
    flat = config.to_parameters()
    flat.update(effective)
    try:
        new = CalibratorConfig.from_parameters(flat)
    except ValueError as exc:
        return ParameterReview(False, str(exc))
    reason = "; ".join(f"{n}={v!r} ({live_effect(n)})" for n, v in effective.items())
    return ParameterReview(True, reason, new, tuple(effective))


def restart_only_differences(old: CalibratorConfig, new: CalibratorConfig) -> list[str]:
    """Names of the restart-only parameters whose values differ between ``old`` and ``new``
    (empty when ``new`` may replace ``old`` in a running session)."""
    a, b = old.to_parameters(), new.to_parameters()
    names = sorted(set(a) | set(b))
    return [n for n in names
            if live_effect(n) is None and not _same(a.get(n), b.get(n))]

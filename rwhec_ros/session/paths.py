"""Where the calibrator writes: the output root of the node and of plain Python (CLI, tests).

``output.directory`` (a parameter) names the root under which every ``calibrate`` and
``save_dataset`` creates a new timestamped directory. Two front ends, two conventions:

* **the node** (:func:`node_output_root`) follows the ROS convention for files a node writes
  (logs go to ``$ROS_LOG_DIR``, else ``$ROS_HOME/log``): the root is ``$ROS_HOME/rwhec_ros``,
  with ``ROS_HOME`` defaulting to ``~/.ros``, so ``~/.ros/rwhec_ros/`` unless configured. A
  relative ``output.directory`` is taken under that root, never under the working directory,
  because the working directory of a node started by ``ros2 launch`` is wherever the launch
  command was typed. An absolute path (``~`` expanded) is used as given;
* **plain Python** (:func:`plain_output_root`: ``rwhec-calibrate``, :class:`CalibrationSession`
  without an explicit root) works like any command-line tool: a relative path is relative to the
  current directory and the empty default is ``./rwhec_output``.

The node names the absolute root in its start-up log, and the absolute directory of every write
in the service answers (:mod:`rwhec_ros.session.responses`).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

__all__ = [
    "DEFAULT_OUTPUT",
    "ROS_OUTPUT_SUBDIR",
    "ros_home",
    "node_output_root",
    "plain_output_root",
]

#: Output root of plain Python (CLI) when ``output.directory`` is empty: ``./rwhec_output``.
DEFAULT_OUTPUT = "rwhec_output"
#: Sub-directory of ``$ROS_HOME`` that holds the node's outputs.
ROS_OUTPUT_SUBDIR = "rwhec_ros"


def _absolute(path: Path, cwd: Path | None) -> Path:
    """``path`` made absolute against ``cwd`` (default: the current directory), normalised
    without resolving symbolic links."""
    base = Path(cwd) if cwd is not None else Path.cwd()
    return Path(os.path.normpath(path if path.is_absolute() else base / path))


def ros_home(environ: Mapping[str, str] | None = None, *, cwd: Path | None = None) -> Path:
    """The ROS home directory: ``$ROS_HOME`` if set and not empty (``~`` expanded), else
    ``~/.ros``, as ROS 2 itself resolves it (e.g. for ``$ROS_HOME/log``). Always absolute.

    Parameters
    ----------
    environ : mapping, optional
        Environment to read (default ``os.environ``); ``HOME`` in it is used for ``~``.
    cwd : Path, optional
        Directory a relative ``ROS_HOME`` is taken against (default: the current directory).
    """
    env = os.environ if environ is None else environ
    value = env.get("ROS_HOME", "")
    home = _expand_user(value, env) if value else _expand_user("~/.ros", env)
    return _absolute(home, cwd)


def _expand_user(value: str, env: Mapping[str, str]) -> Path:
    """``~`` expanded with ``env['HOME']`` when given, else the process's home directory."""
    if value == "~" or value.startswith("~/"):
        home = env.get("HOME") or os.path.expanduser("~")
        return Path(home + value[1:])
    return Path(os.path.expanduser(value))


def node_output_root(directory: str, environ: Mapping[str, str] | None = None, *,
                     cwd: Path | None = None) -> Path:
    """The node's absolute output root for ``output.directory = directory``.

    ``""`` -> ``$ROS_HOME/rwhec_ros`` (``~/.ros/rwhec_ros``); a relative path -> under that
    directory; an absolute path or one starting with ``~`` -> as given (``~`` expanded).

    Examples
    --------
    >>> str(node_output_root("", {"ROS_HOME": "/data/ros"}))
    '/data/ros/rwhec_ros'
    >>> str(node_output_root("rig1", {"ROS_HOME": "/data/ros"}))
    '/data/ros/rwhec_ros/rig1'
    >>> str(node_output_root("/mnt/calib", {"ROS_HOME": "/data/ros"}))
    '/mnt/calib'
    """
    env = os.environ if environ is None else environ
    base = ros_home(env, cwd=cwd) / ROS_OUTPUT_SUBDIR
    if not directory:
        return base
    path = _expand_user(str(directory), env)
    return _absolute(path, base)


def plain_output_root(directory: str) -> Path:
    """The output root of plain Python for ``output.directory = directory``: ``""`` ->
    ``rwhec_output``; otherwise the path as given (``~`` expanded; relative paths stay relative
    to the current directory)."""
    return Path(os.path.expanduser(str(directory) or DEFAULT_OUTPUT))

"""Console-script entry points of the node programs (``calibrator``, ``rwhec_demo_sim``).

They take SIGINT and SIGTERM over *before* importing the node (rclpy, tf2, OpenCV, SciPy: seconds
on a loaded machine): a signal while the program is still starting, e.g. ``ros2 launch``
stopped right after it started, ends the process at once with exit code 0; nothing of ROS exists
yet. (Before, Python's default handler raised ``KeyboardInterrupt`` in the middle of an import:
a traceback and exit code -2 under launch; and waiting for the imports to finish made launch
escalate to SIGTERM.) Once the program runs, :func:`rwhec_ros.ros.process.run_node_program`
installs its own handlers (a quiet, ordered stop). This module imports only the standard library
and :mod:`rwhec_ros.ros.process`.
"""

from __future__ import annotations

import os
import signal
from collections.abc import Sequence

from .process import EXIT_OK, STOP_SIGNALS

__all__ = ["calibrator", "demo_sim", "quit_while_starting"]


def quit_while_starting(signum, frame) -> None:
    """Signal handler of the start-up: leave at once, exit code 0 (no ROS context, no node, no
    thread, nothing written yet)."""
    os._exit(EXIT_OK)


def _take_signals() -> None:
    for s in STOP_SIGNALS:
        signal.signal(s, quit_while_starting)


def calibrator(args: Sequence[str] | None = None) -> int:
    """Console script ``calibrator`` (:func:`rwhec_ros.ros.node.main`)."""
    _take_signals()
    from .node import main

    return main(args)


def demo_sim(args: Sequence[str] | None = None) -> int:
    """Console script ``rwhec_demo_sim`` (:func:`rwhec_ros.ros.sim_node.main`)."""
    _take_signals()
    from .sim_node import main

    return main(args)

"""Moved to :mod:`rwhec_ros.messages` (the conversions need no rclpy); kept as an alias."""

from ..messages import *  # noqa: F403
from ..messages import __all__  # noqa: F401

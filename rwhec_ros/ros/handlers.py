"""Moved to :mod:`rwhec_ros.session.handlers` (the handlers need no rclpy); kept as an alias."""

from ..session.handlers import MessageHandlers

__all__ = ["MessageHandlers"]

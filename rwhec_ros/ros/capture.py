"""The node's ``~/capture`` service (``std_srvs/Trigger``): take one view now, for an arm.

Thin: the handler calls :meth:`CalibrationSession.capture
<rwhec_ros.session.capture.CaptureMixin.capture>` (each camera's next image whose pose has been
at rest for ``capture.rest_s``, at most ``capture.timeout_s``) and answers with
:func:`~rwhec_ros.session.capture.capture_message`: what every camera saw (targets with their
corners, pair kept or why not, rejections with the reason) and the identifiability of every edge
after it. ``success`` is true when every camera took a view. With ``capture.mode: continuous``
the answer says how to switch (``capture.mode`` is a live parameter).

The service has its own mutually exclusive callback group: a capture waits (up to
``capture.timeout_s``) while the images are examined on the detection threads, and must block
neither those nor ``calibrate``, ``~/reset`` and ``~/save_dataset``. Registered by
:func:`add_capture_service` from :class:`~rwhec_ros.ros.node.CalibratorNode`.
"""

from __future__ import annotations

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from std_srvs.srv import Trigger

from ..session.capture import capture_message

__all__ = ["add_capture_service", "handle_capture"]


def handle_capture(node, request, response):
    """``~/capture``: the session's capture, answered in words (module docstring)."""
    result = node.session.capture()
    response.success = bool(result.success)
    response.message = capture_message(result)
    log = node.get_logger().info if result.success else node.get_logger().warning
    log(f"capture: {response.message}")
    return response


def add_capture_service(node):
    """Register ``~/capture`` on ``node`` (a :class:`CalibratorNode`: ``session``,
    ``get_logger``) in its own callback group; returns the service."""
    group = MutuallyExclusiveCallbackGroup()
    return node.create_service(Trigger, "~/capture",
                               lambda request, response: handle_capture(node, request, response),
                               callback_group=group)

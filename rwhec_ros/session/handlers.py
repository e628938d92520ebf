"""Message handlers: convert one incoming message and delegate it to the session (no rclpy).

The node's subscription callbacks (and the CLI's ``bag`` replay) are one-line calls into
:class:`MessageHandlers`, which turns a message into numbers with :mod:`rwhec_ros.messages` and
calls the :class:`~rwhec_ros.session.CalibrationSession`. A message that cannot be converted
(NaN or zero quaternion, unknown image encoding, short buffer, undecodable or truncated JPEG/PNG,
invalid ``k``) is counted in the session (``bad_pose_message``, ``bad_camera_info_message``,
``bad_image_message``) and reported through ``on_warning``, never raised, so one bad message cannot
stop the node. Images are converted lazily: the session decodes only those its motion gate lets
through (:mod:`rwhec_ros.session.image_input`). Being free of
rclpy, the handlers are tested with ``rosbags`` messages.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ..messages import (
    camera_info_to_intrinsics,
    compressed_image_to_gray,
    image_to_gray,
    pose_stamped_to_transform,
    stamp_to_ns,
    transform_stamped_to_transform,
)
from .live import CalibrationSession
from .outcomes import ImageOutcome

__all__ = ["MessageHandlers", "LazyImage", "message_bytes"]


def message_bytes(msg: Any) -> int:
    """Bytes an image message holds (its ``data`` plus 1 kB for the rest); 1 kB when it has no
    ``data`` of a known length."""
    try:
        return len(msg.data) + 1024
    except (AttributeError, TypeError):
        return 1024


class LazyImage:
    """An image message decoded only when called (the session's motion gate decides), with the
    bytes it holds meanwhile (``nbytes``: the session's memory bound of waiting images)."""

    __slots__ = ("convert", "msg", "nbytes")

    def __init__(self, convert: Callable[[Any], np.ndarray], msg: Any) -> None:
        self.convert, self.msg = convert, msg
        self.nbytes = message_bytes(msg)

    def __call__(self) -> np.ndarray:
        return self.convert(self.msg)


class MessageHandlers:
    """Convert-and-delegate callbacks for one :class:`CalibrationSession`.

    Parameters
    ----------
    session : CalibrationSession
    on_warning : callable(str, str), optional
        Called as ``on_warning(key, text)`` for every rejected message (the node logs it with
        throttling per ``key``).
    """

    def __init__(
        self,
        session: CalibrationSession,
        on_warning: Callable[[str, str], None] | None = None,
    ) -> None:
        self.session = session
        self.on_warning = on_warning
        self._last_info: dict[str, tuple] = {}

    def _warn(self, key: str, text: str) -> None:
        self.session.record(key)
        if self.on_warning is not None:
            self.on_warning(key, text)

    def on_pose_stamped(self, msg: Any) -> bool:
        """A ``geometry_msgs/PoseStamped`` of the pose source; True when stored."""
        try:
            stamp_ns, frame_id, T = pose_stamped_to_transform(msg)
        except (ValueError, TypeError, AttributeError) as exc:
            self._warn("bad_pose_message", f"pose message rejected: {exc}")
            return False
        return self.session.add_pose(stamp_ns, T, source=frame_id)

    def on_transform_stamped(self, msg: Any) -> bool:
        """A ``geometry_msgs/TransformStamped`` ``T_parent_child`` of the pose source."""
        try:
            stamp_ns, parent, child, T = transform_stamped_to_transform(msg)
        except (ValueError, TypeError, AttributeError) as exc:
            self._warn("bad_pose_message", f"transform message rejected: {exc}")
            return False
        expected = self.session.config.pose_source
        if child and child != expected.child:
            self._warn("pose_rejected_child_frame",
                       f"transform child {child!r} is not pose_source.child {expected.child!r}")
            return False
        return self.session.add_pose(stamp_ns, T, source=parent)

    def on_camera_info(self, camera: str, msg: Any) -> bool:
        """A ``sensor_msgs/CameraInfo`` of ``camera``; converted only when its content changes."""
        try:
            key = (
                int(msg.width), int(msg.height), str(msg.distortion_model),
                tuple(float(v) for v in msg.k), tuple(float(v) for v in msg.d),
            )
        except (ValueError, TypeError, AttributeError) as exc:
            self._warn("bad_camera_info_message", f"camera_info of {camera!r} rejected: {exc}")
            return False
        if self._last_info.get(camera) == key and self.session.has_camera_info(camera):
            return True
        try:
            intrinsics = camera_info_to_intrinsics(msg)
        except (ValueError, TypeError, AttributeError) as exc:
            self._warn("bad_camera_info_message", f"camera_info of {camera!r} rejected: {exc}")
            return False
        ok = self.session.set_camera_info(camera, intrinsics)
        if ok:
            self._last_info[camera] = key
        return ok

    def on_image(
        self, camera: str, msg: Any, T_parent_child: np.ndarray | None = None, *,
        arrived_ns: int | None = None,
    ) -> ImageOutcome:
        """A ``sensor_msgs/Image`` of ``camera`` (call it off the executor thread: it detects).

        ``T_parent_child`` is the pose at the image stamp when the node looked it up on tf;
        ``arrived_ns`` when the message arrived, on the session's clock
        (:meth:`~rwhec_ros.session.CalibrationSession.image_arrival`; default now). The pixels
        are converted only when the session's motion gate lets the image through.
        """
        return self._image(camera, msg, image_to_gray, T_parent_child, arrived_ns)

    def on_compressed_image(
        self, camera: str, msg: Any, T_parent_child: np.ndarray | None = None, *,
        arrived_ns: int | None = None,
    ) -> ImageOutcome:
        """A ``sensor_msgs/CompressedImage`` of ``camera`` (JPEG, PNG; ``image_transport``'s
        ``compressed`` format strings), decoded with OpenCV only when the session's motion gate
        lets the image through; undecodable or truncated data is counted
        ``bad_image_message`` like a bad raw image."""
        return self._image(camera, msg, compressed_image_to_gray, T_parent_child, arrived_ns)

    def _image(self, camera: str, msg: Any, convert: Callable[[Any], np.ndarray],
               T_parent_child: np.ndarray | None, arrived_ns: int | None) -> ImageOutcome:
        try:
            stamp_ns = stamp_to_ns(msg.header.stamp)
        except (ValueError, TypeError, AttributeError) as exc:
            self._warn("bad_image_message", f"image of {camera!r} rejected: {exc}")
            return ImageOutcome(camera, -1, "rejected", reasons=["bad_image_message"])
        outcome = self.session.add_image(camera, stamp_ns, LazyImage(convert, msg),
                                         T_parent_child, arrived_ns=arrived_ns)
        if outcome.status == "rejected" and self.on_warning is not None:
            for reason in outcome.reasons:
                detail = f": {outcome.detail}" if outcome.detail else ""
                self.on_warning(reason,
                                f"image of {camera!r} at {stamp_ns} ns rejected: {reason}{detail}")
        return outcome

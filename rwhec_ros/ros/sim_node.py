"""``rwhec_demo_sim``: publishes the simulated rig of :mod:`rwhec_ros.simulation` (rclpy, Jazzy).

Topics (matching ``config/demo.yaml``): ``/demo/rig/pose`` (``geometry_msgs/PoseStamped``,
``header.frame_id = world``, the rig's pose ``T_world_rig`` as a motion-capture system would
publish it), and per camera ``/demo/<cam>/image_raw`` (``mono8`` ``sensor_msgs/Image``) and
``/demo/<cam>/camera_info``. For RViz it also broadcasts ``world -> rig`` on ``/tf`` and the TRUE
extrinsics on ``/tf_static`` as ``<cam>_optical_true`` (parent ``rig``) and ``tag_<j>_true`` /
``board_<j>_true`` (parent ``world``), to compare with the calibrator's ``*_calibrated`` frames
(:meth:`rwhec_ros.simulation.SimulatedRig.true_frames`).

Parameters: ``rate_hz`` (image rate, 5.0), ``pose_rate_hz`` (100.0), ``seed`` (0),
``pose_noise_m`` / ``pose_noise_rad`` (pose-stream noise per axis, 0.0005), ``image_noise_std``
(grey levels, 2.0), ``n_cameras`` (3), ``n_tags`` (6), ``boards`` (string array, default empty:
board ``boards[j]``, ``aprilgrid`` or ``charuco``, in place of tag ``j``, as the CLI demo's
``--board``; also ``chessboard``, ``circles``, ``asymmetric_circles``; ``['aprilgrid', 'charuco']``
is what ``config/demo_boards.yaml`` describes, ``['chessboard', 'circles', 'asymmetric_circles']``
``config/demo_grids.yaml``).
Rendering runs in its own callback group so the pose stream keeps its rate under the
``MultiThreadedExecutor``. No maths here: the model is
:func:`rwhec_ros.simulation.demo_board_rig`. Stopping (Ctrl-C, also under ``ros2 launch``) cancels
the timers and waits for a running callback before the node is destroyed
(:func:`rwhec_ros.ros.process.run_node_program`), so nothing publishes on a destroyed publisher.
"""

from __future__ import annotations

import sys
import threading

import numpy as np
import tf2_ros
from geometry_msgs.msg import PoseStamped, TransformStamped
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, Image

from ..messages import (
    fill_message,
    gray_to_image_fields,
    intrinsics_to_camera_info_fields,
    transform_to_pose_stamped_fields,
    transform_to_transform_stamped_fields,
)
from ..simulation import (
    DEMO_POSE_TOPIC,
    DEMO_RIG_FRAME,
    DEMO_SUPERSAMPLE,
    DEMO_WORLD_FRAME,
    demo_board_rig,
    demo_camera_topics,
)
from .process import rclpy_main

__all__ = ["DemoSimulatorNode", "main"]

#: Seconds ``executor.shutdown`` waits for a running render/publish callback when stopping.
EXECUTOR_SHUTDOWN_TIMEOUT_S = 2.0


class DemoSimulatorNode(Node):
    """Publishes poses, images and camera infos of the demo rig (see the module docstring)."""

    def __init__(self, node_name: str = "rwhec_demo_sim", **kwargs) -> None:
        super().__init__(node_name, **kwargs)
        self._stopping = threading.Event()
        rate = float(self.declare_parameter("rate_hz", 5.0).value)
        pose_rate = float(self.declare_parameter("pose_rate_hz", 100.0).value)
        seed = int(self.declare_parameter("seed", 0).value)
        self._pose_noise_m = float(self.declare_parameter("pose_noise_m", 0.0005).value)
        self._pose_noise_rad = float(self.declare_parameter("pose_noise_rad", 0.0005).value)
        self._image_noise = float(self.declare_parameter("image_noise_std", 2.0).value)
        n_cameras = int(self.declare_parameter("n_cameras", 3).value)
        n_tags = int(self.declare_parameter("n_tags", 6).value)
        # declared by type: an empty-list default would make it a BYTE_ARRAY (rclpy #912);
        # unset, its value is None
        boards = self.declare_parameter(
            "boards", Parameter.Type.STRING_ARRAY,
            ParameterDescriptor(description="board kinds (aprilgrid, charuco, chessboard, "
                                            "circles, asymmetric_circles) in place of tags "
                                            "0, 1, ... (default: none)")).value
        for name, value in (("rate_hz", rate), ("pose_rate_hz", pose_rate)):
            if not value > 0:
                raise ValueError(f"{name}: must be > 0, got {value!r}")
        self.rig = demo_board_rig(list(boards or ()), n_cameras, n_tags)
        self._pose_rng = np.random.default_rng(seed)
        self._image_rng = np.random.default_rng(seed + 1)
        self._t0_ns = self.get_clock().now().nanoseconds

        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                         history=HistoryPolicy.KEEP_LAST)
        self._pose_pub = self.create_publisher(PoseStamped, DEMO_POSE_TOPIC, qos)
        self._image_pubs = {}
        self._info_pubs = {}
        for cam in self.rig.cameras:
            image_topic, info_topic = demo_camera_topics(cam)
            self._image_pubs[cam] = self.create_publisher(Image, image_topic, qos)
            self._info_pubs[cam] = self.create_publisher(CameraInfo, info_topic, qos)
        self._tf = tf2_ros.TransformBroadcaster(self)
        self._static_tf = tf2_ros.StaticTransformBroadcaster(self)
        self._publish_truth()

        self._timers = [
            self.create_timer(1.0 / pose_rate, self._on_pose_timer,
                              callback_group=MutuallyExclusiveCallbackGroup()),
            self.create_timer(1.0 / rate, self._on_image_timer,
                              callback_group=MutuallyExclusiveCallbackGroup()),
        ]
        self.get_logger().info(
            f"demo rig: cameras {list(self.rig.cameras)}, targets "
            f"{list(self.rig.target_names())}, "
            f"images at {rate:g} Hz, poses at {pose_rate:g} Hz on {DEMO_POSE_TOPIC}"
        )

    def _sim_time(self, stamp_ns: int) -> float:
        return (stamp_ns - self._t0_ns) * 1e-9

    def _publish_truth(self) -> None:
        now = self.get_clock().now().nanoseconds
        self._static_tf.sendTransform([
            fill_message(TransformStamped(),
                         transform_to_transform_stamped_fields(T, parent, child, now))
            for parent, child, T in self.rig.true_frames()])

    def stop_activity(self) -> None:
        """Stop publishing: the timer callbacks return at once, those running return before
        publishing again (the timers are not cancelled: a task of a cancelled timer fails,
        see :meth:`rwhec_ros.ros.node.CalibratorNode.stop_activity`)."""
        self._stopping.set()

    def _on_pose_timer(self) -> None:
        if self._stopping.is_set():
            return
        stamp = self.get_clock().now().nanoseconds
        T = self.rig.pose_measurement(self._sim_time(stamp), self._pose_rng,
                                      self._pose_noise_m, self._pose_noise_rad)
        self._pose_pub.publish(fill_message(
            PoseStamped(), transform_to_pose_stamped_fields(T, DEMO_WORLD_FRAME, stamp)))
        self._tf.sendTransform(fill_message(
            TransformStamped(),
            transform_to_transform_stamped_fields(T, DEMO_WORLD_FRAME, DEMO_RIG_FRAME, stamp)))

    def _on_image_timer(self) -> None:
        if self._stopping.is_set():
            return
        stamp = self.get_clock().now().nanoseconds
        T_world_rig = self.rig.T_world_rig(self._sim_time(stamp))
        for cam in self.rig.cameras:
            gray = self.rig.render(cam, T_world_rig, self._image_rng,
                                   noise_std=self._image_noise,
                                   supersample=DEMO_SUPERSAMPLE, shift_pattern=True)
            if self._stopping.is_set():  # rendering takes a while: stop before publishing
                return
            frame = f"{cam}_optical"
            self._image_pubs[cam].publish(
                fill_message(Image(), gray_to_image_fields(gray, stamp, frame)))
            self._info_pubs[cam].publish(fill_message(
                CameraInfo(),
                intrinsics_to_camera_info_fields(self.rig.intrinsics[cam], stamp, frame)))


def main(args=None) -> int:
    """Console script ``rwhec_demo_sim`` (through :mod:`rwhec_ros.ros.entry`; stops cleanly:
    see :func:`rwhec_ros.ros.process.rclpy_main`)."""
    return rclpy_main("rwhec_demo_sim", DemoSimulatorNode, args,
                      shutdown_timeout_s=EXECUTOR_SHUTDOWN_TIMEOUT_S)


if __name__ == "__main__":
    sys.exit(main())

"""The ``calibrator`` node (rclpy, ROS 2 Jazzy): subscriptions, services, publishers; no maths.

Run::

    ros2 run rwhec_ros calibrator --ros-args --params-file config/<file>.yaml
    ros2 service call /calibrate std_srvs/srv/Trigger

Interfaces (relative names, so the node can be namespaced):

* subscribes ``cameras.<name>.image_topic`` (``sensor_msgs/Image``) and
  ``cameras.<name>.camera_info_topic`` (``sensor_msgs/CameraInfo``) with
  ``qos_profile_sensor_data`` (``ros.image_qos: reliable`` for a reliable subscription), and
  ``pose_source.topic`` (``geometry_msgs/PoseStamped``) or, with ``pose_source.type: tf``, looks
  ``T_parent_child`` up on tf at every image stamp (tf2 ``Buffer`` + ``TransformListener``);
* services ``calibrate``, ``~/reset``, ``~/save_dataset`` (``std_srvs/Trigger``);
* publishes the extrinsics on ``/tf_static`` (``StaticTransformBroadcaster``, child frames from
  the configuration; only the frames the verdict finds usable unless ``output.publish_unusable``,
  the others named in the ``calibrate`` response and the log), ``~/suboptimality_bound``
  (``std_msgs/Float64``) and ``~/result``
  (``std_msgs/String``, the result YAML), both transient local, and
  ``diagnostic_msgs/DiagnosticArray`` on ``/diagnostics`` (per-edge pairs and identifiability).

Threading: sensor callbacks (reentrant group) only convert cheap messages or enqueue images;
tag detection runs on a worker thread fed by a bounded drop-oldest queue; the services have their
own mutually exclusive group, so ``calibrate`` answers while data keep flowing under a
``MultiThreadedExecutor``. Everything else is delegated to
:class:`~rwhec_ros.session.CalibrationSession` through
:class:`~rwhec_ros.session.handlers.MessageHandlers`.
"""

from __future__ import annotations

import sys
import threading
import time

import rclpy
import tf2_ros
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped, TransformStamped
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.logging import get_logger
from rclpy.node import Node
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from rclpy.time import Time
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Float64, String
from std_srvs.srv import Trigger

from ..config import DEFAULT_NODE_NAME
from ..messages import (
    diagnostic_rows,
    fill_message,
    ns_to_stamp_fields,
    stamp_to_ns,
    transform_stamped_to_transform,
    transform_to_transform_stamped_fields,
)
from ..session import CalibrationSession, ImageQueue, MessageHandlers, QueueWorker
from .params import config_from_node

__all__ = ["CalibratorNode", "main"]

#: Seconds between two log lines of the same warning key.
WARN_THROTTLE_S = 5.0


class CalibratorNode(Node):
    """ROS 2 front end of a :class:`CalibrationSession` (see the module docstring).

    Parameters
    ----------
    node_name : str
    **kwargs
        Passed to :class:`rclpy.node.Node` (e.g. ``namespace``, ``parameter_overrides``,
        ``context``); ``automatically_declare_parameters_from_overrides`` defaults to True so
        that unknown names in the parameter file are reported instead of silently ignored.

    Raises
    ------
    ValueError
        Invalid configuration (naming the dotted parameter); the node is destroyed first.
    """

    def __init__(self, node_name: str = DEFAULT_NODE_NAME, **kwargs) -> None:
        kwargs.setdefault("automatically_declare_parameters_from_overrides", True)
        super().__init__(node_name, **kwargs)
        try:
            self.config = config_from_node(self)
        except ValueError:
            self.destroy_node()
            raise
        cfg = self.config
        self.session = CalibrationSession(cfg)
        self._warn_lock = threading.Lock()
        self._warn_last: dict[str, float] = {}
        self._warn_suppressed: dict[str, int] = {}
        self.handlers = MessageHandlers(self.session, on_warning=self._warn_throttled)

        self._sensor_group = ReentrantCallbackGroup()
        self._service_group = MutuallyExclusiveCallbackGroup()
        self._timer_group = MutuallyExclusiveCallbackGroup()

        # --- detection off the executor: bounded drop-oldest queue + worker thread ----------
        self._queue = ImageQueue(cfg.sync.image_queue_size)
        self._workers = [
            QueueWorker(
                self._queue, self._process_image, name=f"{node_name}-detection-{i}",
                on_error=lambda exc: self._warn_throttled(
                    "image_worker_error", f"image worker error: {type(exc).__name__}: {exc}"),
            ).start()
            for i in range(cfg.sync.detection_threads)
        ]

        # --- subscriptions ------------------------------------------------------------------------
        if cfg.ros.image_qos == "sensor_data":
            image_qos = qos_profile_sensor_data
        else:
            image_qos = QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE,
                                   history=HistoryPolicy.KEEP_LAST)
        for cam in cfg.cameras:
            self.create_subscription(
                Image, cam.image_topic,
                lambda msg, name=cam.name: self._on_image(name, msg),
                image_qos, callback_group=self._sensor_group,
            )
            self.create_subscription(
                CameraInfo, cam.camera_info_topic,
                lambda msg, name=cam.name: self.handlers.on_camera_info(name, msg),
                image_qos, callback_group=self._sensor_group,
            )
        self._tf_buffer = None
        self._tf_listener = None
        if cfg.pose_source.type == "topic":
            pose_qos = QoSProfile(depth=200, reliability=ReliabilityPolicy.BEST_EFFORT,
                                  history=HistoryPolicy.KEEP_LAST)
            self.create_subscription(
                PoseStamped, cfg.pose_source.topic, self.handlers.on_pose_stamped, pose_qos,
                callback_group=self._sensor_group,
            )
        else:
            self._tf_buffer = tf2_ros.Buffer(cache_time=Duration(seconds=30.0))
            self._tf_listener = tf2_ros.TransformListener(self._tf_buffer, self)

        # --- services -----------------------------------------------------------------------------
        self.create_service(Trigger, "calibrate", self._on_calibrate,
                            callback_group=self._service_group)
        self.create_service(Trigger, "~/reset", self._on_reset,
                            callback_group=self._service_group)
        self.create_service(Trigger, "~/save_dataset", self._on_save_dataset,
                            callback_group=self._service_group)

        # --- publishers ---------------------------------------------------------------------------
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                             reliability=ReliabilityPolicy.RELIABLE)
        self._bound_pub = self.create_publisher(Float64, "~/suboptimality_bound", latched)
        self._result_pub = self.create_publisher(String, "~/result", latched)
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._static_tf = tf2_ros.StaticTransformBroadcaster(self)
        self.create_timer(cfg.ros.diagnostics_period_s, self._publish_diagnostics,
                          callback_group=self._timer_group)
        self.get_logger().info(
            f"calibrating cameras {list(cfg.camera_names)} ({cfg.camera_carrier.frame}) and tags "
            f"{list(cfg.tags.ids)} ({cfg.tag_carrier.frame}); poses from "
            f"{cfg.pose_source.type} {cfg.pose_source.parent}->{cfg.pose_source.child}"
            + (f" on {cfg.pose_source.topic}" if cfg.pose_source.type == "topic" else "")
        )

    # --- logging ------------------------------------------------------------------------------
    def _warn_throttled(self, key: str, text: str) -> None:
        """Log ``text`` at warning level at most every WARN_THROTTLE_S seconds per ``key``."""
        now = time.monotonic()
        with self._warn_lock:
            last = self._warn_last.get(key)
            if last is not None and now - last < WARN_THROTTLE_S:
                self._warn_suppressed[key] = self._warn_suppressed.get(key, 0) + 1
                return
            self._warn_last[key] = now
            skipped = self._warn_suppressed.pop(key, 0)
        more = f" (+{skipped} similar suppressed)" if skipped else ""
        self.get_logger().warning(text + more)

    # --- sensor callbacks ---------------------------------------------------------------------
    def _on_image(self, camera: str, msg: Image) -> None:
        if not self._queue.put((camera, msg)):
            self.session.record("image_queue_dropped")

    def _process_image(self, item) -> None:
        """Worker thread: optional tf lookup at the image stamp, then convert + detect."""
        camera, msg = item
        T = None
        if self._tf_buffer is not None:
            T = self._lookup_pose(camera, msg)
            if T is None:
                return
        self.handlers.on_image(camera, msg, T)

    def _lookup_pose(self, camera: str, msg: Image):
        ps = self.config.pose_source
        try:
            stamp_ns = stamp_to_ns(msg.header.stamp)
            tfm = self._tf_buffer.lookup_transform(
                ps.parent, ps.child, Time(nanoseconds=stamp_ns),
                timeout=Duration(seconds=self.config.sync.tf_timeout_s),
            )
            return transform_stamped_to_transform(tfm)[3]
        except tf2_ros.TransformException as exc:
            self.session.record("no_tf_at_stamp")
            self._warn_throttled("no_tf_at_stamp",
                                 f"no tf {ps.parent}->{ps.child} for {camera}: {exc}")
        except ValueError as exc:
            self.session.record("bad_pose_message")
            self._warn_throttled("bad_pose_message", f"tf {ps.parent}->{ps.child}: {exc}")
        return None

    # --- services -----------------------------------------------------------------------------
    def _on_calibrate(self, request, response):
        outcome = self.session.calibrate()
        response.success = outcome.usable  # a result whose verdict is good or caution
        response.message = outcome.message
        if not outcome.success:
            self.get_logger().warning(f"calibrate: {outcome.message}")
            return response
        result, verdict = outcome.result, outcome.verdict
        self._bound_pub.publish(Float64(data=float(result.certificate.suboptimality_bound)))
        self._result_pub.publish(String(data=outcome.result_yaml))
        out = self.config.output
        left_out = self.session.left_out(result, verdict)
        if out.publish_tf and (result.certified or out.publish_uncertified):
            stamp = self.get_clock().now().nanoseconds
            msgs = [
                fill_message(TransformStamped(),
                             transform_to_transform_stamped_fields(T, parent, child, stamp))
                for parent, child, T in self.session.published_transforms(result, verdict)
            ]
            if msgs:
                self._static_tf.sendTransform(msgs)
            if left_out:
                response.message += "\nleft off /tf_static (not usable): " + "; ".join(
                    f"{k}: {v}" for k, v in left_out.items())
        elif out.publish_tf:
            response.message += "\nnot published on /tf_static (not certified)"
        log = self.get_logger().info if outcome.usable else self.get_logger().warning
        log(f"calibrate: {response.message}")
        return response

    def _on_reset(self, request, response):
        self.session.reset()
        response.success = True
        response.message = "session reset: poses, pairs and counters cleared"
        return response

    def _on_save_dataset(self, request, response):
        try:
            path = self.session.save_dataset()
        except (ValueError, OSError) as exc:
            response.success = False
            response.message = str(exc)
            return response
        response.success = True
        response.message = path
        return response

    # --- diagnostics --------------------------------------------------------------------------
    def _publish_diagnostics(self) -> None:
        counters = self.session.counters()
        counters["image_queue_length"] = len(self._queue)
        counters["image_queue_dropped_total"] = self._queue.dropped
        report = self.session.report()
        last = self.session.last_outcome
        calibration = None
        if last is not None and last.verdict is not None:
            calibration = (last.verdict.level, last.verdict.headline())
        rows = diagnostic_rows(
            self.session.diagnostics(), counters, prefix=self.get_name(),
            identifiable=None if report is None else bool(report.identifiable),
            verdict="" if report is None else str(report.verdict), calibration=calibration,
        )
        msg = DiagnosticArray()
        fill_message(msg.header, {"stamp": ns_to_stamp_fields(self.get_clock().now().nanoseconds)})
        for row in rows:
            msg.status.append(
                DiagnosticStatus(
                    level=bytes([row["level"]]),  # an octet: one-byte bytes on Jazzy
                    name=row["name"],
                    message=row["message"],
                    hardware_id=row["hardware_id"],
                    values=[KeyValue(key=k, value=v) for k, v in row["values"]],
                )
            )
        self._diag_pub.publish(msg)

    def destroy_node(self) -> None:
        for worker in getattr(self, "_workers", ()):
            worker.stop()
        super().destroy_node()


def main(args=None) -> int:
    """Console script ``calibrator``: init, spin a MultiThreadedExecutor, shut down cleanly."""
    rclpy.init(args=args)
    node = None
    code = 0
    try:
        node = CalibratorNode()
        executor = MultiThreadedExecutor()
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except ValueError as exc:  # invalid configuration: say which parameter, exit non-zero
        get_logger(DEFAULT_NODE_NAME).fatal(f"invalid configuration: {exc}")
        code = 2
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return code


if __name__ == "__main__":
    sys.exit(main())

"""The ``calibrator`` node (rclpy, ROS 2 Jazzy): subscriptions, services, publishers; no maths.

Run::

    ros2 run rwhec_ros calibrator --ros-args \
        --params-file $(ros2 pkg prefix --share rwhec_ros)/config/<file>.yaml
    ros2 service call /calibrate std_srvs/srv/Trigger

Interfaces (relative names, so the node can be namespaced):

* subscribes ``cameras.<name>.image_topic`` (``sensor_msgs/Image``; with
  ``cameras.<name>.image_transport: compressed`` ``sensor_msgs/CompressedImage`` on
  ``<image_topic>/compressed``) and ``cameras.<name>.camera_info_topic``
  (``sensor_msgs/CameraInfo``) with
  best effort like ``qos_profile_sensor_data`` (``ros.image_qos: reliable`` for a reliable
  subscription), history depth ``ros.image_queue_depth``, and
  ``pose_source.topic`` (``geometry_msgs/PoseStamped``) or, with ``pose_source.type: tf``, looks
  ``T_parent_child`` up on tf at every image stamp (tf2 ``Buffer`` + ``TransformListener``);
* services ``calibrate``, ``~/reset``, ``~/save_dataset``, ``~/capture`` and ``~/check``
  (``std_srvs/Trigger``; ``~/capture`` takes one view now, :mod:`rwhec_ros.ros.capture`;
  ``~/check`` tests the data against a stored calibration, :mod:`rwhec_ros.ros.check`);
* publishes the extrinsics on ``/tf_static`` (``StaticTransformBroadcaster``, child frames from
  the configuration; only the frames the verdict finds usable unless ``output.publish_unusable``,
  the others named in the ``calibrate`` response and the log), ``~/suboptimality_bound``
  (``std_msgs/Float64``) and ``~/result``
  (``std_msgs/String``, the result YAML), both transient local, ``~/estimate``
  (``std_msgs/String``, transient local: the running estimate of the live re-solve with every
  frame's uncertainty and the convergence verdict, the result YAML's schema; see
  :mod:`rwhec_ros.session.live_solve`), and
  ``diagnostic_msgs/DiagnosticArray`` on ``/diagnostics`` (session, live estimate (converged or
  not), one row per camera: received / dropped / skipped / searched and transport loss, one row
  per edge), and ``~/detections`` (``sensor_msgs/Image``, ``bgr8``: a searched camera image with
  every tag and board outlined and labelled, green when kept as a pair, orange with the reason
  otherwise, :mod:`rwhec_ros.vision.annotate`; all cameras on one topic, ``header.frame_id`` the
  camera's optical frame, at most ``ros.detections_rate_hz`` images per second and only while
  someone subscribes, so that it costs nothing otherwise).

Outputs go under ``$ROS_HOME/rwhec_ros`` (``~/.ros/rwhec_ros``) unless ``output.directory``
says otherwise (:mod:`rwhec_ros.session.paths`); the start-up log and every service answer name
the absolute directory (:mod:`rwhec_ros.session.responses`). ``ros2 param set`` of a live
parameter (``solver.*``, ``noise.sigma``/``kappa``, ``keyframe.min_*``, ``output.*``) takes effect
as :mod:`rwhec_ros.config.live_parameters` says; any other change is refused with the reason.
Start-up errors and Ctrl-C (also the double SIGINT of ``ros2 launch``) are handled by
:func:`rwhec_ros.ros.process.run_node_program`: one line, no traceback, exit code 0 on Ctrl-C.

Threading: sensor callbacks (reentrant group) only convert cheap messages or enqueue images;
tag detection runs on ``sync.detection_threads`` worker threads fed by a
:class:`~rwhec_ros.session.FairImageQueue` (one queue per camera, served round-robin, one image
per camera at a time, each held until the pose at its stamp has arrived or will not come: as long
as the pose stream's measured lateness needs, on the node's ROS clock, at most
``sync.max_pose_wait_s``, the waiting images within ``sync.max_waiting_mb``; a camera's backlog of
ready images bounded by ``sync.image_queue_size``, drop-oldest; docs/ros-transport.md);
the services have their own mutually exclusive group, so ``calibrate`` answers while data keep
flowing under a ``MultiThreadedExecutor``. The live re-solve runs on the session's own worker
thread; a timer in a separate mutually exclusive group (every :data:`LIVE_TICK_S`) only asks it
to start one when due (``solver.live_period_s``) and publishes each new estimate once.
Everything else is delegated to :class:`~rwhec_ros.session.CalibrationSession` through
:class:`~rwhec_ros.session.handlers.MessageHandlers`.
"""

from __future__ import annotations

import sys
import threading
import time

import tf2_ros
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped, TransformStamped
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from rclpy.time import Time
from sensor_msgs.msg import CameraInfo, CompressedImage, Image
from std_msgs.msg import Float64, String
from std_srvs.srv import Trigger

from ..config import DEFAULT_NODE_NAME
from ..config.live_parameters import review_changes
from ..core.noise.words import noise_values
from ..data.results import dump_document
from ..messages import (
    bgr_to_image_fields,
    diagnostic_rows,
    fill_message,
    ns_to_stamp_fields,
    stamp_to_ns,
    transform_stamped_to_transform,
    transform_to_transform_stamped_fields,
)
from ..session import CalibrationSession, FairImageQueue, MessageHandlers, QueueWorker
from ..session.camera_monitor import CameraDiagnostics
from ..session.handlers import message_bytes
from ..session.paths import node_output_root
from ..session.pose_loss import warn_row
from ..session.rate_gate import RateGate
from ..session.responses import (
    RESET_MESSAGE,
    calibrate_message,
    save_dataset_message,
    save_on_shutdown,
    should_publish_tf,
)
from ..vision.annotate import annotate_detections
from .capture import add_capture_service
from .check import add_check_service
from .params import config_from_node
from .process import rclpy_main

__all__ = ["CalibratorNode", "main"]

#: Seconds between two log lines of the same warning key.
WARN_THROTTLE_S = 5.0
#: Seconds the detection workers get, all together, to finish their image when the node stops
#: (``ros2 launch`` escalates to SIGTERM 5 s after SIGINT).
WORKER_STOP_TIMEOUT_S = 1.5
#: Period [s] of the live timer: it starts a due re-solve (``solver.live_period_s``, a live
#: parameter, is checked at every tick) and publishes a finished one on ``~/estimate``.
LIVE_TICK_S = 0.25


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
        self.output_root = node_output_root(cfg.output.directory)
        self.session = CalibrationSession(cfg, output_root=self.output_root,
                                          clock=lambda: self.get_clock().now().nanoseconds)
        self._stopping = False  # stop_activity began: workers leave rclpy alone
        self._warn_lock = threading.Lock()
        self._warn_last: dict[str, float] = {}
        self._warn_suppressed: dict[str, int] = {}
        self._live_converged = False
        self.handlers = MessageHandlers(self.session, on_warning=self._warn_throttled)

        self._sensor_group = ReentrantCallbackGroup()
        self._service_group = MutuallyExclusiveCallbackGroup()
        self._timer_group = MutuallyExclusiveCallbackGroup()
        self._live_group = MutuallyExclusiveCallbackGroup()

        # --- detection off the executor: per-camera drop-oldest queues + worker threads -------
        # Images wait in the queue (undecoded) until the session has the pose at their stamp (or
        # knows it will not come), within sync.max_waiting_mb; a camera whose backlog of ready
        # images is full drops first an image the motion gate would skip anyway.
        ready = None if cfg.pose_source.type == "tf" else self._pose_ready
        self._queue = FairImageQueue(
            cfg.camera_names, cfg.sync.image_queue_size, ready=ready,
            expendable=self._gate_would_skip, weight=lambda item: message_bytes(item[0]),
            max_bytes=int(cfg.sync.max_waiting_mb * 1e6), on_drop=self._on_queue_drop)
        self._camera_diagnostics = CameraDiagnostics(cfg.camera_names)
        self._workers = [
            QueueWorker(
                self._queue, self._process_image, name=f"{node_name}-detection-{i}",
                on_error=lambda exc: self._warn_throttled(
                    "image_worker_error", f"image worker error: {type(exc).__name__}: {exc}"),
            ).start()
            for i in range(cfg.detection_thread_count())
        ]

        # --- subscriptions ------------------------------------------------------------------------
        # qos_profile_sensor_data (best effort, volatile, keep last) with the configured depth
        reliability = (qos_profile_sensor_data.reliability if cfg.ros.image_qos == "sensor_data"
                       else ReliabilityPolicy.RELIABLE)
        image_qos = QoSProfile(depth=cfg.ros.image_queue_depth, reliability=reliability,
                               durability=DurabilityPolicy.VOLATILE,
                               history=HistoryPolicy.KEEP_LAST)
        for cam in cfg.cameras:
            compressed = cam.image_transport == "compressed"
            self.create_subscription(
                CompressedImage if compressed else Image, cam.subscribed_topic,
                lambda msg, name=cam.name, c=compressed: self._on_image(name, msg, c),
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
                PoseStamped, cfg.pose_source.topic, self._on_pose, pose_qos,
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
        add_capture_service(self)  # ~/capture (rwhec_ros.ros.capture): one view now, for arms
        self._bringup = add_check_service(self)  # ~/check (rwhec_ros.ros.check): bring-up

        # --- publishers ---------------------------------------------------------------------------
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                             reliability=ReliabilityPolicy.RELIABLE)
        self._bound_pub = self.create_publisher(Float64, "~/suboptimality_bound", latched)
        self._result_pub = self.create_publisher(String, "~/result", latched)
        self._estimate_pub = self.create_publisher(String, "~/estimate", latched)
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._detections_gate = RateGate(cfg.ros.detections_rate_hz)
        self._detections_pub = None
        if cfg.ros.detections_rate_hz > 0:
            self._detections_pub = self.create_publisher(
                Image, "~/detections", QoSProfile(depth=2, reliability=ReliabilityPolicy.RELIABLE,
                                                  history=HistoryPolicy.KEEP_LAST))
        self._static_tf = tf2_ros.StaticTransformBroadcaster(self)
        self._diag_timer = self.create_timer(cfg.ros.diagnostics_period_s,
                                             self._publish_diagnostics,
                                             callback_group=self._timer_group)
        self._live_timer = self.create_timer(LIVE_TICK_S, self._on_live_tick,
                                             callback_group=self._live_group)

        # --- run-time parameter changes (after every declaration: declaring calls these too) --
        self.add_on_set_parameters_callback(self._on_set_parameters)
        post = getattr(self, "add_post_set_parameters_callback", None)  # rclpy >= Iron
        self._apply_in_post_set = post is not None
        if post is not None:
            post(self._on_parameters_set)
        self.get_logger().info(
            f"calibrating cameras {list(cfg.camera_names)} ({cfg.camera_carrier.frame}) and "
            f"targets {list(cfg.x_names)} ({cfg.tag_carrier.frame}); poses from "
            f"{cfg.pose_source.type} {cfg.pose_source.parent}->{cfg.pose_source.child}"
            + (f" on {cfg.pose_source.topic}" if cfg.pose_source.type == "topic" else "")
            + f"; outputs under {self.output_root}"
        )

    # --- logging ------------------------------------------------------------------------------
    def _warn_throttled(self, key: str, text: str) -> None:
        """Log ``text`` at warning level at most every WARN_THROTTLE_S seconds per ``key`` (not
        while stopping: a worker finishing its image then leaves rclpy alone)."""
        if self._stopping:
            return
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

    # --- parameters ---------------------------------------------------------------------------
    def _review(self, params):
        """The verdict on setting ``params`` against the configuration in use."""
        return review_changes(self.config, {p.name: p.value for p in params})

    def _on_set_parameters(self, params):
        """Before rclpy stores new values: accept live parameters (validated), refuse the others
        with the reason (``restart the node to change ...``)."""
        from rcl_interfaces.msg import SetParametersResult

        review = self._review(params)
        if not review.accepted:
            self.get_logger().warning(f"parameter change refused: {review.reason}")
        elif not self._apply_in_post_set:
            self._apply(review)
        return SetParametersResult(successful=review.accepted, reason=review.reason)

    def _on_parameters_set(self, params) -> None:
        """After rclpy stored accepted values (every callback agreed): use them."""
        review = self._review(params)
        if review.accepted:
            self._apply(review)

    def _apply(self, review) -> None:
        if not review.changed:
            return
        cfg = review.config
        root = node_output_root(cfg.output.directory)
        try:
            self.session.update_config(cfg, output_root=root)
        except ValueError as exc:  # cannot happen after review_changes; never crash a callback
            self.get_logger().error(f"parameter change not applied: {exc}")
            return
        self.config, self.output_root = cfg, root
        self.get_logger().info(f"parameters changed: {review.reason}"
                               + (f"; outputs under {root}"
                                  if "output.directory" in review.changed else ""))

    # --- sensor callbacks ---------------------------------------------------------------------
    def _on_pose(self, msg: PoseStamped) -> None:
        self.handlers.on_pose_stamped(msg)
        self._queue.notify()  # images waiting for this pose may go now

    def _on_image(self, camera: str, msg, compressed: bool) -> None:
        try:
            stamp_ns = stamp_to_ns(msg.header.stamp)
        except (ValueError, TypeError, AttributeError):
            stamp_ns = arrived = None  # rejected and counted by the handlers
        else:
            self._camera_diagnostics.record(camera, stamp_ns)
            stamp_ns = self.session.pose_time(camera, stamp_ns)  # + sync.time_offset.<camera>
            arrived = self.session.image_arrival(stamp_ns)
        if not self._queue.put(camera, (msg, stamp_ns, compressed, arrived)):
            self.session.record("image_queue_dropped")

    def _on_queue_drop(self, camera: str, item, waiting: bool) -> None:
        """The queue dropped an image for memory (``sync.max_waiting_mb``): one that waited for
        its pose is an image without a pose, one ready a detection backlog drop."""
        if waiting:
            self.session.record_no_pose(camera, "wait_memory")
        else:
            self.session.record("image_queue_dropped")

    def _pose_ready(self, item) -> bool:
        stamp_ns, arrived = item[1], item[3]
        return stamp_ns is None or self.session.pose_ready(stamp_ns, arrived)

    def _gate_would_skip(self, camera: str, item) -> bool:
        stamp_ns = item[1]
        return stamp_ns is not None and self.session.gate_would_skip(camera, stamp_ns)

    def _process_image(self, entry) -> None:
        """Worker thread: optional tf lookup at the image stamp, then gate, decode, detect."""
        camera, (msg, _, compressed, arrived) = entry
        if self._stopping:
            return
        T = None
        if self._tf_buffer is not None:
            T = self._lookup_pose(camera, msg)
            if T is None:
                return
        if compressed:
            outcome = self.handlers.on_compressed_image(camera, msg, T, arrived_ns=arrived)
        else:
            outcome = self.handlers.on_image(camera, msg, T, arrived_ns=arrived)
        self._publish_detections(camera, outcome)

    def _publish_detections(self, camera: str, outcome) -> None:
        """``~/detections``: the searched image annotated, rate-limited, only when subscribed."""
        pub = self._detections_pub
        if (self._stopping or pub is None or outcome is None
                or getattr(outcome, "detection", None) is None
                or outcome.image is None or pub.get_subscription_count() == 0
                or not self._detections_gate.take()):
            return
        try:
            bgr = annotate_detections(outcome.image, outcome.detection, outcome.kept,
                                      title=camera)
            stamp = self.session.image_time(camera, outcome.stamp_ns)  # the image's own stamp
            fields = bgr_to_image_fields(bgr, stamp, self.config.camera(camera).frame)
            pub.publish(fill_message(Image(), fields))
        except Exception as exc:  # noqa: BLE001 - a drawing problem never stops detection
            self._warn_throttled("detections_image", f"~/detections not published: "
                                 f"{type(exc).__name__}: {exc}")

    def _lookup_pose(self, camera: str, msg):
        ps = self.config.pose_source
        try:
            stamp_ns = stamp_to_ns(msg.header.stamp)  # + sync.time_offset.<camera>
            stamp_ns += int(round(self.config.sync.time_offset_s(camera) * 1e9))
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
        out = self.config.output
        response.success = outcome.usable  # a result whose verdict is good or caution
        if not outcome.success:
            response.message = calibrate_message(outcome, out, published=False)
            self.get_logger().warning(f"calibrate: {response.message}")
            return response
        result, verdict = outcome.result, outcome.verdict
        self._bound_pub.publish(Float64(data=float(result.certificate.suboptimality_bound)))
        self._result_pub.publish(String(data=outcome.result_yaml))
        published = should_publish_tf(outcome, out)
        left_out = self.session.left_out(result, verdict)
        if published:
            stamp = self.get_clock().now().nanoseconds
            msgs = [
                fill_message(TransformStamped(),
                             transform_to_transform_stamped_fields(T, parent, child, stamp))
                for parent, child, T in self.session.published_transforms(result, verdict)
            ]
            if msgs:
                self._static_tf.sendTransform(msgs)
        response.message = calibrate_message(outcome, out, published=published,
                                             left_out=left_out)
        log = self.get_logger().info if outcome.usable else self.get_logger().warning
        log(f"calibrate: {response.message}")
        return response

    def _on_reset(self, request, response):
        self.session.reset()
        response.success = True
        response.message = RESET_MESSAGE
        return response

    def _on_save_dataset(self, request, response):
        try:
            path = self.session.save_dataset()
        except (ValueError, OSError) as exc:
            response.success = False
            response.message = str(exc)
            return response
        response.success = True
        response.message = save_dataset_message(path)
        self.get_logger().info(f"save_dataset: {response.message}")
        return response

    # --- live estimate ------------------------------------------------------------------------
    def _on_live_tick(self) -> None:
        """Start a due live re-solve (returns at once) and publish a new estimate once, while
        ``~/estimate`` has a subscriber (without one the YAML is never built; the latest
        estimate is published when one appears)."""
        if self._stopping:
            return
        live = self.session.live
        live.tick()
        if self._estimate_pub.get_subscription_count() == 0:
            return
        est = live.take_new()
        if est is None:
            return
        try:
            text = dump_document(est.document)
        except Exception as exc:  # noqa: BLE001 - never into the executor
            self._warn_throttled("live_estimate", f"live estimate not published: "
                                 f"{type(exc).__name__}: {exc}")
            return
        self._estimate_pub.publish(String(data=text))
        if est.converged and not self._live_converged:
            self.get_logger().info(f"live estimate {est.line()}; call calibrate to publish it")
        self._live_converged = est.converged

    # --- diagnostics --------------------------------------------------------------------------
    def _publish_diagnostics(self) -> None:
        if self._stopping:
            return
        counters = self.session.counters()
        counters["image_queue_length"] = len(self._queue)
        counters["image_queue_dropped_total"] = self._queue.dropped
        report = self.session.report()
        last = self.session.last_outcome
        calibration, accuracy = None, ()
        if last is not None and last.verdict is not None:
            calibration = (last.verdict.level, last.verdict.headline())
        if last is not None and last.accuracy is not None:
            accuracy = last.accuracy.diagnostic_values()
        if last is not None and getattr(last, "time_offsets", None) is not None:
            accuracy = [*accuracy, *last.time_offsets.diagnostic_values()]
        if last is not None and last.verdict is not None and last.verdict.exclusion is not None:
            accuracy = [*accuracy, *last.verdict.exclusion.diagnostic_values()]
        if last is not None and last.result is not None:  # the noise the data fit, per camera
            accuracy = [*accuracy, *noise_values(getattr(last.result, "noise", None))]
        rows = diagnostic_rows(
            self.session.diagnostics(), counters, prefix=self.get_name(),
            identifiable=None if report is None else bool(report.identifiable),
            verdict="" if report is None else str(report.verdict), calibration=calibration,
            accuracy=accuracy,
        )
        cameras = self._camera_diagnostics.rows(
            self.session.camera_counters(), self._queue.stats(), prefix=self.get_name(),
            no_pose=self.session.no_pose_counts())
        session_row = warn_row(rows[0], self._camera_diagnostics.no_pose.problem())
        session_row["values"] = list(session_row["values"]) + self.session.pose_wait_values()
        rows[0] = session_row
        rows[1:1] = [self.session.live.status().diagnostic_row(self.get_name())]
        rows[2:2] = cameras
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

    def stop_activity(self) -> None:
        """Stop the timer callbacks, the detection workers and the live re-solve (before the
        executor and the node go away, while the context is valid): the images still queued are
        dropped, not examined, and the workers finish the image they are on within
        :data:`WORKER_STOP_TIMEOUT_S` (all together); meanwhile they neither log nor publish.
        The timers are not cancelled (a timer cancelled while the executor holds a task of it
        makes that task fail: ``failed to call timer: timer is canceled`` on stderr at exit):
        their callbacks return at once, ``executor.shutdown`` waits for them, ``destroy_node``
        destroys them."""
        self._stopping = True
        workers = getattr(self, "_workers", ())
        for worker in workers:
            worker.request_stop()
        queue = getattr(self, "_queue", None)
        if queue is not None:
            queue.discard()
            queue.close()
        deadline = time.monotonic() + WORKER_STOP_TIMEOUT_S
        for worker in workers:
            worker.join(max(0.0, deadline - time.monotonic()))
        if getattr(self, "_bringup", None) is not None:
            self._bringup.stop()
        session = getattr(self, "session", None)
        if session is not None:
            session.close()
            save_on_shutdown(session, self.get_logger())  # pairs never lost at shutdown

    def destroy_node(self) -> None:
        self.stop_activity()
        super().destroy_node()


#: Seconds ``executor.shutdown`` waits for running callbacks (e.g. a solve) when stopping;
#: ``ros2 launch`` escalates to SIGTERM after 5 s.
EXECUTOR_SHUTDOWN_TIMEOUT_S = 3.0


def main(args=None) -> int:
    """Console script ``calibrator`` (through :mod:`rwhec_ros.ros.entry`): init, spin a
    MultiThreadedExecutor, stop cleanly (:func:`rwhec_ros.ros.process.rclpy_main`)."""
    return rclpy_main(DEFAULT_NODE_NAME, CalibratorNode, args,
                      shutdown_timeout_s=EXECUTOR_SHUTDOWN_TIMEOUT_S)


if __name__ == "__main__":
    sys.exit(main())

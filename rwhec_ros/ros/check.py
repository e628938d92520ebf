"""The node's bring-up check: the ``~/check`` service (``std_srvs/Trigger``) and its
``/diagnostics`` rows. Thin: the check is :class:`~rwhec_ros.session.bringup.BringupCheck` on the
session's pairs, the words and files :mod:`rwhec_ros.session.bringup_outputs`.

* ``~/check``: the pairs so far against ``check.reference`` (a file, or ``tf``: each configured
  frame looked up now as ``T_<carrier>_<frame>``, e.g. from robot_state_publisher and the URDF);
  ``success`` is true when every camera is consistent and the verdict usable; the message is the
  answer (``CHECK MOVED: cam1: MOVED by 5.1 +- 0.3 mm ...``, the verdict, one line per camera)
  and the absolute output directory (``check_<UTC stamp>`` under the output root: check.yaml,
  the reference frames with the moved ones re-estimated as launch file, URDF snippet and
  frames.yaml, the data set). The re-estimated frames go to ``/tf_static`` (its own
  broadcaster) when ``output.publish_tf`` and the verdict finds them usable.
* ``/diagnostics``: a ``<node>: check`` row and one ``<node>: check <camera>`` row per camera
  (OK consistent, ERROR moved, WARN not enough data yet), every ``ros.diagnostics_period_s``.
* ``check.period_s`` > 0 (live): the node also checks that often while new pairs arrive (each
  a new look; the false-alarm rate is spent over the looks).

Registered by :func:`add_check_service` from :class:`~rwhec_ros.ros.node.CalibratorNode`; its
callbacks have their own mutually exclusive group.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import tf2_ros
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import TransformStamped
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.duration import Duration
from rclpy.time import Time
from std_srvs.srv import Trigger

from ..data.reference import read_reference, reference_from_transforms
from ..data.results import FrameNaming, new_output_dir
from ..messages import (
    fill_message,
    ns_to_stamp_fields,
    transform_stamped_to_transform,
    transform_to_transform_stamped_fields,
)
from ..session.bringup import (
    BringupCheck,
    CheckOptions,
    reference_lookup_names,
    session_problem,
)
from ..session.bringup_outputs import check_message, check_rows, check_transforms
from ..session.solving import verdict_options

__all__ = ["NodeCheck", "add_check_service", "check_options", "PERIOD_TICK_S"]

#: Seconds between two looks at ``check.period_s`` (a live parameter: read at every tick).
PERIOD_TICK_S = 0.5


def check_options(config) -> CheckOptions:
    """The node's :class:`CheckOptions` from ``check.*`` (sequential: the node looks again)."""
    from ..core.analysis.change import ChangeTolerance

    c = config.check
    return CheckOptions(tolerance=ChangeTolerance(c.tolerance_translation_m,
                                                  c.tolerance_rotation_deg),
                        false_alarm_rate=c.false_alarm_rate, hold=c.hold, noise=c.noise,
                        sequential=True, mode=config.solver.mode)


class NodeCheck:
    """The check's state on one node (module docstring)."""

    def __init__(self, node) -> None:
        self.node = node
        self._lock = threading.Lock()
        self._check: BringupCheck | None = None
        self._key = None
        self._waiting = ""
        self._tf_buffer = getattr(node, "_tf_buffer", None)
        self._tf_listener = None
        if self._tf_buffer is None and node.config.check.reference == "tf":
            self._tf_buffer = tf2_ros.Buffer(cache_time=Duration(seconds=10.0))
            self._tf_listener = tf2_ros.TransformListener(self._tf_buffer, node)
        self._static_tf = tf2_ros.StaticTransformBroadcaster(node)
        group = MutuallyExclusiveCallbackGroup()
        self.service = node.create_service(Trigger, "~/check", self.handle, callback_group=group)
        self._diag_pub = node.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._diag_timer = node.create_timer(node.config.ros.diagnostics_period_s,
                                             self.publish_diagnostics, callback_group=group)
        self._last_periodic = time.monotonic()
        self._stopping = False
        self._period_timer = node.create_timer(PERIOD_TICK_S, self._periodic,
                                               callback_group=group)

    # --- the reference ----------------------------------------------------------------------
    def _reference(self):
        config = self.node.config
        c = config.check
        if not c.reference:
            raise ValueError("no reference: set check.reference (a result.yaml, frames.yaml or "
                             "URDF file, or tf)")
        names = reference_lookup_names(config)
        if c.reference != "tf":
            return read_reference(Path(c.reference).expanduser(), names)
        if self._tf_buffer is None:
            self._tf_buffer = tf2_ros.Buffer(cache_time=Duration(seconds=10.0))
            self._tf_listener = tf2_ros.TransformListener(self._tf_buffer, self.node)
        found = []
        for _name, (carrier, children) in names.items():
            for child in children:
                try:
                    tfm = self._tf_buffer.lookup_transform(carrier, child, Time(),
                                                           timeout=Duration(seconds=0.2))
                except tf2_ros.TransformException:
                    continue
                found.append((carrier, child, transform_stamped_to_transform(tfm)[3]))
                break
        return reference_from_transforms(found, names, "tf")

    def _checker(self) -> BringupCheck:
        """The check of the current configuration (a new one, looks from 1, when ``check.*``
        or the reference changed)."""
        config = self.node.config
        key = (config.check, config.solver.mode)
        if self._check is None or key != self._key:
            self._check = BringupCheck(self._reference(), check_options(config))
            self._key = key
        return self._check

    # --- checking ---------------------------------------------------------------------------
    def run(self):
        """One look at the session's pairs: the report, or None and why not."""
        config = self.node.config
        problem, version, why = session_problem(self.node.session)
        if problem is None:
            return None, why
        checker = self._checker()
        naming = FrameNaming.from_config(config)
        carriers = (config.camera_carrier.frame, config.tag_carrier.frame)
        report = checker.check(problem, version=version, expected_cameras=config.camera_names,
                               thresholds=verdict_options(config.verdict), carriers=carriers)
        return report, naming

    def handle(self, request, response):
        """``~/check``: one look, the answer in words, the files, the re-estimated frames on
        ``/tf_static``."""
        log = self.node.get_logger()
        with self._lock:
            try:
                report, naming = self.run()
            except Exception as exc:  # noqa: BLE001 - answered in words, the node keeps running
                self._waiting = f"check failed: {type(exc).__name__}: {exc}"
                response.success, response.message = False, self._waiting
                log.warning(f"check: {response.message}")
                return response
            if report is None:
                self._waiting = naming
                response.success, response.message = False, naming
                return response
            message = check_message(report)
            try:
                out = self._write(report, naming)
                message += f"\noutput directory: {Path(out).resolve()}"
            except OSError as exc:
                message += f"\nWRITING THE OUTPUTS FAILED: {exc}"
            self._publish_updated(report, naming)
        response.success = bool(report.status == "consistent" and (
            report.verdict is None or report.verdict.usable))
        response.message = message
        (log.info if response.success else log.warning)(f"check: {message}")
        return response

    def _write(self, report, naming) -> Path:
        from ..session.bringup_outputs import write_check_outputs

        session = self.node.session
        out = new_output_dir(session.output_root, "check")
        write_check_outputs(out, report, naming, config=self.node.config.to_parameters(),
                            source={"type": "session", "reference": report.reference.source})
        try:
            session.save_dataset(out / "dataset.yaml")
        except ValueError:
            pass
        return out

    def _publish_updated(self, report, naming) -> None:
        if not report.updated or not self.node.config.output.publish_tf:
            return
        transforms, _ = check_transforms(report, naming)
        children = {naming.frames[n][1] for n in report.updated}
        stamp = self.node.get_clock().now().nanoseconds
        msgs = [fill_message(TransformStamped(),
                             transform_to_transform_stamped_fields(T, parent, child, stamp))
                for parent, child, T in transforms if child in children]
        if msgs:
            self._static_tf.sendTransform(msgs)

    def _periodic(self) -> None:
        """Every :data:`PERIOD_TICK_S`: a look when ``check.period_s`` (live) has passed."""
        if self._stopping:
            return
        c = self.node.config.check
        now = time.monotonic()
        if c.period_s <= 0 or now - self._last_periodic < c.period_s or not c.reference:
            return
        self._last_periodic = now
        with self._lock:
            try:
                report, why = self.run()
                if report is None:
                    self._waiting = why
            except Exception as exc:  # noqa: BLE001 - shown on /diagnostics, never raised
                self._waiting = f"check failed: {type(exc).__name__}: {exc}"

    def publish_diagnostics(self) -> None:
        if self._stopping:
            return
        report = None if self._check is None else self._check.last
        rows = check_rows(report, self.node.get_name(), waiting=self._waiting)
        msg = DiagnosticArray()
        fill_message(msg.header, {"stamp": ns_to_stamp_fields(
            self.node.get_clock().now().nanoseconds)})
        for row in rows:
            msg.status.append(DiagnosticStatus(
                level=bytes([row["level"]]), name=row["name"], message=row["message"],
                hardware_id=row["hardware_id"],
                values=[KeyValue(key=k, value=v) for k, v in row["values"]]))
        self._diag_pub.publish(msg)

    def stop(self) -> None:
        """The node is stopping: the timer callbacks return at once from now on. The timers are
        not cancelled (a timer cancelled while the executor holds a task of it makes that task
        fail at exit: :meth:`CalibratorNode.stop_activity`); ``destroy_node`` destroys them."""
        self._stopping = True


def add_check_service(node) -> NodeCheck:
    """Register ``~/check`` and the check's ``/diagnostics`` rows on ``node`` (a
    :class:`CalibratorNode`: ``config``, ``session``, ``get_logger``, ``get_name``)."""
    return NodeCheck(node)

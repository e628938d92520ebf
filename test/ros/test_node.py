"""The calibrator node in-process (needs rclpy, i.e. a sourced ROS 2 Jazzy; skipped otherwise).

One context, a MultiThreadedExecutor spinning in a thread, a helper node that publishes the
demo simulation's messages on the configured topics and calls the services.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")
pytest.importorskip("tf2_ros")

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import PoseStamped  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.executors import MultiThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import CameraInfo, Image  # noqa: E402
from std_msgs.msg import Float64, String  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402
from tf2_msgs.msg import TFMessage  # noqa: E402

from rwhec_ros.config import read_parameter_file  # noqa: E402
from rwhec_ros.messages import (  # noqa: E402
    fill_message,
    gray_to_image_fields,
    intrinsics_to_camera_info_fields,
    transform_to_pose_stamped_fields,
)
from rwhec_ros.ros.node import CalibratorNode  # noqa: E402
from rwhec_ros.simulation import DEMO_POSE_TOPIC, demo_camera_topics, demo_rig  # noqa: E402

DEMO_YAML = Path(__file__).resolve().parents[2] / "config" / "demo.yaml"
NS = 1_000_000_000


def overrides(tmp_path: Path, **changes) -> list[Parameter]:
    flat = read_parameter_file(DEMO_YAML)
    flat["output.directory"] = str(tmp_path)
    flat.update(changes)
    return [Parameter(name, value=value) for name, value in flat.items()]


@pytest.fixture
def context():
    ctx = Context()
    rclpy.init(context=ctx)
    try:
        yield ctx
    finally:
        rclpy.try_shutdown(context=ctx)


@pytest.fixture
def running(context, tmp_path):
    """(calibrator node, helper node, executor) with the executor spinning in a thread."""
    node = CalibratorNode(context=context, parameter_overrides=overrides(tmp_path))
    helper = Node("rwhec_test_helper", context=context)
    executor = MultiThreadedExecutor(context=context)
    executor.add_node(node)
    executor.add_node(helper)
    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    try:
        yield node, helper, executor
    finally:
        executor.shutdown()
        node.destroy_node()
        helper.destroy_node()
        thread.join(5.0)


def call(helper: Node, name: str, timeout: float = 60.0):
    client = helper.create_client(Trigger, name)
    assert client.wait_for_service(timeout_sec=10.0), name
    future = client.call_async(Trigger.Request())
    deadline = time.monotonic() + timeout
    while not future.done() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert future.done(), f"{name} did not answer"
    return future.result()


def wait_for(predicate, timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return False


def test_parameters_declared_with_typed_defaults(context, tmp_path):
    node = CalibratorNode(context=context, parameter_overrides=overrides(tmp_path))
    try:
        assert node.get_parameter("noise.kappa").value == 400.0  # from the file
        assert node.get_parameter("sync.pose_buffer_size").value == 4000  # schema default
        assert node.get_parameter("cameras.cam1.image_topic").value == "/demo/cam1/image_raw"
        assert node.get_parameter("cameras.cam1.calibrated_frame").value == ""
        assert node.config.camera_names == ("cam0", "cam1", "cam2")
        assert node.config.output.directory == str(tmp_path)
    finally:
        node.destroy_node()


@pytest.mark.parametrize(
    "changes, name",
    [
        ({"noise.sigma": -1.0}, "noise.sigma"),
        ({"noise.sigmaa": 1.0}, "noise.sigmaa"),  # unknown names are not silently ignored
        ({"tags.default_size": 1}, "tags.default_size"),  # integer for a double
    ],
)
def test_invalid_configuration_names_the_parameter(context, tmp_path, changes, name):
    with pytest.raises(ValueError, match=name):
        CalibratorNode(context=context, parameter_overrides=overrides(tmp_path, **changes))


def test_calibrate_without_data_answers_false(running):
    node, helper, _ = running
    response = call(helper, "/calibrate")
    assert response.success is False and "no measurement pairs" in response.message
    assert call(helper, "/calibrator/reset").success
    assert call(helper, "/calibrator/save_dataset").success is False


def test_feed_topics_and_calibrate(running, tmp_path):
    node, helper, _ = running
    rig = demo_rig()
    rng = np.random.default_rng(3)
    reliable = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
    pose_pub = helper.create_publisher(PoseStamped, DEMO_POSE_TOPIC, reliable)
    image_pubs = {c: helper.create_publisher(Image, demo_camera_topics(c)[0], reliable)
                  for c in rig.cameras}
    info_pubs = {c: helper.create_publisher(CameraInfo, demo_camera_topics(c)[1], reliable)
                 for c in rig.cameras}
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                         reliability=ReliabilityPolicy.RELIABLE)
    received = {"tf": [], "bound": [], "result": [], "diag": []}
    helper.create_subscription(TFMessage, "/tf_static", lambda m: received["tf"].append(m),
                               QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                                          reliability=ReliabilityPolicy.RELIABLE))
    helper.create_subscription(Float64, "/calibrator/suboptimality_bound",
                               lambda m: received["bound"].append(m), latched)
    helper.create_subscription(String, "/calibrator/result",
                               lambda m: received["result"].append(m), latched)
    helper.create_subscription(DiagnosticArray, "/diagnostics",
                               lambda m: received["diag"].append(m), 10)
    assert wait_for(lambda: pose_pub.get_subscription_count() > 0
                    and all(p.get_subscription_count() > 0 for p in image_pubs.values()))

    t0 = 1000 * NS
    for t in np.arange(0.0, 24.0, 0.2):  # one yaw turn: images at 5 Hz, poses at 100 Hz
        for k in range(20):
            tp = t + 0.01 * (k - 10)
            stamp = t0 + int(round(tp * NS))
            pose_pub.publish(fill_message(PoseStamped(), transform_to_pose_stamped_fields(
                rig.pose_measurement(tp), "world", stamp)))
        stamp = t0 + int(round(t * NS))
        for cam in rig.cameras:
            info_pubs[cam].publish(fill_message(CameraInfo(), intrinsics_to_camera_info_fields(
                rig.intrinsics[cam], stamp, f"{cam}_optical")))
            gray = rig.render(cam, rig.T_world_rig(t), rng, supersample=2)
            image_pubs[cam].publish(fill_message(Image(), gray_to_image_fields(
                gray, stamp, f"{cam}_optical")))
        time.sleep(0.03)  # let the detection worker keep up with the bounded queue
    assert wait_for(lambda: node.session.counters().get("pairs_kept", 0) > 60, timeout=30.0)

    response = call(helper, "/calibrate")
    assert response.success, response.message  # success: a usable verdict (good or caution)
    assert response.message.startswith(("GOOD: ", "CAUTION: "))  # the verdict comes first
    assert "CERTIFIED" in response.message
    assert wait_for(lambda: received["bound"] and received["result"] and received["tf"])
    assert received["bound"][-1].data < 1e-4  # certified: relative suboptimality below tol
    children = {t.child_frame_id for m in received["tf"] for t in m.transforms}
    assert {"cam0_optical_calibrated", "tag_5_calibrated"} <= children
    assert wait_for(lambda: received["diag"])
    assert wait_for(lambda: received["diag"][-1].status[0].message.startswith(
        "last calibration: "))
    status = received["diag"][-1].status[0]
    assert isinstance(status.level, bytes) and len(status.level) == 1
    assert status.level[0] in (0, 1)  # OK for good, WARN for caution
    assert call(helper, "/calibrator/save_dataset").success
    assert any(Path(node.config.output.directory).rglob("result.yaml"))

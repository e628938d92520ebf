"""The node's ``~/capture`` service in-process (needs rclpy, i.e. a sourced ROS 2 Jazzy).

The demo rig stands still (its pose published at 50 Hz, images at 10 Hz per camera): with
``capture.mode: capture`` nothing is searched until ``~/capture`` is called; the call takes each
camera's next image whose pose has been at rest for ``capture.rest_s`` and answers with what
every camera saw and the identifiability after it.
"""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")
pytest.importorskip("tf2_ros")

from geometry_msgs.msg import PoseStamped  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import CameraInfo, Image  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402
from test_node import NS, overrides, spinning, wait_for  # noqa: E402

from rwhec_ros.messages import (  # noqa: E402
    fill_message,
    gray_to_image_fields,
    intrinsics_to_camera_info_fields,
    transform_to_pose_stamped_fields,
)
from rwhec_ros.simulation import DEMO_POSE_TOPIC, demo_camera_topics, demo_rig  # noqa: E402


def _publishers(helper, rig):
    reliable = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
    pose = helper.create_publisher(PoseStamped, DEMO_POSE_TOPIC, reliable)
    images = {c: helper.create_publisher(Image, demo_camera_topics(c)[0], reliable)
              for c in rig.cameras}
    infos = {c: helper.create_publisher(CameraInfo, demo_camera_topics(c)[1], reliable)
             for c in rig.cameras}
    assert wait_for(lambda: pose.get_subscription_count() > 0
                    and all(p.get_subscription_count() > 0 for p in images.values()))
    return pose, images, infos


def _stand_still(rig, pubs, seconds: float, t0_ns: int, stop: threading.Event | None = None):
    """Publish the rig at rest at its pose of t = 0: poses at 50 Hz, images at 10 Hz."""
    pose_pub, image_pubs, info_pubs = pubs
    T = rig.T_world_rig(0.0)
    grays = {c: rig.render(c, T, supersample=2) for c in rig.cameras}
    for i in range(int(seconds * 50)):
        if stop is not None and stop.is_set():
            return
        stamp = t0_ns + i * NS // 50
        pose_pub.publish(fill_message(PoseStamped(), transform_to_pose_stamped_fields(
            T, "world", stamp)))
        if i % 5 == 4:
            for cam in rig.cameras:
                info_pubs[cam].publish(fill_message(CameraInfo(), intrinsics_to_camera_info_fields(
                    rig.intrinsics[cam], stamp, f"{cam}_optical")))
                image_pubs[cam].publish(fill_message(Image(), gray_to_image_fields(
                    grays[cam], stamp, f"{cam}_optical")))
        time.sleep(0.02)


def test_capture_takes_one_view_per_camera_at_rest(context, tmp_path):
    params = overrides(tmp_path, **{"capture.mode": "capture", "capture.rest_s": 0.3,
                                    "capture.timeout_s": 20.0})
    with spinning(context, params) as (node, helper, _):
        rig = demo_rig()
        pubs = _publishers(helper, rig)
        _stand_still(rig, pubs, 1.0, 1000 * NS)
        assert wait_for(lambda: node.session.counters().get("images_not_captured", 0) > 0)
        assert node.session.counters().get("pairs_kept", 0) == 0  # nothing searched yet
        client = helper.create_client(Trigger, "/calibrator/capture")
        assert client.wait_for_service(timeout_sec=10.0)
        future = client.call_async(Trigger.Request())
        stop = threading.Event()
        feeder = threading.Thread(target=_stand_still, args=(rig, pubs, 10.0, 1001 * NS, stop))
        feeder.start()
        try:
            assert wait_for(future.done, timeout=30.0), "~/capture did not answer"
        finally:
            stop.set()
            feeder.join(15.0)
        response = future.result()
        assert response.success, response.message
        lines = response.message.splitlines()
        assert lines[0].startswith("capture: 3 of 3 cameras took a view at rest")
        for cam in rig.cameras:
            assert any(ln.startswith(f"{cam} (image at ") for ln in lines), response.message
        assert any(ln.startswith("identifiability: ") for ln in lines)
        kept = node.session.counters().get("pairs_kept", 0)
        assert kept == int(lines[0].split(", ")[1].split()[0]) > 0


def test_capture_in_continuous_mode_says_how_to_switch(context, tmp_path):
    with spinning(context, overrides(tmp_path)) as (node, helper, _):
        client = helper.create_client(Trigger, "/calibrator/capture")
        assert client.wait_for_service(timeout_sec=10.0)
        future = client.call_async(Trigger.Request())
        assert wait_for(future.done, timeout=10.0)
        response = future.result()
        assert response.success is False
        assert "capture.mode is 'continuous'" in response.message
        assert node.config.capture.mode == "continuous"
        np.testing.assert_equal(node.session.counters().get("images_not_captured", 0), 0)

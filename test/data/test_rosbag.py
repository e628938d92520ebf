"""rosbag2 reading and writing without ROS (rosbags), and the offline tf tree."""

from __future__ import annotations

import numpy as np
import pytest

from rwhec_ros.core.lie import invert_transform, make_transform, so3_exp
from rwhec_ros.messages import (
    camera_info_to_intrinsics,
    gray_to_image_fields,
    image_to_gray,
    intrinsics_to_camera_info_fields,
    pose_stamped_to_transform,
    transform_stamped_to_transform,
    transform_to_pose_stamped_fields,
    transform_to_transform_stamped_fields,
)
from rwhec_ros.vision.intrinsics import CameraIntrinsics

pytest.importorskip("rosbags.rosbag2")

from rwhec_ros.data.rosbag import (  # noqa: E402 - after the importorskip
    CAMERA_INFO,
    COMPRESSED_IMAGE,
    IMAGE,
    POSE_STAMPED,
    TF_MESSAGE,
    TfTree,
    bag_topics,
    message_from_fields,
    read_messages,
    write_bag,
)

NS = 1_000_000_000


def random_transform(rng: np.random.Generator) -> np.ndarray:
    return make_transform(so3_exp(rng.standard_normal(3)), rng.standard_normal(3))


# --- messages and bags -----------------------------------------------------------------------


def test_message_from_fields_fills_ros_defaults_and_rejects_unknown_fields():
    msg = message_from_fields(CAMERA_INFO, {"width": 640, "height": 480})
    assert msg.width == 640 and msg.height == 480
    assert msg.k.shape == (9,) and not msg.k.any()  # fixed arrays zero-filled
    assert msg.d.shape == (0,)  # sequences empty
    assert msg.header.frame_id == "" and msg.roi.do_rectify is False
    with pytest.raises(ValueError, match="unknown fields.*'widht'"):
        message_from_fields(CAMERA_INFO, {"widht": 640})
    with pytest.raises(ValueError, match="expected 9 elements"):
        message_from_fields(CAMERA_INFO, {"k": [1.0, 2.0]})


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_written_messages_read_back_identically_in_log_time_order(tmp_path, storage):
    rng = np.random.default_rng(0)
    T_pose, T_tf = random_transform(rng), random_transform(rng)
    gray = rng.integers(0, 256, size=(6, 8), dtype=np.uint8)
    intr = CameraIntrinsics.pinhole(8, 6, 5.0, 5.5)
    msgs = [  # written out of log-time order on purpose
        ("/img", IMAGE, 3 * NS, message_from_fields(IMAGE, gray_to_image_fields(gray, 3 * NS,
                                                                                  "cam"))),
        ("/pose", POSE_STAMPED, 1 * NS, message_from_fields(
            POSE_STAMPED, transform_to_pose_stamped_fields(T_pose, "world", 1 * NS))),
        ("/info", CAMERA_INFO, 2 * NS, message_from_fields(
            CAMERA_INFO, intrinsics_to_camera_info_fields(intr, 2 * NS, "cam"))),
        ("/tf", TF_MESSAGE, 4 * NS, message_from_fields(TF_MESSAGE, {"transforms": [
            transform_to_transform_stamped_fields(T_tf, "world", "rig", 4 * NS)]})),
        ("/other", POSE_STAMPED, 0, message_from_fields(POSE_STAMPED, {})),
    ]
    bag = write_bag(tmp_path / "bag", msgs, storage=storage)
    assert bag_topics(bag) == {"/img": (IMAGE, 1), "/pose": (POSE_STAMPED, 1),
                               "/info": (CAMERA_INFO, 1), "/tf": (TF_MESSAGE, 1),
                               "/other": (POSE_STAMPED, 1)}
    calls = []
    got = list(read_messages(bag, ["/img", "/pose", "/info", "/tf", "/absent"],
                             on_progress=lambda done, total: calls.append((done, total))))
    assert [m.topic for m in got] == ["/pose", "/info", "/img", "/tf"]  # /other filtered out
    assert [m.log_time_ns for m in got] == [NS, 2 * NS, 3 * NS, 4 * NS]
    assert calls == [(1, 4), (2, 4), (3, 4), (4, 4)]
    stamp, frame, T = pose_stamped_to_transform(got[0].msg)
    assert (stamp, frame) == (NS, "world")
    # quaternion round trip through the message: float64 rounding only
    assert np.allclose(T, T_pose, atol=1e-12)
    assert camera_info_to_intrinsics(got[1].msg) == intr
    assert np.array_equal(image_to_gray(got[2].msg), gray)
    stamp, parent, child, T = transform_stamped_to_transform(got[3].msg.transforms[0])
    assert (stamp, parent, child) == (4 * NS, "world", "rig")
    assert np.allclose(T, T_tf, atol=1e-12)  # float64 rounding only


def test_bag_errors_name_the_path(tmp_path):
    with pytest.raises(ValueError, match="no_such_bag.*no such file"):
        bag_topics(tmp_path / "no_such_bag")
    (tmp_path / "not_a_bag").mkdir()
    with pytest.raises(ValueError, match="not_a_bag.*cannot open"):
        list(read_messages(tmp_path / "not_a_bag", ["/x"]))
    write_bag(tmp_path / "b", [("/x", POSE_STAMPED, 0, message_from_fields(POSE_STAMPED, {}))])
    with pytest.raises(ValueError, match="already exists"):
        write_bag(tmp_path / "b", [])
    with pytest.raises(ValueError, match="storage"):
        write_bag(tmp_path / "c", [], storage="rosbag1")


def test_simulated_bag_holds_the_demo_topics(tmp_path):
    from rwhec_ros.simulation import DEMO_POSE_TOPIC, demo_rig, write_simulated_bag

    rig = demo_rig(1, 2)
    bag = write_simulated_bag(tmp_path / "sim", rig, np.random.default_rng(0), seconds=0.4,
                              pose_source="both", image_rate_hz=5.0, pose_rate_hz=50.0,
                              supersample=1)
    topics = bag_topics(bag)
    # poses at 0, 20, ..., 400 ms; images at 10 and 210 ms
    assert topics == {DEMO_POSE_TOPIC: (POSE_STAMPED, 21), "/tf": (TF_MESSAGE, 21),
                      "/demo/cam0/camera_info": (CAMERA_INFO, 2),
                      "/demo/cam0/image_raw": (IMAGE, 2)}
    first = next(read_messages(bag, [DEMO_POSE_TOPIC]))
    stamp, frame, T = pose_stamped_to_transform(first.msg)
    assert frame == "world" and stamp == first.log_time_ns == NS
    # the default pose noise is 0.5 mm / 0.5 mrad per axis: well within 1 cm / 0.01 rad
    assert np.allclose(T, rig.T_world_rig(0.0), atol=1e-2)


def test_simulated_bag_with_compressed_images(tmp_path):
    from rwhec_ros.messages import compressed_image_to_gray
    from rwhec_ros.simulation import demo_rig, simulated_stream, write_simulated_bag

    rig = demo_rig(1, 2)
    options = dict(seconds=0.4, image_rate_hz=5.0, pose_rate_hz=50.0, supersample=1)
    bag = write_simulated_bag(tmp_path / "sim", rig, np.random.default_rng(0),
                              image_transport="compressed", **options)
    topics = bag_topics(bag)
    assert topics["/demo/cam0/image_raw/compressed"] == (COMPRESSED_IMAGE, 2)
    assert "/demo/cam0/image_raw" not in topics
    msgs = list(read_messages(bag, ["/demo/cam0/image_raw/compressed"]))
    raw = [d for _, cam, d in simulated_stream(rig, np.random.default_rng(0), **options)
           if cam is not None]
    for m, gray in zip(msgs, raw, strict=True):
        assert m.msg.format == "mono8; jpeg compressed mono8"
        decoded = compressed_image_to_gray(m.msg)
        # JPEG quality 95 quantises away part of the rendering's pixel noise (std 2 grey
        # levels): the mean error stays below that noise (measured 1.2)
        assert decoded.shape == gray.shape
        assert np.abs(decoded.astype(float) - gray).mean() < 2.0
    with pytest.raises(ValueError, match="image_transport"):
        write_simulated_bag(tmp_path / "bad", rig, np.random.default_rng(0),
                            image_transport="theora", **options)


# --- offline tf ------------------------------------------------------------------------------


def rot_z(angle: float, t=(0.0, 0.0, 0.0)) -> np.ndarray:
    return make_transform(so3_exp(np.array([0.0, 0.0, angle])), np.asarray(t, dtype=float))


@pytest.fixture
def tree() -> TfTree:
    """world -> base (static), base -> arm (dynamic: constant yaw rate 0.5 rad/s, samples every
    100 ms), arm -> tool (static), base -> camera (static)."""
    rng = np.random.default_rng(1)
    tf = TfTree(max_gap_ns=NS // 5, tolerance_ns=NS // 100)
    tf.add("world", "base", 0, random_transform(rng), static=True)
    tf.add("arm", "tool", 0, random_transform(rng), static=True)
    tf.add("base", "camera", 0, random_transform(rng), static=True)
    for k in range(21):
        t = k * 0.1
        tf.add("base", "arm", int(round(t * NS)), rot_z(0.5 * t, (0.2, 0.0, 0.1)), static=False)
    return tf


def test_tf_chain_lookup_interpolates_dynamic_links(tree):
    T_world_base = tree.lookup("world", "base", 0)
    T_arm_tool = tree.lookup("arm", "tool", 0)
    for t in (0.0, 0.35, 1.05, 2.0):
        expected = T_world_base @ rot_z(0.5 * t, (0.2, 0.0, 0.1)) @ T_arm_tool
        got = tree.lookup("world", "tool", int(round(t * NS)))
        # constant twist between samples: SE(3) interpolation is exact up to rounding
        assert np.allclose(got, expected, atol=1e-12)
        # reversed lookup is the inverse; siblings go through the common ancestor
        assert np.allclose(tree.lookup("tool", "world", int(round(t * NS))),
                           invert_transform(expected), atol=1e-12)
    T_cam_tool = tree.lookup("camera", "tool", NS)
    expected = invert_transform(tree.lookup("base", "camera", 0)) @ rot_z(0.5, (0.2, 0, 0.1)) \
        @ T_arm_tool
    assert np.allclose(T_cam_tool, expected, atol=1e-12)  # rounding only


def test_tf_lookup_failures_say_why(tree):
    with pytest.raises(LookupError, match="'nowhere' does not appear"):
        tree.lookup("world", "nowhere", 0)
    tree.add("map", "odom", 0, np.eye(4), static=True)
    with pytest.raises(LookupError, match="not connected"):
        tree.lookup("world", "odom", 0)
    with pytest.raises(LookupError, match="base -> arm.*after_buffer"):
        tree.lookup("world", "tool", 3 * NS)
    assert tree.lookup("world", "tool", 2 * NS + NS // 200) is not None  # within tolerance


def test_tf_messages_with_bad_transforms_are_counted_not_raised():
    tf = TfTree(max_gap_ns=NS)
    good = transform_to_transform_stamped_fields(np.eye(4), "a", "b", 0)
    bad = transform_to_transform_stamped_fields(np.eye(4), "a", "c", 0)
    bad["transform"]["rotation"] = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 0.0}
    msg = message_from_fields(TF_MESSAGE, {"transforms": [good, bad]})
    assert tf.add_message(msg, static=False) == 1
    assert tf.rejected == 1
    assert tf.frames == {"a", "b"}

"""The stop-and-go rule (rwhec_ros.sync.at_rest): bridge, wait, and where it is hooked (no ROS)."""

from __future__ import annotations

import numpy as np
import pytest

from rwhec_ros.config import CalibratorConfig
from rwhec_ros.core.lie import make_transform, so3_exp
from rwhec_ros.data.rosbag import TfTree
from rwhec_ros.session import CalibrationSession
from rwhec_ros.sync.at_rest import AtRestRule, at_rest_lookup, same_pose, waits_at_rest
from rwhec_ros.sync.buffer import LookupStatus, PoseBuffer
from rwhec_ros.vision.intrinsics import CameraIntrinsics
from rwhec_ros.vision.render import RenderedTag, render_tags

MS = 1_000_000
RULE = AtRestRule(max_gap_ns=2000 * MS, translation_m=5e-4, rotation_rad=1e-3)
P = make_transform(so3_exp(np.array([0.1, -0.2, 0.3])), [0.4, 0.1, 0.5])


def nudged(T, dt=0.0, dr=0.0):
    """``T`` moved by ``dt`` metres along x and turned by ``dr`` rad about z."""
    return make_transform(T[:3, :3] @ so3_exp(np.array([0.0, 0.0, dr])), T[:3, 3] + [dt, 0, 0])


def buffer(samples, max_gap_ms=50):
    buf = PoseBuffer(max_gap_ns=max_gap_ms * MS, extrapolation_tol_ns=0)
    for stamp_ms, T in samples:
        assert buf.add(stamp_ms * MS, T)
    return buf


def test_same_pose_is_within_both_tolerances():
    assert same_pose(P, nudged(P, 4.9e-4, 0.9e-3), RULE)
    assert not same_pose(P, nudged(P, 5.1e-4), RULE)
    assert not same_pose(P, nudged(P, 0.0, 1.1e-3), RULE)


def test_bridge_pairs_an_image_between_agreeing_samples_only():
    # joint-state tf at 10 Hz, the buffer interpolates only 50 ms gaps: the robot at rest from
    # 0 to 300 ms, then moving
    Q = nudged(P, 2e-4, 3e-4)  # encoder jitter, within the tolerance
    buf = buffer([(0, P), (100, Q), (200, P), (300, nudged(P, 0.05))])
    assert buf.lookup_status(150 * MS) is LookupStatus.GAP_TOO_LARGE
    got = at_rest_lookup(buf, 150 * MS, RULE)
    assert got is not None and same_pose(got, P, RULE) and same_pose(got, Q, RULE)
    assert at_rest_lookup(buf, 250 * MS, RULE) is None  # the robot moved between 200 and 300
    assert at_rest_lookup(buf, 350 * MS, RULE) is None  # no sample after: never
    assert at_rest_lookup(buf, 100 * MS, RULE) is None  # exact: the buffer's own business
    off = AtRestRule(0, 5e-4, 1e-3)
    assert at_rest_lookup(buf, 150 * MS, off) is None
    assert at_rest_lookup(buf, 150 * MS, None) is None


def test_bridge_is_bounded_by_the_rules_gap():
    buf = buffer([(0, P), (2500, P)])
    assert at_rest_lookup(buf, 1000 * MS, RULE) is None  # 2.5 s > 2 s
    assert at_rest_lookup(buffer([(0, P), (2000, P)]), 1000 * MS, RULE) is not None


def test_wait_rule_sparse_agreeing_and_dense_moving_streams():
    # a sparse stream (one sample per stop): an image 300 ms after the last sample may wait
    sparse = buffer([(0, nudged(P, 0.1)), (1000, P)])
    assert sparse.lookup_status(1300 * MS) is LookupStatus.AFTER_BUFFER
    assert waits_at_rest(sparse, 1300 * MS, RULE)
    assert not waits_at_rest(sparse, 3100 * MS, RULE)  # beyond the rule's gap
    # a slow stream at rest: the two newest agree
    assert waits_at_rest(buffer([(0, P), (40, P)]), 300 * MS, RULE)
    # a dense stream that moved up to its last sample (a dropout): no wait
    assert not waits_at_rest(buffer([(0, P), (10, nudged(P, 0.01))]), 300 * MS, RULE)
    assert not waits_at_rest(buffer([(0, P)]), 0, RULE)  # not newer than the newest


# --- hooked in the session and the bag's tf tree --------------------------------------------------

INTR = CameraIntrinsics(640, 480, [[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]], [])
T_CAM_TAG = make_transform(np.diag([1.0, -1.0, -1.0]), [0.02, -0.01, 0.8])


def session(at_rest_gap_s: float = 2.0) -> CalibrationSession:
    flat = {
        "camera_carrier.frame": "tool0", "camera_carrier.moving": True,
        "tag_carrier.frame": "base", "tag_carrier.moving": False,
        "pose_source.type": "topic", "pose_source.topic": "/pose",
        "pose_source.parent": "base", "pose_source.child": "tool0",
        "cameras.names": ["cam0"], "cameras.cam0.image_topic": "/image",
        "cameras.cam0.camera_info_topic": "/info",
        "tags.ids": [0], "tags.default_size": 0.16,
        "sync.max_gap_s": 0.05, "sync.extrapolation_tolerance_s": 0.0,
        "sync.at_rest_max_gap_s": at_rest_gap_s,
    }
    s = CalibrationSession(CalibratorConfig.from_parameters(flat), live_solve=lambda *a, **k: None)
    s.set_camera_info("cam0", INTR)
    return s


@pytest.fixture(scope="module")
def tag_image():
    return render_tags(INTR, [RenderedTag(0, T_CAM_TAG, 0.16)])


def test_session_pairs_a_stop_and_go_image_after_the_next_sample(tag_image):
    s = session()
    s.add_pose(1000 * MS, P, source="base")
    # 300 ms after the only sample: waits (pending) instead of after_buffer
    assert s.add_image("cam0", 1300 * MS, tag_image).status == "pending"
    s.add_pose(1600 * MS, nudged(P, 1e-4), source="base")  # the arm still there
    c = s.counters()
    assert c["pairs_kept"] == 1 and c["pose_at_rest"] == 1, c
    # the pair's A is the pose at rest (eye-in-hand: the inverse of T_base_tool0)
    A = s.pairs_snapshot().edges[("tag_0", "cam0")].A[0]
    np.testing.assert_allclose(A @ P, np.eye(4), atol=2e-4)


def test_session_rejects_an_image_when_the_arm_moved(tag_image):
    s = session()
    s.add_pose(1000 * MS, P, source="base")
    assert s.add_image("cam0", 1300 * MS, tag_image).status == "pending"
    s.add_pose(1600 * MS, nudged(P, 0.02), source="base")  # it moved: never paired
    # (the image may still wait for poses reordered into the gap: the end of the data decides)
    s.flush_pending()
    c = s.counters()
    assert c.get("pairs_kept", 0) == 0 and c["no_pose_at_stamp:gap_too_large"] == 1, c


def test_session_without_the_rule_never_pairs_at_rest(tag_image):
    """Without the rule the image waits only for a pose that brackets it (issue 39's waiting
    for a late stream), and the same later sample at rest does not pair it."""
    s = session(at_rest_gap_s=0.0)
    s.add_pose(1000 * MS, P, source="base")
    assert s.add_image("cam0", 1300 * MS, tag_image).status == "pending"
    s.add_pose(1600 * MS, nudged(P, 1e-4), source="base")
    s.flush_pending()
    c = s.counters()
    assert c.get("pairs_kept", 0) == 0 and c.get("pose_at_rest", 0) == 0, c
    assert c["no_pose_at_stamp:gap_too_large"] == 1, c


def test_tf_tree_bridges_a_link_at_rest():
    tree = TfTree(max_gap_ns=50 * MS, at_rest=RULE)
    tree.add("base", "shoulder", 0, P, static=False)
    tree.add("base", "shoulder", 100 * MS, P, static=False)
    tree.add("shoulder", "tool0", 0, P, static=True)
    np.testing.assert_allclose(tree.lookup("base", "tool0", 50 * MS), P @ P, atol=1e-12)
    plain = TfTree(max_gap_ns=50 * MS)
    for stamp in (0, 100 * MS):
        plain.add("base", "shoulder", stamp, P, static=False)
    with pytest.raises(LookupError, match="gap_too_large"):
        plain.lookup("base", "shoulder", 50 * MS)

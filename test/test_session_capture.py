"""``capture.mode`` and the session's capture (rwhec_ros.session.capture), without ROS."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from rwhec_ros.config import CalibratorConfig
from rwhec_ros.core.lie import invert_transform, make_transform, so3_exp
from rwhec_ros.session import CalibrationSession
from rwhec_ros.session.capture import capture_message
from rwhec_ros.vision.intrinsics import CameraIntrinsics
from rwhec_ros.vision.render import RenderedTag, render_tags

MS = 1_000_000
INTR = CameraIntrinsics(640, 480, [[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]], [])
T_TOOL_CAM = make_transform(np.eye(3), [0.0, 0.0, 0.05])
T_BASE_TAG = np.eye(4)  # the tag on the table, its face (z) up


def tool_pose(i: int) -> np.ndarray:
    """``T_base_tool0`` of stop ``i``: the camera 0.8 m above the tag looking down, turned a
    little per stop."""
    down = np.diag([1.0, -1.0, -1.0])
    look = make_transform(down @ so3_exp(np.array([0.05 * i, -0.04 * i, 0.3 * i])),
                          [0.01 * i, 0, 0.8])
    return look @ invert_transform(T_TOOL_CAM)


def image_at(T_base_tool: np.ndarray) -> np.ndarray:
    T_cam_tag = invert_transform(T_base_tool @ T_TOOL_CAM) @ T_BASE_TAG
    return render_tags(INTR, [RenderedTag(0, T_cam_tag, 0.16)], supersample=2)


def make_session(mode: str, cameras=("cam0",), **extra) -> CalibrationSession:
    flat = {
        "camera_carrier.frame": "tool0", "camera_carrier.moving": True,
        "tag_carrier.frame": "base", "tag_carrier.moving": False,
        "pose_source.type": "tf", "pose_source.parent": "base", "pose_source.child": "tool0",
        "cameras.names": list(cameras),
        "tags.ids": [0], "tags.default_size": 0.16,
        "capture.mode": mode, "capture.rest_s": 0.5, "capture.timeout_s": 2.0,
        "solver.min_pairs": 1,
    }
    for c in cameras:
        flat[f"cameras.{c}.image_topic"] = f"/{c}/image"
        flat[f"cameras.{c}.camera_info_topic"] = f"/{c}/info"
    flat.update(extra)
    s = CalibrationSession(CalibratorConfig.from_parameters(flat),
                           live_solve=lambda *a, **k: None)
    for c in cameras:
        s.set_camera_info(c, INTR)
    return s


@pytest.fixture(scope="module")
def images():
    return {i: image_at(tool_pose(i)) for i in range(3)}


def feed(s, camera, stop, t0_ms, images, n=4, period_ms=200):
    """``n`` images of ``camera`` at stop ``stop`` from ``t0_ms`` every ``period_ms``; outcomes."""
    return [s.add_image(camera, (t0_ms + k * period_ms) * MS, images[stop], tool_pose(stop))
            for k in range(n)]


def test_capture_only_mode_takes_the_first_image_at_rest_for_rest_s(images):
    s = make_session("capture")
    outs = feed(s, "cam0", 0, 0, images, n=2)  # no request: left out, undecoded
    assert [o.status for o in outs] == ["skipped", "skipped"]
    assert s.counters()["images_not_captured"] == 2
    req = s.request_capture()
    # the arm arrives at stop 1 at 1000 ms; images at 1000, 1200, 1400 (at rest 0.4 s) are not
    # taken, the one at 1600 ms (at rest 0.6 s) is
    outs = feed(s, "cam0", 1, 1000, images, n=4)
    assert [o.status for o in outs] == ["skipped", "skipped", "skipped", "used"]
    assert req.complete
    result = s.finish_capture(req)
    assert result.success and result.pairs_kept == 1
    assert result.rest_s["cam0"] == pytest.approx(0.6)
    text = capture_message(result)
    assert text.splitlines()[0] == "capture: 1 of 1 cameras took a view at rest, 1 pairs kept"
    assert "cam0 (image at 1.600 s, at rest 0.60 s): tag_0 4 corners" in text
    assert "pair kept" in text and "(tag_0, cam0): 1 pairs" in text
    # after the capture, images are left out again
    assert feed(s, "cam0", 1, 1800, images, n=1)[0].status == "skipped"


def test_a_second_capture_at_the_same_stop_says_the_keyframe_test_refused_it(images):
    s = make_session("capture")
    req = s.request_capture()
    feed(s, "cam0", 1, 0, images, n=4)
    assert s.finish_capture(req).pairs_kept == 1
    req = s.request_capture()
    feed(s, "cam0", 1, 1000, images, n=1)  # still at rest (since 0 ms): taken at once
    result = s.finish_capture(req)
    assert result.success and result.pairs_kept == 0
    assert "pair not kept (keyframe test" in capture_message(result)


def test_continuous_mode_refuses_with_the_hint(images):
    s = make_session("continuous")
    with pytest.raises(ValueError, match="capture.mode is 'continuous'.*ros2 param set"):
        s.request_capture()
    result = s.capture(timeout_s=0.01)
    assert not result.success and "capture.mode" in capture_message(result)
    assert feed(s, "cam0", 0, 0, images, n=1)[0].status == "used"  # keyframing as before


def test_both_mode_keyframes_and_captures_past_the_motion_gate(images):
    s = make_session("both")
    assert feed(s, "cam0", 1, 0, images, n=1)[0].status == "used"  # continuous keyframing
    # the same stop again: the motion gate skips the image ...
    assert feed(s, "cam0", 1, 200, images, n=1)[0].status == "skipped"
    req = s.request_capture()
    out = feed(s, "cam0", 1, 600, images, n=1)[0]  # ... a capture searches it all the same
    assert out.status == "no_new_pairs" and out.detection is not None
    assert s.finish_capture(req).views["cam0"] is out


def test_a_camera_without_a_view_at_rest_is_named_with_why(images):
    s = make_session("capture", cameras=("cam0", "cam1"))
    req = s.request_capture()
    feed(s, "cam0", 1, 0, images, n=4)
    # cam1 sees the arm moving: a new stop at every image
    for k in range(4):
        s.add_image("cam1", k * 200 * MS, images[k % 3], tool_pose(k % 3))
    result = s.finish_capture(req)
    assert not result.success and set(result.views) == {"cam0"}
    assert result.missing["cam1"].startswith("its pose was not at rest for 0.5 s (at rest 0.00 s")
    assert "cam1: no view (its pose was not at rest" in capture_message(result)
    s2 = make_session("capture")
    result = s2.capture(timeout_s=0.01)
    assert result.missing == {"cam0": "no image with a pose reached the calibrator"}


def test_capture_blocks_until_the_images_arrive(images):
    s = make_session("capture")
    box = {}
    waiter = threading.Thread(target=lambda: box.setdefault("r", s.capture(timeout_s=30.0)))
    waiter.start()
    while not s._capture._requests:  # the request is armed
        threading.Event().wait(0.01)
    feed(s, "cam0", 2, 0, images, n=4)
    waiter.join(30.0)
    assert box["r"].success and box["r"].pairs_kept == 1


def test_capture_mode_is_validated():
    with pytest.raises(ValueError, match=r"capture.mode: must be one of \['continuous', "
                                         r"'capture', 'both'\]"):
        make_session("sometimes")

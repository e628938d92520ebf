"""The verdict in the session's answers: what is published, what the summary and the launch file
say, rejected data in words, images held for their CameraInfo. No rendering: synthetic pairs
through the same output functions the session and the CLI use, and blank images."""

from __future__ import annotations

import numpy as np
import pytest
from launch_helpers import demo_config, launch_transforms

from rwhec_ros.core.solve import solve
from rwhec_ros.core.verdict import assess
from rwhec_ros.data.results import FrameNaming
from rwhec_ros.session import CalibrationSession, summary
from rwhec_ros.session.info_wait import CameraInfoWait
from rwhec_ros.session.outputs import launch_header, publishable, static_transforms_launch
from rwhec_ros.simulation.synthetic import random_instance
from rwhec_ros.vision.intrinsics import CameraIntrinsics

NS = 1_000_000_000


@pytest.fixture(scope="module")
def with_missing_camera():
    """A good synthetic result whose configuration also asks for a camera it has no data of."""
    problem, _ = random_instance(np.random.default_rng(0), 2, 2, n_per_edge=20, sigma=0.005,
                                 kappa=400.0)
    result = solve(problem)
    naming = FrameNaming.from_carriers(["x0", "x1"], ["y0", "y1", "y2"], camera_carrier="rig",
                                       tag_carrier="world")
    verdict = assess(result, problem, expected_y=naming.y_names, expected_x=naming.x_names)
    return problem, result, naming, verdict


def test_unusable_frames_are_left_out_and_named(with_missing_camera):
    problem, result, naming, verdict = with_missing_camera
    assert verdict.level == "unusable" and verdict.frames["y2"].calibrated is False
    names = list(result.y_names) + list(result.x_names)
    keep, left = publishable(naming.transforms(result), names, verdict)
    assert [c for _, c, _ in keep] == ["y0_calibrated", "y1_calibrated", "x0_calibrated",
                                       "x1_calibrated"]
    assert left == {}  # y2 has no estimate at all: nothing to leave out
    # a frame with an estimate that the verdict finds unusable: left out, unless widened
    verdict.frames["y1"].level = "unusable"
    verdict.frames["y1"].why.append("predicted +-234 mm, +-9.3 deg")
    keep, left = publishable(naming.transforms(result), names, verdict)
    assert "y1_calibrated" not in [c for _, c, _ in keep]
    assert left == {"y1": "predicted +-234 mm, +-9.3 deg"}
    keep, left = publishable(naming.transforms(result), names, verdict, publish_unusable=True)
    assert len(keep) == 4 and left == {}
    # the summary: verdict first, never a number for a frame that is not usable
    text = summary(result, problem, {}, naming, verdict)
    lines = text.splitlines()
    assert lines[0].startswith("UNUSABLE: y2: not calibrated: no tag was ever kept")
    assert "rig->y1_calibrated: NOT CALIBRATED (predicted +-234 mm, +-9.3 deg)" in lines
    assert "rig->y2_calibrated: NOT CALIBRATED (no data)" in lines
    assert any(line.startswith("rig->y0_calibrated: t=[") for line in lines)
    # the launch file: the verdict and what was left out as its first comment lines
    keep, left = publishable(naming.transforms(result), names, verdict)
    launch = static_transforms_launch(keep, header=launch_header(result, verdict, left,
                                                                 "created now"))
    assert launch.startswith("# UNUSABLE: y2: not calibrated")
    assert "# left out (not usable): y1: predicted +-234 mm, +-9.3 deg" in launch
    assert set(launch_transforms(launch)) == {"y0_calibrated", "x0_calibrated",
                                              "x1_calibrated"}
    compile(launch, "launch.py", "exec")  # still a valid Python file


def test_whole_camera_rejected_for_its_image_size_is_said_in_words(tmp_path):
    session = CalibrationSession(demo_config(tmp_path))
    session.set_camera_info("cam0", CameraIntrinsics.pinhole(640, 480, 500.0))
    for k in range(7):
        session.add_pose(k * NS // 10, np.eye(4), source="world")
        session.add_image("cam0", k * NS // 10, np.zeros((960, 1280), np.uint8))
    assert session.rejections() == [
        "all 7 images of cam0 rejected: 1280x960 images, CameraInfo says 640x480"]
    out = session.calibrate()
    assert not out.success
    assert out.message == ("no measurement pairs: all 7 images of cam0 rejected: 1280x960 "
                           "images, CameraInfo says 640x480")


def test_poses_of_another_frame_are_said_in_words(tmp_path):
    session = CalibrationSession(demo_config(tmp_path))
    for k in range(6150):
        session.add_pose(k * NS // 100, np.eye(4), source="map")
    assert session.rejections() == [
        "all 6,150 poses rejected: frame_id 'map', configured pose_source.parent 'world'"]
    assert "all 6,150 poses rejected" in session.calibrate().message
    session.reset()
    assert session.rejections() == []


def test_camera_info_wait_holds_briefly_then_releases():
    wait = CameraInfoWait(max_wait_ns=100, max_images=3)
    assert wait.hold("cam0", 0, "a") == [] and wait.hold("cam0", 50, "b") == []
    assert wait.hold("cam1", 60, "x") == [] and len(wait) == 3
    # too old (by stamp) or too many: handed back to be processed (and rejected, counted)
    assert wait.hold("cam0", 120, "c") == ["a"]
    assert wait.release("cam0") == ["b", "c"] and wait.release("cam0") == []
    assert list(wait.drain()) == [("cam1", "x")] and len(wait) == 0
    wait = CameraInfoWait(max_wait_ns=10**9, max_images=2)
    for k, item in enumerate("pqr"):
        out = wait.hold("cam0", k, item)
    assert out == ["p"]
    with pytest.raises(ValueError, match="max_images"):
        CameraInfoWait(max_images=0)

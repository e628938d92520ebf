"""The reprojection gate scaled to the corner noise the detector measures, and the flip check
scaled to the number of points."""

import numpy as np
import pytest

from rwhec_ros.core.lie import invert_transform
from rwhec_ros.vision.detection import TagDetector, tag_object_points
from rwhec_ros.vision.detector_config import DetectorConfig, RejectReason, corner_noise_px
from rwhec_ros.vision.intrinsics import CameraIntrinsics
from rwhec_ros.vision.planar_pose import ratio_for_points
from rwhec_ros.vision.render import RenderedTag, look_at, render_tags

CAM = CameraIntrinsics.pinhole(640, 480, 500.0)


def test_corner_noise_is_the_precision_models():
    assert corner_noise_px(1.0, 4) == pytest.approx(np.sqrt(2.0))  # a tag: sqrt(2) rms
    assert corner_noise_px(1.0, 54) == pytest.approx(np.sqrt(54 / 102))
    with pytest.raises(ValueError, match="n_points must be >= 4"):
        corner_noise_px(1.0, 3)


def test_reprojection_limit_follows_the_camera_and_keeps_its_floor():
    cfg = DetectorConfig()  # floor 1 px, factor 4
    assert cfg.reprojection_limit(5.0, 4, None) == 1.0  # no history: the fixed floor
    assert cfg.reprojection_limit(0.02, 4, [0.03] * 10) == 1.0  # clean renders: the floor
    # a camera whose poses measure 0.8 px of corner noise: 4 x 0.8 px as an RMS of 4 points
    limit = cfg.reprojection_limit(1.2, 4, [0.8] * 10)
    assert limit == pytest.approx(4 * 0.8 / np.sqrt(2.0))
    # the pose's own noise counts: a camera's first pose is judged by itself
    assert cfg.reprojection_limit(1.3, 4, []) == pytest.approx(4 * 1.3)
    # a gross error among many good poses does not move the median
    assert cfg.reprojection_limit(6.0, 4, [0.8] * 10) == pytest.approx(limit)
    with pytest.raises(ValueError, match="reprojection_gate_factor must be >= 1"):
        DetectorConfig(reprojection_gate_factor=0.5)


def test_flip_ratio_for_n_points_keeps_the_tags_and_relaxes_with_points():
    assert ratio_for_points(3.0, 4) == 3.0
    assert ratio_for_points(3.0, 8) == pytest.approx(np.sqrt(1 + 16 / 10))
    assert ratio_for_points(3.0, 24) == pytest.approx(np.sqrt(1 + 16 / 42))
    assert ratio_for_points(1.0, 100) == 1.0  # check off stays off
    # the same excess misfit in noise units: (2N - 6)(ratio^2 - 1) is constant
    for n in (5, 8, 30):
        assert (2 * n - 6) * (ratio_for_points(3.0, n) ** 2 - 1) == pytest.approx(16.0)


def test_a_tag_above_the_floor_is_kept_by_a_noisy_camera_and_refused_by_a_clean_one():
    """Corners moved by ~1 px (what a real lens gives, rms above the 1 px floor): rejected
    without a history and with one of clean renders, kept by a camera whose poses measure that
    much noise; the noise of the pose is reported either way."""
    T = invert_transform(look_at([0.1, 0.05, 0.8], [0, 0, 0], up=[0, 1, 0]))
    img = render_tags(CAM, [RenderedTag(3, T, 0.2)])
    quad = CAM.project_points(tag_object_points(0.2), T)
    quad = quad + np.array([[1.5, 0.0], [0.0, -1.5], [-1.5, 0.0], [0.0, 1.5]])
    det = TagDetector(DetectorConfig(tag_sizes={3: 0.2}, corner_refinement="none"))
    plain = det.estimate_markers(img, [3], [quad], CAM)
    assert [r.reason for r in plain.rejections] == [RejectReason.REPROJECTION_ERROR.value]
    own = plain.corner_noise_px[3]
    clean = det.estimate_markers(img, [3], [quad], CAM, noise_history=[0.02] * 20)
    assert [r.reason for r in clean.rejections] == [RejectReason.REPROJECTION_ERROR.value]
    noisy = det.estimate_markers(img, [3], [quad], CAM, noise_history=[own] * 20)
    assert [o.tag_id for o in noisy.observations] == [3]
    assert noisy.observations[0].reprojection_rms_px > 1.0

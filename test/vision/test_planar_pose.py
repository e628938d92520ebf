"""Pose-flip safety: the two IPPE solutions, the ratio test, resolution by a predicted pose."""

import numpy as np
import pytest

from rwhec_ros.core.lie import invert_transform, rotation_distance, so3_exp
from rwhec_ros.vision.detection import DetectorConfig, RejectReason, TagDetector, tag_object_points
from rwhec_ros.vision.intrinsics import CameraIntrinsics
from rwhec_ros.vision.planar_pose import PoseStatus, solve_planar_pose
from rwhec_ros.vision.render import RenderedTag, look_at, render_tags

CAM = CameraIntrinsics.pinhole(480, 400, 1000.0)
SIZE = 0.08


def view(rng, distance, max_tilt_deg):
    """T_cam_tag: camera at ``distance`` within ``max_tilt_deg`` of the tag normal."""
    tilt = np.deg2rad(rng.uniform(0.0, max_tilt_deg))
    ph = rng.uniform(0.0, 2 * np.pi)
    pos = distance * np.array([np.sin(tilt) * np.cos(ph), np.sin(tilt) * np.sin(ph),
                               np.cos(tilt)])
    return invert_transform(look_at(pos, np.r_[rng.normal(0.0, 0.05, 2), 0.0], up=[0, 1, 0]))


def deg(R1, R2):
    return float(np.degrees(rotation_distance(R1, R2)))


def solve(corners, **kw):
    return solve_planar_pose(tag_object_points(SIZE), corners, corners, CAM, square=True, **kw)


def test_well_conditioned_square_is_unique_and_exact():
    T = invert_transform(look_at([0.4, 0.3, 0.6], [0.0, 0.0, 0.0], up=[0, 1, 0]))
    corners = CAM.project_points(tag_object_points(SIZE), T)
    pose = solve(corners)
    assert pose.status == PoseStatus.UNIQUE
    # Noise-free corners: IPPE + LM reach the truth to solver precision (1e-8 m, 1e-6 deg).
    np.testing.assert_allclose(pose.T[:3, 3], T[:3, 3], atol=1e-8)
    assert deg(pose.T[:3, :3], T[:3, :3]) < 1e-6
    assert pose.rms_px < 1e-6 and pose.ratio > 1e3  # the mirror pose reprojects visibly worse


def _ambiguous_case():
    """Noisy corners of a small, far, nearly face-on tag whose two poses reproject alike."""
    rng = np.random.default_rng(0)
    for _ in range(200):
        T = view(rng, 3.0, 15.0)
        corners = CAM.project_points(tag_object_points(SIZE), T) + rng.normal(0, 0.3, (4, 2))
        pose = solve(corners)
        if pose.status == PoseStatus.AMBIGUOUS:
            return T, corners, pose
    raise AssertionError("no ambiguous case among 200 noisy small far tags")


def test_ambiguous_pose_is_flagged_and_a_prediction_decides():
    T, corners, pose = _ambiguous_case()
    assert pose.ratio < 3.0 and pose.separation_deg >= 2.0
    assert pose.alternative is not None and pose.T is not None  # both kept for the caller
    for chosen in (pose.T, pose.alternative):
        # A prediction 1 degree away from one solution picks that one, whatever reprojects best.
        predicted = chosen.copy()
        predicted[:3, :3] = chosen[:3, :3] @ so3_exp(np.deg2rad([1.0, 0.0, 0.0]))
        resolved = solve(corners, predicted=predicted)
        assert resolved.status == PoseStatus.RESOLVED_BY_PREDICTION
        np.testing.assert_allclose(resolved.T, chosen, atol=1e-12)
    # A prediction halfway between the two decides nothing.
    half = pose.T.copy()
    rotvec = np.deg2rad(pose.separation_deg) * 0.5
    axis = invert_transform(pose.T)[:3, :3] @ pose.alternative[:3, :3]
    w = np.array([axis[2, 1] - axis[1, 2], axis[0, 2] - axis[2, 0], axis[1, 0] - axis[0, 1]])
    half[:3, :3] = pose.T[:3, :3] @ so3_exp(rotvec * w / np.linalg.norm(w))
    assert solve(corners, predicted=half).status == PoseStatus.AMBIGUOUS
    # min_ratio = 1 switches the check off.
    assert solve(corners, min_ratio=1.0).status == PoseStatus.UNIQUE


def test_options_are_validated_by_name():
    corners = CAM.project_points(tag_object_points(SIZE), view(np.random.default_rng(1), 1, 20))
    for kw, name in (({"min_ratio": 0.5}, "min_ratio"),
                     ({"min_separation_deg": -1.0}, "min_separation_deg"),
                     ({"prediction_margin": 0.0}, "prediction_margin")):
        with pytest.raises(ValueError, match=name):
            solve(corners, **kw)
    with pytest.raises(ValueError, match="N >= 4"):
        solve_planar_pose(np.zeros((3, 3)), np.zeros((3, 2)), np.zeros((3, 2)), CAM)
    with pytest.raises(ValueError, match="flip_min_ratio"):
        DetectorConfig(flip_min_ratio=0.9)


def _is_flip(T_true, T_kept, corners):
    """The kept pose is the mirror one: the other IPPE solution is nearer the truth."""
    pose = solve(corners)
    if pose.alternative is None or pose.separation_deg < 2.0:
        return False
    other = pose.alternative if np.allclose(pose.T, T_kept, atol=1e-9) else pose.T
    return deg(T_true[:3, :3], T_kept[:3, :3]) > deg(T_true[:3, :3], other[:3, :3])


def test_rendered_small_far_tags_flip_without_the_check_and_not_with_it():
    """8 cm tags at 3 m (25 px), 0-30 degrees off face-on, noisy images: the planar ambiguity
    shows (some kept poses are the mirror ones without the check); with the default check none
    is kept, the ambiguous ones are rejected with their reason, and a predicted pose (the truth
    turned by 2 degrees, a realistic current estimate) resolves most of them correctly (not
    those whose two poses are both several degrees off the truth: still rejected)."""
    off = TagDetector(DetectorConfig(default_tag_size=SIZE, flip_min_ratio=1.0))
    on = TagDetector(DetectorConfig(default_tag_size=SIZE))
    rng = np.random.default_rng(30)
    flips_off = kept_on = ambiguous = resolved = kept_pred = 0
    for _ in range(30):
        T = view(rng, 3.0, 30.0)
        img = render_tags(CAM, [RenderedTag(0, T, SIZE)], noise_std=2.0, blur_sigma=0.6, rng=rng)
        res_off = off.detect(img, CAM)
        assert res_off.observations, "every view is detected (25 px > min_side_px)"
        o = res_off.observations[0]
        flipped = _is_flip(T, o.T_cam_tag, o.corners)
        flips_off += flipped
        res_on = on.detect(img, CAM)
        if res_on.observations:
            kept_on += 1
            assert not _is_flip(T, res_on.observations[0].T_cam_tag, o.corners)
        else:
            assert [r.reason for r in res_on.rejections] == [RejectReason.AMBIGUOUS_POSE.value]
            ambiguous += 1
        if flipped:
            assert not res_on.observations  # every flip is caught
        predicted = T.copy()
        predicted[:3, :3] = T[:3, :3] @ so3_exp(np.deg2rad([2.0, 0.0, 0.0]))
        res_pred = on.detect(img, CAM, predicted={0: predicted})
        if res_on.observations:  # a prediction never overrides a clear reprojection verdict
            assert res_pred.observations[0].pose_status == PoseStatus.UNIQUE.value
            np.testing.assert_array_equal(res_pred.observations[0].T_cam_tag,
                                          res_on.observations[0].T_cam_tag)
        for obs in res_pred.observations:
            kept_pred += 1
            assert not _is_flip(T, obs.T_cam_tag, o.corners)
            resolved += obs.pose_status == PoseStatus.RESOLVED_BY_PREDICTION.value
    # Measured with these seeds: 2 flips without the check; 16 kept and 14 ambiguous with it;
    # 13 of the 14 resolved by the prediction.
    assert flips_off >= 2  # the scenario does produce flips
    assert ambiguous >= flips_off and kept_on + ambiguous == 30
    assert kept_pred == kept_on + resolved and resolved >= ambiguous // 2

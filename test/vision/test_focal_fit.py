"""The focal length that the tag corners fit, per camera (issue 16: the verdict's focal check)."""

import numpy as np
import pytest

from rwhec_ros.core.lie import invert_transform
from rwhec_ros.simulation import Trajectory
from rwhec_ros.simulation.rig import demo_rig
from rwhec_ros.vision.detection import DetectorConfig, TagDetector, tag_object_points
from rwhec_ros.vision.focal_fit import fit_focal_scale, scaled_focal
from rwhec_ros.vision.render import look_at

DISTORTION = np.array([-0.2, 0.05, 0.001, -0.001, 0.0])  # a typical plumb_bob lens


def _projected(cam="cam1", noise_px=0.2, seed=0):
    """Corners of the demo rig's tags seen by ``cam`` over 24 s (one view per 0.25 s),
    projected through a distorted lens with Gaussian pixel noise."""
    rig = demo_rig()
    intr = rig.intrinsics[cam].with_distortion(DISTORTION, "plumb_bob")
    rng = np.random.default_rng(seed)
    corners = []
    for t in np.arange(0.0, 24.0, 0.25):
        for seen in rig.visible_tags(cam, rig.T_world_rig(t)):
            c = intr.project_points(tag_object_points(rig.tag_size), seen.T_cam_tag)
            corners.append(c + noise_px * rng.standard_normal(c.shape))
    return corners, intr


def test_the_right_focal_length_fits_and_a_wrong_one_is_measured():
    corners, intr = _projected(noise_px=0.1)
    assert len(corners) > 30
    good = fit_focal_scale(corners, intr)
    # 0.1 px noise on 33 views: std ~0.5 % (measured 0.47-0.55 % over 3 seeds; it grows
    # linearly with the noise); 4 std is the verdict's test
    assert abs(good.scale - 1.0) < 4 * good.scale_std and good.scale_std < 0.01
    assert good.fitted_rms_px <= good.rms_px + 1e-9  # the fit can only lower the residual
    for factor in (1.05, 0.95):
        wrong = fit_focal_scale(corners, scaled_focal(intr, factor))
        # the corners fit the true focal length: 1/factor of the configured one, to the noise
        assert wrong.scale == pytest.approx(1.0 / factor, abs=4 * wrong.scale_std)
        assert abs(wrong.scale - 1.0) > 6 * wrong.scale_std  # measured 8.5-11 std
        assert wrong.rms_px > 1.2 * good.rms_px  # the per-image fit as configured is worse
        # with the fitted focal length the per-image fit is as good as with the true one
        assert wrong.fitted_rms_px == pytest.approx(good.rms_px, rel=0.1)


def test_noise_free_corners_give_the_factor_exactly():
    corners, intr = _projected(noise_px=0.0)
    fit = fit_focal_scale(corners, scaled_focal(intr, 1.05))
    # a parabola step on an almost quadratic cost: the factor to 1e-4 without noise
    assert fit.scale == pytest.approx(1 / 1.05, abs=1e-4)


def test_tags_seen_face_on_do_not_claim_a_focal_length():
    """A tag seen face-on at the image centre: the depth absorbs any focal length, so the
    factor is not determined (NaN) or its std is too large to be significant."""
    rig = demo_rig()
    intr = rig.intrinsics["cam0"]
    rng = np.random.default_rng(1)
    corners = []
    for d in np.linspace(0.6, 1.2, 12):
        # camera on the tag's normal, looking at its centre
        T = invert_transform(look_at(np.array([0.0, 0.0, d]), np.zeros(3), up=(0.0, 1.0, 0.0)))
        c = intr.project_points(tag_object_points(0.16), T)
        corners.append(c + 0.2 * rng.standard_normal(c.shape))
    fit = fit_focal_scale(corners, scaled_focal(intr, 1.05))
    assert not np.isfinite(fit.scale) or abs(fit.scale - 1.0) < 4 * fit.scale_std


def test_too_few_images_and_bad_options():
    corners, intr = _projected()
    fit = fit_focal_scale(corners[:2], intr)
    assert fit.n_images == 2 and np.isnan(fit.scale) and np.isinf(fit.scale_std)
    with pytest.raises(ValueError, match="max_images"):
        fit_focal_scale(corners, intr, max_images=2)
    assert fit_focal_scale(corners, intr, max_images=10).n_images == 10


def test_rendered_and_detected_corners():
    """The detector's corners on rendered images (blur, noise, supersampling) of cam1 over one
    12-s turn (10 images): the right focal length fits, one 5 % too large is measured."""
    rig = demo_rig(3, 6, trajectory=Trajectory(yaw_rate=2 * np.pi / 12.0))
    cam = "cam1"
    detector = TagDetector(DetectorConfig(default_tag_size=rig.tag_size))
    rng = np.random.default_rng(3)
    corners = []
    for t in np.arange(0.0, 12.0, 0.6):
        T_world_rig = rig.T_world_rig(t)
        if not rig.visible_tags(cam, T_world_rig):
            continue
        img = rig.render(cam, T_world_rig, rng, supersample=2)
        corners += [o.corners for o in detector.detect(img, rig.intrinsics[cam]).observations]
    assert len(corners) >= 8  # 10 views of a tag in this turn
    intr = rig.intrinsics[cam]
    good = fit_focal_scale(corners, intr)
    wrong = fit_focal_scale(corners, scaled_focal(intr, 1.05))
    # benchmarks/verdict.py section 3: rendered good runs within 0.3 % of 1, 5 % off at
    # 0.953-0.955 (the renderer's small bias); the verdict's thresholds are 2 % and 4 std
    assert abs(good.scale - 1.0) < 0.01
    assert wrong.scale == pytest.approx(1 / 1.05, abs=0.01)
    assert abs(wrong.scale - 1.0) > 4 * wrong.scale_std


def _board_views(noise_px=0.2, seed=0):
    """Corners of an AprilGrid (3 x 3 tags, demo layout) at the demo's position 0 seen by the
    demo cameras over 24 s: per view the grid tags fully in the image (often a part of the
    board), projected through a distorted lens with Gaussian pixel noise."""
    from rwhec_ros.simulation.rig import demo_board

    rig = demo_rig()
    board = demo_board("aprilgrid", 0)
    intr = rig.intrinsics["cam0"].with_distortion(DISTORTION, "plumb_bob")
    rng = np.random.default_rng(seed)
    corners, points = [], []
    for t in np.arange(0.0, 24.0, 0.25):
        for cam in rig.cameras:  # same intrinsics for all: views of three cameras for one lens
            T = rig.T_cam_tag(cam, 0, rig.T_world_rig(t))
            if T[2, 3] < 0.1 or float(T[:3, 2] @ T[:3, 3]) >= 0:
                continue
            P = [board.marker_object_points(m) for m in board.marker_ids]
            keep = [p for p in P if _inside(intr.project_points(p, T))]
            if len(keep) >= 2:
                obj = np.concatenate(keep)
                c = intr.project_points(obj, T)
                corners.append(c + noise_px * rng.standard_normal(c.shape))
                points.append(obj)
    return corners, points, intr


def _inside(uv):
    return bool((uv >= 2).all() and (uv[:, 0] < 638).all() and (uv[:, 1] < 478).all())


def test_board_corners_measure_the_focal_length():
    """Board views (K = 8..36 corners each, board-frame points per view): the right focal length
    fits, one 5 % off is measured, with the std of the tags' case or smaller for the same
    noise (more corners per view)."""
    corners, points, intr = _board_views(noise_px=0.2)
    assert len(corners) >= 20 and len({len(c) for c in corners}) > 1
    good = fit_focal_scale(corners, intr, object_points=points)
    assert good.n_images == len(corners)
    # rms of the 2D corner error: 0.2 px per axis over the 2 K - 6 residual degrees of freedom
    # of each view (its pose absorbs 6), within 10 % (hundreds of corners)
    k = np.array([len(c) for c in corners])
    assert good.rms_px == pytest.approx(0.2 * np.sqrt(np.sum(2 * k - 6) / k.sum()), rel=0.1)
    assert abs(good.scale - 1.0) < 4 * good.scale_std and good.scale_std < 0.01
    wrong = fit_focal_scale(corners, scaled_focal(intr, 1.05), object_points=points)
    assert wrong.scale == pytest.approx(1 / 1.05, abs=4 * wrong.scale_std)
    assert abs(wrong.scale - 1.0) > 6 * wrong.scale_std
    tags, tag_intr = _projected(cam="cam0", noise_px=0.2)
    # the tags' std with the same noise (33+ views of four corners) is larger
    assert good.scale_std < fit_focal_scale(tags, tag_intr).scale_std
    with pytest.raises(ValueError, match="object_points: expected one entry per image"):
        fit_focal_scale(corners, intr, object_points=points[:-1])


def test_tags_and_boards_mix_in_one_fit():
    corners, points, intr = _board_views(noise_px=0.0)
    tags, _ = _projected(cam="cam0", noise_px=0.0)
    fit = fit_focal_scale(corners + tags, scaled_focal(intr, 1.05),
                          object_points=points + [None] * len(tags))
    assert fit.n_images == min(100, len(corners) + len(tags))
    assert fit.scale == pytest.approx(1 / 1.05, abs=1e-4)  # noise free: as the tags' test

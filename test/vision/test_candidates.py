"""Candidate search (decimated or not): coordinates, factor choice, accuracy, small tags."""

import cv2
import numpy as np
import pytest

from rwhec_ros.core.lie import rotation_distance
from rwhec_ros.vision.candidates import (
    AUTO_DECIMATE_MIN_SIDE_PX,
    REDETECT_BELOW_PX_PER_CELL,
    corners_to_full_resolution,
    decimate_image,
    decimation_factor,
    min_perimeter_rate,
    redetect_in_window,
)
from rwhec_ros.vision.detection import DetectorConfig, TagDetector
from rwhec_ros.vision.families import aruco_dictionary
from rwhec_ros.vision.intrinsics import CameraIntrinsics
from rwhec_ros.vision.render import RenderedTag, look_at, render_tags

CAM = CameraIntrinsics.pinhole(1280, 1024, 1000.0)
SIZE = 0.16


def face_on(distance):
    T = np.diag([1.0, -1.0, -1.0, 1.0])
    T[:3, 3] = [0.0, 0.0, distance]
    return T


def random_view(rng, distance):
    """T_cam_tag for a camera up to 45 degrees off the tag normal, aimed near its centre."""
    th, ph = np.deg2rad(rng.uniform(0, 45)), rng.uniform(0, 2 * np.pi)
    pos = distance * np.array([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
    T_tag_cam = look_at(pos, [*rng.normal(0, 0.05, 2), 0.0], up=[0.0, 1.0, 0.0])
    return np.linalg.inv(T_tag_cam)


def test_pixel_centres_correspond_under_area_decimation():
    """A bright square of whole 3 x 3 blocks: its centroid in the small image, mapped back,
    is its centroid in the full image (the pixel-centre convention of the mapping)."""
    full = np.zeros((90, 120), np.uint8)
    full[30:48, 60:75] = 255  # rows 30..47 (centre 38.5), columns 60..74 (centre 67)
    small = decimate_image(full, 3)
    assert small.shape == (30, 40)
    v, u = np.nonzero(small)
    centre = corners_to_full_resolution(np.array([[u.mean(), v.mean()]]), small.shape, full.shape)
    np.testing.assert_allclose(centre, [[67.0, 38.5]])
    assert decimate_image(full, 1) is full


def test_mapping_uses_the_exact_size_ratio():
    # 1001 columns -> 500 at factor 2: the scale is 1001 / 500, not 2.
    out = corners_to_full_resolution(np.array([[499.5, 0.0]]), (300, 500), (601, 1001))
    np.testing.assert_allclose(out, [[1000.5, 0.5 * 601 / 300 - 0.5]])


def test_decimation_factor():
    assert AUTO_DECIMATE_MIN_SIDE_PX == 600
    assert decimation_factor("auto", 640, 480) == 1
    assert decimation_factor("auto", 1280, 1024) == 2
    assert decimation_factor("AUTO", 2448, 2048) == 4
    assert decimation_factor(3, 640, 480) == 3
    assert decimation_factor(50, 640, 480) == 30  # never below 16 px on the shorter side
    for bad in (0, -2, 1.5, True, "x", None):
        with pytest.raises(ValueError, match="decimate"):
            decimation_factor(bad, 640, 480)


def test_min_perimeter_rate_is_one_pixel_per_cell():
    assert min_perimeter_rate(8, 640, 512) == pytest.approx(32 / 640)
    assert min_perimeter_rate(8, 6400, 10) == 0.01  # the floor


def test_only_refinements_with_a_full_resolution_step_decimate():
    assert DetectorConfig(decimate=2).decimation_for(1280, 1024) == 2
    assert DetectorConfig(corner_refinement="subpix").decimation_for(1280, 1024) == 2
    for mode in ("none", "contour", "apriltag"):
        assert DetectorConfig(corner_refinement=mode, decimate=2).decimation_for(1280, 1024) == 1


@pytest.mark.parametrize("refinement", ["edge", "subpix"])
def test_decimated_search_keeps_corner_and_pose_accuracy(refinement):
    """Same images, full-resolution and factor-2 search: the refined corners and the poses
    agree to within the refinement's own noise."""
    rng = np.random.default_rng(7)
    full = TagDetector(
        DetectorConfig(default_tag_size=SIZE, decimate=1, corner_refinement=refinement)
    )
    half = TagDetector(
        DetectorConfig(default_tag_size=SIZE, decimate=2, corner_refinement=refinement)
    )
    for _ in range(6):
        T = random_view(rng, rng.uniform(0.6, 2.5))
        img = render_tags(CAM, [RenderedTag(3, T, SIZE)], noise_std=1.0, blur_sigma=0.5, rng=rng)
        a, b = full.detect(img, CAM), half.detect(img, CAM)
        assert [o.tag_id for o in a.observations] == [o.tag_id for o in b.observations] == [3]
        ca, cb = a.observations[0].corners, b.observations[0].corners
        # edge: 0.05 px (measured <= 0.034 px between the two searches, 20 views, noise 2 grey
        # levels); subpix: cornerSubPix stops at 0.1 px steps from different seeds (measured
        # <= 0.14 px).
        assert np.max(np.abs(ca - cb)) < (0.05 if refinement == "edge" else 0.25)
        Ta, Tb = a.observations[0].T_cam_tag, b.observations[0].T_cam_tag
        # The two poses agree far below the pose error itself (measured on these views: edge
        # 0.07 mm / 0.011 deg, subpix 0.2 mm / 0.03 deg apart; errors up to 0.3 mm / 0.05 deg for
        # edge and 12 mm / 0.27 deg for subpix, whose corners are biased).
        assert 1000.0 * np.linalg.norm(Ta[:3, 3] - Tb[:3, 3]) < 0.6
        assert np.degrees(rotation_distance(Ta[:3, :3], Tb[:3, :3])) < 0.1
        if refinement == "edge":  # the acceptance figures of test_detection.py
            assert 1000.0 * np.linalg.norm(Tb[:3, 3] - T[:3, 3]) < 2.0
            assert np.degrees(rotation_distance(Tb[:3, :3], T[:3, :3])) < 0.2


def test_decimation_raises_the_smallest_detectable_tag():
    """The documented cost: an 18 px tag is found (and gated as too small) at full resolution
    but not searched at factor 2; a 40 px tag is found at both."""
    detectors = {d: TagDetector(DetectorConfig(default_tag_size=SIZE, decimate=d)) for d in (1, 2)}
    for distance, seen_at_2 in ((9.0, False), (4.0, True)):  # 18 px and 40 px sides
        tags = [RenderedTag(0, face_on(distance), SIZE)]
        img = render_tags(CAM, tags, noise_std=1.0, blur_sigma=0.5, rng=np.random.default_rng(0))
        at_1, at_2 = (detectors[d].detect(img, CAM) for d in (1, 2))
        assert len(at_1.observations) + len(at_1.rejections) == 1
        assert (len(at_2.observations) + len(at_2.rejections) == 1) is seen_at_2


def test_small_tags_are_searched_again_at_full_resolution():
    """Below REDETECT_BELOW_PX_PER_CELL pixels per cell in the decimated image (< 64 px sides at
    factor 2) the corners come from a full-resolution search in a window: the same corners as
    the full-image search (to float32 round-off), not the mapped ones (up to 4 px off)."""
    assert REDETECT_BELOW_PX_PER_CELL * 8 * 2 == 64
    full = TagDetector(DetectorConfig(default_tag_size=SIZE, decimate=1))
    half = TagDetector(DetectorConfig(default_tag_size=SIZE, decimate=2))
    for distance in (3.5, 5.0):  # 46 and 32 px sides
        tags = [RenderedTag(0, face_on(distance), SIZE)]
        img = render_tags(CAM, tags, noise_std=1.0, blur_sigma=0.5, rng=np.random.default_rng(0))
        (ids_a, (a,)), (ids_b, (b,)) = full.detect_markers(img), half.detect_markers(img)
        assert ids_a == ids_b == [0]
        # 1e-3 px: both are aruco's float32 SUBPIX corners of the same pixels.
        np.testing.assert_allclose(b, a, atol=1e-3)


def test_window_search_needs_the_same_id_near_the_same_place():
    img = render_tags(
        CAM,
        [RenderedTag(5, face_on(4.0), SIZE)],
        noise_std=1.0,
        blur_sigma=0.5,
        rng=np.random.default_rng(0),
    )
    detector = TagDetector(DetectorConfig(default_tag_size=SIZE, decimate=1))
    (_, (quad,)) = detector.detect_markers(img)
    params = DetectorConfig().aruco_parameters()
    window = cv2.aruco.ArucoDetector(aruco_dictionary("tag36h11"), params)
    found = redetect_in_window(window, params, img, quad + 1.5, 5, 8)
    np.testing.assert_allclose(found, quad, atol=1e-3)
    assert redetect_in_window(window, params, img, quad, 6, 8) is None  # another id
    assert redetect_in_window(window, params, img, quad + 200.0, 5, 8) is None  # elsewhere

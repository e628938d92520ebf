"""Board layouts (AprilGrid, ChArUco): geometry, printed pattern, OpenCV orientation, validation."""

import cv2
import numpy as np
import pytest

from rwhec_ros.vision.boards import AprilGridSpec, CharucoSpec
from rwhec_ros.vision.detection import tag_object_points
from rwhec_ros.vision.families import (
    dictionary_key,
    marker_bitmap,
    official_marker_bitmap,
    official_orientation_turned,
)

# tag36h11 in the AprilTag project's own layout (apriltag/tag36h11.c): id 0's code, and the
# (x, y) cell of each code bit (most significant first), y down from the top of the tag, inside
# the 8 x 8 black square. An independent source for the official (upright) image.
TAG36H11_CODE0 = 0xD7E00984B
BIT_X = [1, 2, 3, 4, 5, 2, 3, 4, 3, 6, 6, 6, 6, 6, 5, 5, 5, 4, 6, 5, 4, 3, 2, 5, 4, 3, 4, 1, 1,
         1, 1, 1, 2, 2, 2, 3]
BIT_Y = [1, 1, 1, 1, 1, 2, 2, 2, 3, 1, 2, 3, 4, 5, 2, 3, 4, 3, 6, 6, 6, 6, 6, 5, 5, 5, 4, 6, 5,
         4, 3, 2, 5, 4, 3, 4]


def test_official_bitmap_matches_the_apriltag_project():
    expected = np.zeros((8, 8), dtype=np.uint8)
    for i in range(36):
        if TAG36H11_CODE0 & (1 << (35 - i)):
            expected[BIT_Y[i], BIT_X[i]] = 255
    np.testing.assert_array_equal(official_marker_bitmap("tag36h11", 0), expected)
    cv_drawn = marker_bitmap("tag36h11", 0, quiet_zone_cells=0)
    turned = official_orientation_turned("tag36h11")
    np.testing.assert_array_equal(cv_drawn, np.rot90(expected, 2) if turned else expected)
    if cv2.__version__.startswith("4."):
        assert turned  # OpenCV 4.x draws AprilTags upside down (opencv/opencv#28823)
    assert not official_orientation_turned("DICT_5X5_100")  # ArUco: OpenCV's own drawing
    two = official_marker_bitmap("tag36h11", 0, border_bits=2)
    assert two.shape == (10, 10) and np.all(two[[0, 1, -2, -1], :] == 0)
    np.testing.assert_array_equal(two[1:-1, 1:-1], expected)


def test_dictionary_names():
    assert dictionary_key("36h11") == dictionary_key("DICT_APRILTAG_36h11") == "tag36h11"
    assert dictionary_key("5x5_100") == dictionary_key("DICT_5X5_100") == "DICT_5X5_100"
    assert dictionary_key("aruco_original") == "DICT_ARUCO_ORIGINAL"
    with pytest.raises(ValueError, match="unknown dictionary 'DICT_9X9_1'"):
        dictionary_key("DICT_9X9_1")


def test_aprilgrid_geometry_follows_kalibr():
    g = AprilGridSpec(rows=2, cols=3, tag_size=0.1, tag_spacing=0.3, first_id=10)
    # 1e-12: sums of a few exact decimal products.
    assert g.width == pytest.approx(3 * 0.1 + 2 * 0.03, abs=1e-12)
    assert g.height == pytest.approx(2 * 0.1 + 0.03, abs=1e-12)
    assert g.marker_ids == (10, 11, 12, 13, 14, 15) and g.cells == 10 and g.n_corners == 24
    # Kalibr: id 10 bottom-left, ids along +x, then up a row; origin at the pattern centre.
    np.testing.assert_allclose(g.tag_centre(10), [-0.13, -0.065, 0.0], atol=1e-12)
    np.testing.assert_allclose(g.tag_centre(12), [0.13, -0.065, 0.0], atol=1e-12)
    np.testing.assert_allclose(g.tag_centre(13), [-0.13, 0.065, 0.0], atol=1e-12)
    # In Kalibr's target frame (origin at the outer bottom-left corner of tag 0) the bottom-left
    # corner of the first tag is the origin.
    corners = g.marker_object_points(10) + [0.5 * g.width, 0.5 * g.height, 0.0]
    assert np.min(np.linalg.norm(corners, axis=1)) < 1e-12
    with pytest.raises(ValueError, match="not on this grid"):
        g.tag_centre(16)


def test_one_tag_grid_is_the_single_tag_frame_up_to_opencvs_turn():
    g = AprilGridSpec(1, 1, 0.16, border_bits=1)
    pts = g.marker_object_points(0)
    single = tag_object_points(0.16)  # in OpenCV's drawing of the tag
    if official_orientation_turned("tag36h11"):
        single = single * [-1.0, -1.0, 1.0]  # turned by 180 degrees about z
    np.testing.assert_allclose(pts, single, atol=1e-15)


def test_aprilgrid_texture_is_the_kalibr_pattern():
    """Sampled at cell centres, the texture equals a grid assembled from the official bitmaps:
    tags upright, 2-bit borders, gaps of 3 cells, black squares at every gap crossing."""
    g = AprilGridSpec(2, 3, tag_size=0.1, tag_spacing=0.3, first_id=4)
    cell = 0.01  # 10 cells per tag, gap 3 cells
    n_x, n_y = 3 * 10 + 4 * 3, 2 * 10 + 3 * 3  # with a gap-wide border of corner squares
    expected = np.full((n_y, n_x), 255, dtype=np.uint8)
    for r in range(2):
        for c in range(3):
            top = 3 + (1 - r) * 13  # row 0 of the image is the top of the board
            left = 3 + c * 13
            expected[top:top + 10, left:left + 10] = official_marker_bitmap(
                "tag36h11", 4 + 3 * r + c, border_bits=2)
    for top in (0, 13, 26):
        for left in (0, 13, 26, 39):
            expected[top:top + 3, left:left + 3] = 0
    xs = -0.5 * g.width - g.gap + (np.arange(n_x) + 0.5) * cell
    ys = 0.5 * g.height + g.gap - (np.arange(n_y) + 0.5) * cell
    X, Y = np.meshgrid(xs, ys)
    np.testing.assert_array_equal(np.where(g.texture(X, Y) > 0, 255, 0), expected)


def test_charuco_matches_opencv():
    c = CharucoSpec(5, 4, square_size=0.04, marker_size=0.024, dictionary="4x4_50")
    board = c.cv2_board()
    W, H = c.width, c.height
    cv_pts = np.asarray(board.getChessboardCorners(), dtype=float)
    ours = c.corner_object_points()
    # Documented frame change: p_cv = (x + W/2, H/2 - y, -z); 1e-7 m: OpenCV keeps float32.
    np.testing.assert_allclose(np.c_[ours[:, 0] + W / 2, H / 2 - ours[:, 1], -ours[:, 2]],
                               cv_pts, atol=1e-7)
    for marker_id, quad in zip(np.asarray(board.getIds()).ravel(), board.getObjPoints(),
                               strict=True):
        mine = c.marker_object_points(int(marker_id))
        np.testing.assert_allclose(np.c_[mine[:, 0] + W / 2, H / 2 - mine[:, 1]],
                                   np.asarray(quad)[:, :2], atol=1e-7)
    # The printed pattern at 1 px per mm (6 marker cells of 4 px, squares of 40 px) equals
    # OpenCV's own drawing pixel for pixel.
    px = 0.001
    img = board.generateImage((int(round(W / px)), int(round(H / px))), marginSize=0)
    xs = -W / 2 + (np.arange(img.shape[1]) + 0.5) * px
    ys = H / 2 - (np.arange(img.shape[0]) + 0.5) * px
    X, Y = np.meshgrid(xs, ys)
    np.testing.assert_array_equal(np.where(c.texture(X, Y) > 0, 255, 0), img)


@pytest.mark.parametrize("legacy", [False, True])
def test_charuco_ids_and_legacy_pattern(legacy):
    c = CharucoSpec(6, 4, 0.05, 0.035, "DICT_6X6_250", first_id=30, legacy_pattern=legacy)
    assert c.marker_ids == tuple(range(30, 42)) and c.n_corners == 15
    board = c.cv2_board()
    assert board.getLegacyPattern() == legacy
    np.testing.assert_array_equal(np.asarray(board.getIds()).ravel(), np.arange(30, 42))


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"rows": 0, "cols": 2, "tag_size": 0.1}, "rows"),
        ({"rows": 2, "cols": 2.5, "tag_size": 0.1}, "cols"),
        ({"rows": 2, "cols": 2, "tag_size": -0.1}, "tag_size"),
        ({"rows": 2, "cols": 2, "tag_size": 0.1, "tag_spacing": 0.05}, "tag_spacing"),
        ({"rows": 2, "cols": 2, "tag_size": 0.1, "tag_spacing": 1.5}, "tag_spacing"),
        ({"rows": 2, "cols": 2, "tag_size": 0.1, "family": "tag99h9"}, "family"),
        ({"rows": 2, "cols": 2, "tag_size": 0.1, "border_bits": 0}, "border_bits"),
        ({"rows": 2, "cols": 2, "tag_size": 0.1, "first_id": -1}, "first_id"),
        ({"rows": 10, "cols": 10, "tag_size": 0.1, "family": "tag16h5"}, "first_id"),
    ],
)
def test_aprilgrid_validation_names_the_field(kwargs, field):
    with pytest.raises(ValueError, match=field):
        AprilGridSpec(**kwargs)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"squares_x": 1}, "squares_x"),
        ({"squares_y": 0}, "squares_y"),
        ({"square_size": 0.0}, "square_size"),
        ({"marker_size": 0.05}, "marker_size"),
        ({"dictionary": "DICT_5X5_7"}, "dictionary"),
        ({"dictionary": "DICT_4X4_50", "squares_x": 12, "squares_y": 10}, "first_id"),
    ],
)
def test_charuco_validation_names_the_field(kwargs, field):
    base = {"squares_x": 5, "squares_y": 4, "square_size": 0.04, "marker_size": 0.03}
    with pytest.raises(ValueError, match=field):
        CharucoSpec(**{**base, **kwargs})

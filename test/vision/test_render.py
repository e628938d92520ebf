"""Synthetic renderer: exact pixel content on aligned cases, coverage, visibility, randomness."""

import numpy as np
import pytest

from rwhec_ros.core.lie import invert_transform
from rwhec_ros.vision.boards import AprilGridSpec, CharucoSpec
from rwhec_ros.vision.families import APRILTAG_FAMILIES, marker_bitmap, marker_cells
from rwhec_ros.vision.intrinsics import CameraIntrinsics
from rwhec_ros.vision.render import (
    RenderedBoard,
    RenderedTag,
    look_at,
    render_tags,
    sample_offsets,
)

BLACK, WHITE, BACKGROUND = 30.0, 225.0, 128.0


def face_on(x=0.0, y=0.0, z=1.0):
    """Upright tag facing the camera: tag x = camera x, tag y = -camera y."""
    T = np.diag([1.0, -1.0, -1.0, 1.0])
    T[:3, 3] = [x, y, z]
    return T


def test_look_at_frame():
    T = look_at([1.0, 2.0, 3.0], [0.0, 0.0, 0.5], up=[0.0, 0.0, 1.0])
    R = T[:3, :3]
    # 1e-12: orthonormality from exact cross products of unit vectors.
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)
    to_target = np.array([0.0, 0.0, 0.5]) - [1.0, 2.0, 3.0]
    np.testing.assert_allclose(R[:, 2], to_target / np.linalg.norm(to_target), atol=1e-12)
    assert R[:, 1] @ [0.0, 0.0, 1.0] < 0  # image y (down) points against world up
    assert abs(R[:, 0] @ [0.0, 0.0, 1.0]) < 1e-12  # no roll: image x stays horizontal
    with pytest.raises(ValueError, match="target_point"):
        look_at([1.0, 1.0, 1.0], [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="up"):
        look_at([0.0, 0.0, 1.0], [0.0, 0.0, 0.0], up=[0.0, 0.0, 1.0])


def test_look_at_facing_tag_gives_the_face_on_pose():
    T_cam_tag = invert_transform(look_at([0.0, 0.0, 1.0], [0.0, 0.0, 0.0], up=[0.0, 1.0, 0.0]))
    # 1e-12: exact arithmetic on axis-aligned vectors.
    np.testing.assert_allclose(T_cam_tag, face_on(), atol=1e-12)


def test_sample_offsets_are_a_latin_square_in_the_pixel():
    off = sample_offsets(4)
    assert off.shape == (16, 2)
    assert np.all(np.abs(off) < 0.5)
    for axis in range(2):  # every sample has its own x and its own y, 1/16 px apart
        np.testing.assert_allclose(np.sort(off[:, axis]), (np.arange(16) + 0.5) / 16 - 0.5)


# the bad edge directions of the 2 x 2, 3 x 3 and 4 x 4 lattices (45 degrees, slopes 1/2, 1/3)
@pytest.mark.parametrize("turn_deg", [45.0, 26.57, 18.43])
def test_shifted_pattern_locates_tags_turned_at_any_angle(turn_deg):
    """The demo's images (DEMO_SUPERSAMPLE samples, the pattern shifted in every pixel) locate
    the corners of a tag turned in the image at the angles where a fixed lattice resolves an
    edge in few coverage levels; the fixed lattice of the same size does not at its bad angle."""
    from rwhec_ros.core.lie import make_transform, so3_exp
    from rwhec_ros.simulation import DEMO_SUPERSAMPLE
    from rwhec_ros.vision.detection import DetectorConfig, TagDetector, tag_object_points

    cam = CameraIntrinsics.pinhole(640, 480, 500.0)
    T = face_on(0.02, -0.03, 1.2) @ make_transform(
        so3_exp(np.array([0.05, -0.08, np.radians(turn_deg)])), np.zeros(3))
    truth = cam.project_points(tag_object_points(0.25), T)
    det = TagDetector(DetectorConfig(tag_sizes={7: 0.25}))

    def corner_error(shift: bool) -> float:
        img = render_tags(cam, [RenderedTag(7, T, 0.25)], supersample=DEMO_SUPERSAMPLE,
                          blur_sigma=0.6, shift_pattern=shift)
        obs = det.detect(img, cam).by_id()[7]
        return float(np.sqrt(np.mean(np.sum((obs.corners - truth) ** 2, axis=1))))

    err = corner_error(True)
    # measured 0.03-0.10 px shifted (at 45 degrees the edge fit itself leaves ~0.1 px on this
    # noise-free view with 5 x 5 fixed samples too); the fixed 3 x 3 lattice: 0.46 px at 1/2
    assert err < 0.15, err
    if turn_deg == 26.57:
        assert corner_error(False) > 0.3


def test_pixel_aligned_tag_equals_the_upscaled_bitmap():
    """f = 1000 px, 8 cm tag at 1 m, principal point at a pixel corner: 10 px per cell exactly."""
    cam = CameraIntrinsics.pinhole(200, 160, 1000.0, cx=99.5, cy=79.5)
    img = render_tags(cam, [RenderedTag(7, face_on(), 0.08)], "tag36h11", supersample=2)
    bitmap = marker_bitmap("tag36h11", 7)  # 10 x 10 cells with the quiet zone
    expected = np.kron(np.where(bitmap > 127, WHITE, BLACK), np.ones((10, 10)))
    np.testing.assert_array_equal(img[30:130, 50:150], expected.astype(np.uint8))
    assert np.all(img[:30] == BACKGROUND) and np.all(img[:, :50] == BACKGROUND)
    assert np.all(img[130:] == BACKGROUND) and np.all(img[:, 150:] == BACKGROUND)


def test_edge_pixels_carry_the_covered_area():
    """A shift of 0.3 px gives edge pixels 30 % / 70 % coverage (1/16 px lattice resolution)."""
    cam = CameraIntrinsics.pinhole(200, 160, 1000.0, cx=99.5, cy=79.5)
    img = render_tags(cam, [RenderedTag(7, face_on(x=0.0003), 0.08)], supersample=4)
    # Left edge of the quiet zone at u = 49.5 + 0.3: pixel 49 stays background, pixel 50 is
    # 30 % background and 70 % white. 5/16 is the lattice's nearest level to 0.3.
    level = 5 / 16 * BACKGROUND + 11 / 16 * WHITE
    # 0.5 grey level: rounding to uint8.
    np.testing.assert_allclose(img[40:120, 50], level, atol=0.5)
    np.testing.assert_array_equal(img[40:120, 49], BACKGROUND)


def test_mean_intensity_matches_black_fraction_at_an_angle():
    """Area is preserved: total darkness of an oblique tag equals the projected cell areas."""
    cam = CameraIntrinsics.pinhole(640, 480, 800.0)
    T_cam_tag = invert_transform(look_at([0.4, 0.2, 0.9], [0.0, 0.0, 0.0], up=[0.0, 1.0, 0.0]))
    tag = RenderedTag(3, T_cam_tag, 0.12)
    img = render_tags(cam, [tag], image=WHITE, supersample=6).astype(float)
    darkness = np.sum(WHITE - img) / (WHITE - BLACK)
    # Independent path: sum the projected areas (shoelace) of the black cells.
    bitmap = marker_bitmap("tag36h11", 3)
    cell = 0.12 / marker_cells("tag36h11")
    half = 0.5 * bitmap.shape[0] * cell
    area = 0.0
    for r, c in zip(*np.nonzero(bitmap < 128), strict=True):
        x0, y0 = -half + c * cell, half - r * cell
        corners = np.array(
            [[x0, y0, 0], [x0 + cell, y0, 0], [x0 + cell, y0 - cell, 0], [x0, y0 - cell, 0]]
        )
        uv = cam.project_points(corners, T_cam_tag)
        area += 0.5 * abs(
            np.dot(uv[:, 0], np.roll(uv[:, 1], -1)) - np.dot(uv[:, 1], np.roll(uv[:, 0], -1))
        )
    # 0.5 %: uint8 rounding of the edge pixels and the 36-sample lattice quantisation.
    assert darkness == pytest.approx(area, rel=5e-3)


def test_tags_behind_or_facing_away_are_skipped():
    cam = CameraIntrinsics.pinhole(320, 240, 300.0)
    behind = face_on(z=-1.0)
    away = np.diag([1.0, 1.0, 1.0, 1.0])  # tag normal +z points away from the camera
    away[2, 3] = 1.0
    img = render_tags(cam, [RenderedTag(0, behind, 0.2), RenderedTag(1, away, 0.2)])
    assert np.all(img == BACKGROUND)


def test_near_tags_occlude_far_ones():
    cam = CameraIntrinsics.pinhole(320, 240, 300.0)
    far = RenderedTag(0, face_on(z=2.0), 0.2)
    near = RenderedTag(1, face_on(z=1.0), 0.2)
    img_a = render_tags(cam, [far, near])
    img_b = render_tags(cam, [near, far])
    np.testing.assert_array_equal(img_a, img_b)
    np.testing.assert_array_equal(img_a, render_tags(cam, [near]))  # far one fully hidden


def test_background_image_blur_and_seeded_noise():
    cam = CameraIntrinsics.pinhole(160, 120, 150.0)
    background = np.tile(np.linspace(0, 255, 160), (120, 1))
    tags = [RenderedTag(2, face_on(z=1.5), 0.3)]
    clean = render_tags(cam, tags, image=background)
    assert clean[0, 0] == 0 and clean[0, -1] == 255
    a = render_tags(cam, tags, noise_std=3.0, rng=np.random.default_rng(5), blur_sigma=1.0)
    b = render_tags(cam, tags, noise_std=3.0, rng=np.random.default_rng(5), blur_sigma=1.0)
    c = render_tags(cam, tags, noise_std=3.0, rng=np.random.default_rng(6), blur_sigma=1.0)
    np.testing.assert_array_equal(a, b)
    assert np.any(a != c)
    with pytest.raises(ValueError, match="rng"):
        render_tags(cam, tags, noise_std=1.0)
    with pytest.raises(ValueError, match="image"):
        render_tags(cam, tags, image=np.zeros((10, 10)))
    with pytest.raises(ValueError, match="supersample"):
        render_tags(cam, tags, supersample=0)


def test_distorted_render_puts_corners_where_the_model_projects_them():
    """Barrel distortion: the dark quad's extreme pixels follow project_points, not the pinhole."""
    pinhole = CameraIntrinsics.pinhole(640, 480, 400.0)
    cam = pinhole.with_distortion([-0.3, 0.1, 0.0, 0.0, 0.0], "plumb_bob")
    T = face_on(x=0.25, y=0.15, z=1.0)
    img = render_tags(cam, [RenderedTag(0, T, 0.2)], image=WHITE, quiet_zone_cells=0)
    dark = np.argwhere(img < (BLACK + WHITE) / 2)
    corner = cam.project_points(np.array([[0.1, -0.1, 0.0]]), T)[0]  # bottom-right corner
    pin = pinhole.project_points(np.array([[0.1, -0.1, 0.0]]), T)[0]
    far = dark[np.argmax(dark[:, 0] + dark[:, 1])][::-1]
    # 1.5 px: the extreme dark pixel of a corner is within a pixel diagonal of the corner.
    assert np.linalg.norm(far - corner) < 1.5
    assert np.linalg.norm(pin - corner) > 5  # and the distortion (9 px here) matters


@pytest.mark.parametrize("family", sorted(APRILTAG_FAMILIES))
def test_every_family_has_bitmaps_with_a_quiet_zone(family):
    bitmap = marker_bitmap(family, 1, quiet_zone_cells=2)
    n = marker_cells(family)
    assert bitmap.shape == (n + 4, n + 4)
    assert np.all(bitmap[:2] == 255) and np.all(bitmap[:, -2:] == 255)
    assert np.all(bitmap[2, 2:-2] == 0)  # the black border row
    with pytest.raises(ValueError, match="tag_id"):
        marker_bitmap(family, 100000)


def test_face_on_charuco_board_equals_opencvs_drawing():
    """f = 1000 px, board at 1 m, principal point at a pixel corner: 1 px per mm, so a ChArUco
    board of 40 mm squares and 24 mm markers (4 px cells) renders exactly as OpenCV draws it,
    inside a white margin of half a square."""
    c = CharucoSpec(5, 4, square_size=0.04, marker_size=0.024, dictionary="DICT_4X4_50")
    cam = CameraIntrinsics.pinhole(300, 240, 1000.0, cx=149.5, cy=119.5)
    img = render_tags(cam, [RenderedBoard(c, face_on())], supersample=2)
    drawn = c.cv2_board().generateImage((200, 160), marginSize=0)
    expected = np.where(drawn > 127, WHITE, BLACK).astype(np.uint8)
    np.testing.assert_array_equal(img[40:200, 50:250], expected)
    assert np.all(img[20:40, 30:270] == WHITE) and np.all(img[200:220, 30:270] == WHITE)
    assert np.all(img[:20] == BACKGROUND) and np.all(img[:, :30] == BACKGROUND)


def test_rendered_board_validation():
    g = AprilGridSpec(2, 2, 0.1)
    with pytest.raises(ValueError, match="board"):
        RenderedBoard("grid", face_on())
    with pytest.raises(ValueError, match="T_cam_board"):
        RenderedBoard(g, np.eye(3))
    with pytest.raises(ValueError, match="margin"):
        RenderedBoard(g, face_on(), margin=-0.1)
    # Default margin: one gap (0.03 m) beyond the corner squares (another gap).
    x0, x1, y0, y1 = RenderedBoard(g, face_on()).extent()
    # 1e-12: sums of exact decimals.
    assert x1 == pytest.approx(0.5 * g.width + 2 * g.gap, abs=1e-12) and x0 == -x1
    assert y1 == pytest.approx(0.5 * g.height + 2 * g.gap, abs=1e-12) and y0 == -y1

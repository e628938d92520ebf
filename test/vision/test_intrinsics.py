"""CameraIntrinsics: CameraInfo parsing, validation, projection vs textbook formulas, inverses."""

from types import SimpleNamespace

import numpy as np
import pytest

from rwhec_ros.vision.intrinsics import DISTORTION_MODELS, CameraIntrinsics

K_LIST = [1000.0, 0.0, 639.5, 0.0, 1010.0, 511.5, 0.0, 0.0, 1.0]
PLUMB_BOB = [-0.28, 0.09, 0.0008, -0.0005, -0.015]
RATIONAL = [0.6, -0.2, 0.001, -0.001, 0.05, 0.9, -0.1, 0.08]
EQUIDISTANT = [0.08, -0.02, 0.004, -0.001]


def camera_info(**overrides):
    msg = dict(width=1280, height=1024, k=K_LIST, d=PLUMB_BOB, distortion_model="plumb_bob")
    msg.update(overrides)
    return SimpleNamespace(**msg)


def random_points(rng, n=200):
    """Points in front of the camera within about +-30 degrees of the axis."""
    return np.c_[rng.uniform(-0.5, 0.5, (n, 2)), rng.uniform(0.9, 3.0, n)]


def textbook_projection(K, D, model, P):
    """Independent implementation of the three distortion models (OpenCV documentation)."""
    x, y = P[:, 0] / P[:, 2], P[:, 1] / P[:, 2]
    D = np.asarray(D, dtype=float)
    if model == "equidistant":
        r = np.hypot(x, y)
        theta = np.arctan(r)
        k1, k2, k3, k4 = D
        theta_d = theta * (1 + k1 * theta**2 + k2 * theta**4 + k3 * theta**6 + k4 * theta**8)
        scale = np.where(r > 0, theta_d / np.where(r > 0, r, 1.0), 1.0)
        xd, yd = x * scale, y * scale
    else:
        k = np.zeros(8)
        k[: D.size] = D
        k1, k2, p1, p2, k3, k4, k5, k6 = k
        r2 = x**2 + y**2
        radial = (1 + k1 * r2 + k2 * r2**2 + k3 * r2**3) / (1 + k4 * r2 + k5 * r2**2 + k6 * r2**3)
        xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x**2)
        yd = y * radial + p1 * (r2 + 2 * y**2) + 2 * p2 * x * y
    return np.c_[K[0, 0] * xd + K[0, 1] * yd + K[0, 2], K[1, 1] * yd + K[1, 2]]


def test_from_camera_info_reads_fields():
    cam = CameraIntrinsics.from_camera_info(camera_info())
    assert (cam.width, cam.height, cam.model) == (1280, 1024, "plumb_bob")
    np.testing.assert_array_equal(cam.K, np.reshape(K_LIST, (3, 3)))
    np.testing.assert_array_equal(cam.D, PLUMB_BOB)
    assert cam.has_distortion
    assert cam.focal_px == pytest.approx(np.sqrt(1000.0 * 1010.0))


def test_empty_d_means_no_distortion_for_every_model():
    for model in DISTORTION_MODELS:
        cam = CameraIntrinsics.from_camera_info(camera_info(d=[], distortion_model=model))
        assert cam.D.size == 0 and not cam.has_distortion


def test_empty_model_with_empty_d_is_plumb_bob():
    cam = CameraIntrinsics.from_camera_info(camera_info(d=[], distortion_model=""))
    assert cam.model == "plumb_bob" and not cam.has_distortion


@pytest.mark.parametrize(
    "overrides, field",
    [
        (dict(width=0), "width"),
        (dict(height=0), "height"),
        (dict(k=[0.0, 0, 639.5, 0, 1000, 511.5, 0, 0, 1]), "focal"),
        (dict(k=[1000.0, 0, 639.5, 0, -1000, 511.5, 0, 0, 1]), "focal"),
        (dict(k=[np.nan, 0, 639.5, 0, 1000, 511.5, 0, 0, 1]), "finite"),
        (dict(k=[1000.0, 0, 639.5, 0, 1000, 511.5, 0, 0]), "k must have 9"),
        (dict(k=[1000.0, 0, 639.5, 0, 1000, 511.5, 0, 1, 1]), "last row"),
        (dict(distortion_model="fisheye_cubic"), "model"),
        (dict(d=PLUMB_BOB[:4]), "D must have 5"),
        (dict(d=PLUMB_BOB, distortion_model="rational_polynomial"), "D must have 8"),
        (dict(d=PLUMB_BOB, distortion_model="equidistant"), "D must have 4"),
        (dict(d=[np.inf, 0, 0, 0, 0]), "D must be finite"),
    ],
)
def test_validation_names_the_field(overrides, field):
    with pytest.raises(ValueError, match=field):
        CameraIntrinsics.from_camera_info(camera_info(**overrides))


def test_focal_length_error_prints_plain_numbers():
    # numpy 2 reprs a scalar as np.float64(0.0); the message must read the same on numpy 1 and 2
    with pytest.raises(ValueError) as info:
        CameraIntrinsics.from_camera_info(camera_info(k=[0.0, 0, 639.5, 0, -5, 511.5, 0, 0, 1]))
    assert "fx=0.0, fy=-5.0" in str(info.value) and "np." not in str(info.value)


def test_arrays_are_read_only_and_equality_compares_values():
    cam = CameraIntrinsics.from_camera_info(camera_info())
    with pytest.raises(ValueError):
        cam.K[0, 0] = 1.0
    assert cam == CameraIntrinsics.from_camera_info(camera_info())
    assert cam != cam.with_distortion([], "plumb_bob")
    # An empty D and explicit zeros describe the same camera.
    assert cam.with_distortion([], "plumb_bob") == cam.with_distortion(np.zeros(5), "plumb_bob")


@pytest.mark.parametrize(
    "model, D",
    [
        ("plumb_bob", []),
        ("plumb_bob", PLUMB_BOB),
        ("rational_polynomial", RATIONAL),
        ("equidistant", EQUIDISTANT),
    ],
)
def test_projection_matches_textbook_formulas(model, D):
    rng = np.random.default_rng(0)
    cam = CameraIntrinsics.from_camera_info(camera_info(d=D, distortion_model=model))
    P = random_points(rng)
    expected = textbook_projection(cam.K, D if len(D) else np.zeros(5), model, P)
    # 1e-9 px: both are the same closed-form expression evaluated in double precision.
    np.testing.assert_allclose(cam.project_points(P), expected, atol=1e-9)


@pytest.mark.parametrize(
    "model, D",
    [
        ("plumb_bob", []),
        ("plumb_bob", PLUMB_BOB),
        ("rational_polynomial", RATIONAL),
        ("equidistant", EQUIDISTANT),
    ],
)
def test_undistort_inverts_projection(model, D):
    rng = np.random.default_rng(1)
    cam = CameraIntrinsics.from_camera_info(camera_info(d=D, distortion_model=model))
    P = random_points(rng)
    pixels = cam.project_points(P)
    # 1e-9: the iterative undistortion runs to eps 1e-12 in normalized units (50 iterations).
    np.testing.assert_allclose(cam.normalize_points(pixels), P[:, :2] / P[:, 2:], atol=1e-9)
    ideal = cam.K[:2, :2] @ (P[:, :2] / P[:, 2:]).T + cam.K[:2, 2:3]
    # 1e-6 px: the 1e-9 normalized tolerance times a focal length of about 1000 px.
    np.testing.assert_allclose(cam.undistort_points(pixels), ideal.T, atol=1e-6)


def test_project_points_with_object_pose():
    cam = CameraIntrinsics.pinhole(640, 480, 500.0)
    T = np.eye(4)
    T[:3, 3] = [0.1, -0.2, 2.0]
    uv = cam.project_points(np.zeros((1, 3)), T)
    # 1e-9 px: exact pinhole arithmetic.
    np.testing.assert_allclose(uv, [[319.5 + 25.0, 239.5 - 50.0]], atol=1e-9)
    with pytest.raises(ValueError, match="points"):
        cam.project_points(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="T_cam_obj"):
        cam.project_points(np.zeros((1, 3)), np.eye(3))
    with pytest.raises(ValueError, match="pixels"):
        cam.normalize_points(np.zeros(4))

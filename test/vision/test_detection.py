"""TagDetector on rendered images: pose accuracy, frame convention, gates, distortion, errors."""

import numpy as np
import pytest

from rwhec_ros.core.lie import invert_transform, rotation_distance
from rwhec_ros.vision.detection import (
    DetectorConfig,
    RejectReason,
    TagDetector,
    pose_precision,
    tag_object_points,
)
from rwhec_ros.vision.families import APRILTAG_FAMILIES
from rwhec_ros.vision.intrinsics import CameraIntrinsics
from rwhec_ros.vision.render import RenderedTag, look_at, render_tags

CAM = CameraIntrinsics.pinhole(1280, 1024, 1000.0)
SIZE = 0.16


def viewed_from(obliquity_deg, azimuth_deg=0.0, distance=1.0, offset=(0.0, 0.0)):
    """T_cam_tag for a camera at ``distance`` from the tag centre, off its normal by the angle,
    aimed at a point ``offset`` (metres, tag plane) away from the centre."""
    th, ph = np.deg2rad(obliquity_deg), np.deg2rad(azimuth_deg)
    pos = distance * np.array([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
    return invert_transform(look_at(pos, [offset[0], offset[1], 0.0], up=[0.0, 1.0, 0.0]))


def pose_errors(T_est, T_true):
    """(translation error in mm, rotation error in degrees)."""
    return (
        1000.0 * np.linalg.norm(T_est[:3, 3] - T_true[:3, 3]),
        np.degrees(rotation_distance(T_est[:3, :3], T_true[:3, :3])),
    )


def render(cam, poses, sizes=None, ids=None, seed=0, **kwargs):
    sizes = sizes or [SIZE] * len(poses)
    ids = ids or list(range(len(poses)))
    tags = [RenderedTag(i, T, s) for i, T, s in zip(ids, poses, sizes, strict=True)]
    kwargs.setdefault("noise_std", 1.0)
    kwargs.setdefault("blur_sigma", 0.5)
    return render_tags(cam, tags, rng=np.random.default_rng(seed), **kwargs)


def test_pose_accuracy_at_one_metre():
    """16 cm tag at 1 m, 1280x1024, f = 1000 px, noise 1 grey level, blur 0.5 px, 8 views with
    obliquity 0-45 degrees. Measured with the defaults (edge refinement + LM): translation
    error at most 0.11 mm, rotation error at most 0.09 degrees (the face-on view; see also
    benchmarks/perception.md)."""
    detector = TagDetector(DetectorConfig(default_tag_size=SIZE))
    rng = np.random.default_rng(42)
    worst_t = worst_r = 0.0
    for k in range(8):
        T = viewed_from(45.0 * k / 7, rng.uniform(0, 360), offset=rng.normal(0, 0.05, 2))
        result = detector.detect(render(CAM, [T], seed=k), CAM)
        assert [o.tag_id for o in result.observations] == [0] and result.rejections == []
        e_t, e_r = pose_errors(result.observations[0].T_cam_tag, T)
        worst_t, worst_r = max(worst_t, e_t), max(worst_r, e_r)
    # The task's acceptance figures: 2 mm and 0.2 degrees.
    assert worst_t < 2.0 and worst_r < 0.2


def test_frame_convention_and_corner_order():
    """Upright face-on tag: R_cam_tag = diag(1, -1, -1) (z toward the camera), corners TL TR BR
    BL."""
    T = np.diag([1.0, -1.0, -1.0, 1.0])
    T[:3, 3] = [0.05, -0.03, 1.2]
    detector = TagDetector(DetectorConfig(tag_sizes={0: SIZE}))
    obs = detector.detect(render(CAM, [T]), CAM).observations[0]
    # 0.5 degree: face-on rotation is the least constrained direction; far below a flip (180).
    assert np.degrees(rotation_distance(obs.T_cam_tag[:3, :3], T[:3, :3])) < 0.5
    assert obs.T_cam_tag[2, 2] < -0.99  # tag z axis points back at the camera
    u, v = obs.corners[:, 0], obs.corners[:, 1]
    assert u[0] < u[1] and v[0] < v[3] and u[3] < u[2] and v[1] < v[2]
    truth = CAM.project_points(tag_object_points(SIZE), T)
    # 0.05 px: the renderer resolves axis-aligned edges to 1/16 px (measured max 0.03 px).
    np.testing.assert_allclose(obs.corners, truth, atol=0.05)
    assert obs.obliquity_deg < 5.0 and obs.side_px == pytest.approx(SIZE * 1000 / 1.2, rel=0.01)


def test_edge_refinement_beats_opencv_refinements_on_corners():
    """The reason for the default: corner RMS on the same image (measured: edge 0.009 px,
    subpix 0.16 px, none 0.83 px)."""
    T = viewed_from(30.0, 20.0, offset=(0.02, -0.01))
    img = render(CAM, [T])
    truth = CAM.project_points(tag_object_points(SIZE), T)
    rms = {}
    for mode in ("edge", "subpix", "none"):
        det = TagDetector(DetectorConfig(default_tag_size=SIZE, corner_refinement=mode))
        corners = det.detect(img, CAM).observations[0].corners
        rms[mode] = float(np.sqrt(np.mean(np.sum((corners - truth) ** 2, axis=1))))
    assert rms["edge"] < 0.05 and rms["edge"] < rms["subpix"] / 3 and rms["edge"] < rms["none"] / 3


def test_nothing_to_detect_gives_empty_lists():
    detector = TagDetector(DetectorConfig(default_tag_size=SIZE))
    rng = np.random.default_rng(3)
    texture = np.kron(rng.integers(0, 256, (32, 40)), np.ones((32, 32)))  # blocky clutter
    for img in (render(CAM, [], image=128.0), render(CAM, [], image=texture, blur_sigma=2.0)):
        result = detector.detect(img, CAM)
        assert result.observations == [] and result.rejections == []


def test_oblique_tag_is_rejected_with_reason():
    detector = TagDetector(DetectorConfig(default_tag_size=SIZE))
    result = detector.detect(render(CAM, [viewed_from(80.0)]), CAM)
    assert result.observations == []
    assert [(r.tag_id, r.reason) for r in result.rejections] == [(0, RejectReason.TOO_OBLIQUE)]
    assert "80.0 deg" in result.rejections[0].detail
    relaxed = TagDetector(DetectorConfig(default_tag_size=SIZE, max_obliquity_deg=85.0))
    obs = relaxed.detect(render(CAM, [viewed_from(80.0)]), CAM).observations
    # 0.5 degree: obliquity comes from the estimated pose.
    assert len(obs) == 1 and obs[0].obliquity_deg == pytest.approx(80.0, abs=0.5)


def test_tiny_tag_is_rejected_with_reason():
    # Full-resolution search: a decimated one does not see an 18 px tag at all
    # (test_candidates.py).
    detector = TagDetector(DetectorConfig(default_tag_size=SIZE, decimate=1))
    T = np.diag([1.0, -1.0, -1.0, 1.0])
    T[:3, 3] = [0.0, 0.0, 9.0]  # 160 mm at 9 m: about 18 px
    result = detector.detect(render(CAM, [T]), CAM)
    assert result.observations == []
    assert [(r.tag_id, r.reason) for r in result.rejections] == [(0, "too_small")]


def test_unconfigured_id_and_per_id_sizes():
    base = viewed_from(20.0, 0.0)
    poses = []
    for shift in (0.0, 0.3, -0.3):  # three tags side by side in the same plane
        T = base.copy()
        T[:3, 3] += base[:3, :3] @ [shift, 0.0, 0.0]
        poses.append(T)
    img = render(CAM, poses, sizes=[0.16, 0.08, 0.16], ids=[4, 9, 11])
    detector = TagDetector(DetectorConfig(tag_sizes={4: 0.16, 9: 0.08}))
    result = detector.detect(img, CAM)
    assert [o.tag_id for o in result.observations] == [4, 9]
    assert [(r.tag_id, r.reason) for r in result.rejections] == [(11, "not_in_configuration")]
    for obs, T in zip(result.observations, poses, strict=False):
        e_t, e_r = pose_errors(obs.T_cam_tag, T)
        # 2 mm / 0.2 degree: the task's figures (the 8 cm tag is the harder one).
        assert e_t < 2.0 and e_r < 0.2
    # A wrong size scales the translation by the same factor: the unknown-scale model (eq. (21)).
    scaled = TagDetector(DetectorConfig(tag_sizes={4: 0.32}, unknown_scale=True))
    obs = scaled.detect(img, CAM).by_id()[4]
    # 1 um: same corners; IPPE and LM are scale-equivariant up to their termination tolerances.
    np.testing.assert_allclose(
        obs.T_cam_tag[:3, 3], 2.0 * result.by_id()[4].T_cam_tag[:3, 3], atol=1e-6
    )


def test_only_ids_examines_those_tags_exactly_as_a_full_detect():
    base = viewed_from(20.0, 0.0)
    poses = []
    for shift in (0.0, 0.3, -0.3):
        T = base.copy()
        T[:3, 3] += base[:3, :3] @ [shift, 0.0, 0.0]
        poses.append(T)
    img = render(CAM, poses, ids=[4, 9, 11])
    detector = TagDetector(DetectorConfig(tag_sizes={4: SIZE, 9: SIZE}))
    full = detector.detect(img, CAM)
    part = detector.detect(img, CAM, only_ids=[9, 30])
    assert [o.tag_id for o in part.observations] == [9]
    assert part.skipped == [4]  # configured, found, not asked for
    # an unconfigured id is still rejected by name (cheap, and counted by the session)
    assert [(r.tag_id, r.reason) for r in part.rejections] == [(11, "not_in_configuration")]
    assert full.skipped == []
    # The same numbers as the full detection: each tag is refined and solved on its own.
    np.testing.assert_array_equal(part.by_id()[9].T_cam_tag, full.by_id()[9].T_cam_tag)
    np.testing.assert_array_equal(part.by_id()[9].corners, full.by_id()[9].corners)
    assert detector.detect(img, CAM, only_ids=()).observations == []


def test_duplicate_ids_are_rejected():
    poses = [viewed_from(0.0, offset=(0.25, 0.0)), viewed_from(0.0, offset=(-0.25, 0.0))]
    result = TagDetector(DetectorConfig(default_tag_size=SIZE)).detect(
        render(CAM, poses, ids=[5, 5]), CAM
    )
    assert result.observations == []
    assert [(r.tag_id, r.reason) for r in result.rejections] == [(5, "duplicate_id")] * 2


@pytest.mark.parametrize(
    "model, D",
    [
        ("plumb_bob", [-0.28, 0.09, 0.0008, -0.0005, -0.015]),
        ("rational_polynomial", [0.6, -0.2, 0.001, -0.001, 0.05, 0.9, -0.1, 0.08]),
        ("equidistant", [0.08, -0.02, 0.004, -0.001]),
    ],
)
def test_distortion_round_trip(model, D):
    """Render with distortion, detect, pose within 2 mm / 0.2 deg; the tag sits 0.3-0.4 m off
    axis where these models move pixels by several pixels (measured: <= 0.05 mm, 0.01 deg)."""
    cam = CAM.with_distortion(D, model)
    T = viewed_from(30.0, 200.0)
    T[:3, 3] += [0.35, 0.3, 0.0]
    shift = cam.project_points(tag_object_points(SIZE), T) - CAM.project_points(
        tag_object_points(SIZE), T
    )
    assert np.max(np.linalg.norm(shift, axis=1)) > 3
    result = TagDetector(DetectorConfig(default_tag_size=SIZE)).detect(render(cam, [T]), cam)
    assert len(result.observations) == 1
    e_t, e_r = pose_errors(result.observations[0].T_cam_tag, T)
    assert e_t < 2.0 and e_r < 0.2


@pytest.mark.parametrize("family", [*sorted(APRILTAG_FAMILIES), "DICT_6X6_250", "DICT_4X4_50"])
def test_every_family_detects(family):
    # single ArUco markers too (printed with OpenCV; a real eye-to-hand set uses DICT_6X6_250):
    # the frame is the one the renderer draws, OpenCV's, as for AprilTags
    cam = CameraIntrinsics.pinhole(640, 480, 500.0)
    T = viewed_from(25.0, 60.0, distance=0.8)
    img = render(cam, [T], ids=[3], family=family)
    result = TagDetector(DetectorConfig(family=family, default_tag_size=SIZE)).detect(img, cam)
    assert [o.tag_id for o in result.observations] == [3]
    e_t, e_r = pose_errors(result.observations[0].T_cam_tag, T)
    assert e_t < 2.0 and e_r < 0.2  # same figures as at 1280x1024 (closer tag, shorter focal)


def test_precision_fields_follow_the_documented_model():
    detector = TagDetector(DetectorConfig(default_tag_size=SIZE, pixel_noise_floor_px=0.05))
    T = viewed_from(30.0, distance=2.0)
    obs = detector.detect(render(CAM, [T]), CAM).observations[0]
    sigma, kappa = pose_precision(
        obs.reprojection_rms_px,
        np.linalg.norm(obs.T_cam_tag[:3, 3]),
        CAM.focal_px,
        SIZE,
        pixel_noise_floor_px=0.05,
    )
    assert (obs.sigma, obs.kappa) == (sigma, kappa)
    # Textbook values: 0.05 px floor, 2 m, f = 1000 px, 16 cm: sigma = 4 * 0.05 / 160 m.
    assert pose_precision(0.0, 2.0, 1000.0, 0.16, pixel_noise_floor_px=0.05) == pytest.approx(
        (1.25e-3, 1.0 / (2.0 * (2 * 4 * 0.05 / (1000.0 * 0.16**2)) ** 2))
    )
    # Floors bind for close, clean tags; larger residuals mean lower precision.
    assert pose_precision(0.0, 0.3, 1000.0, 0.16) == pytest.approx(
        (1e-3, 1.0 / (2.0 * np.deg2rad(0.05) ** 2))
    )
    lo = pose_precision(0.1, 2.0, 1000.0, 0.16)
    hi = pose_precision(1.0, 2.0, 1000.0, 0.16)
    assert hi[0] > lo[0] and hi[1] < lo[1]
    off = TagDetector(DetectorConfig(default_tag_size=SIZE, estimate_precision=False))
    obs = off.detect(render(CAM, [T]), CAM).observations[0]
    assert obs.sigma is None and obs.kappa is None


def test_never_raises_on_valid_images():
    detector = TagDetector(DetectorConfig(default_tag_size=SIZE))
    rng = np.random.default_rng(9)
    small = CameraIntrinsics.pinhole(8, 6, 10.0)
    cases = [
        (np.zeros((1024, 1280), np.uint8), CAM),
        (np.full((1024, 1280), 255, np.uint8), CAM),
        (rng.integers(0, 256, (1024, 1280)).astype(np.uint8), CAM),
        (rng.integers(0, 256, (6, 8)).astype(np.uint8), small),
    ]
    for img, cam in cases:
        result = detector.detect(img, cam)
        assert result.observations == []
    # A tag cut by the image border is either accepted with a good pose or rejected, never raises.
    T = np.diag([1.0, -1.0, -1.0, 1.0])
    T[:3, 3] = [0.62, 0.0, 1.0]
    for obs in detector.detect(render(CAM, [T]), CAM).observations:
        assert pose_errors(obs.T_cam_tag, T)[0] < 2.0


def test_bad_input_raises_value_error():
    detector = TagDetector(DetectorConfig(default_tag_size=SIZE))
    with pytest.raises(ValueError, match="gray"):
        detector.detect(np.zeros((1024, 1280), np.float32), CAM)
    with pytest.raises(ValueError, match="gray"):
        detector.detect(np.zeros((1024, 1280, 3), np.uint8), CAM)
    with pytest.raises(ValueError, match="does not match"):
        detector.detect(np.zeros((480, 640), np.uint8), CAM)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(family="tag99h1"), "family"),
        (dict(family="DICT_9X9_1"), "family"),
        (dict(tag_sizes={1: -0.1}), r"tag_sizes\[1\]"),
        (dict(tag_sizes={-1: 0.1}), "tag_sizes key"),
        (dict(default_tag_size=0.0), "default_tag_size"),
        (dict(corner_refinement="magic"), "corner_refinement"),
        (dict(max_obliquity_deg=95.0), "max_obliquity_deg"),
        (dict(max_reprojection_rms_px=-1.0), "max_reprojection_rms_px"),
        (dict(min_side_px=-1.0), "min_side_px"),
        (dict(detector_parameters={"noSuchParameter": 1}), "noSuchParameter"),
        (dict(decimate=0), "decimate"),
        (dict(decimate="half"), "decimate"),
    ],
)
def test_config_validation(kwargs, field):
    with pytest.raises(ValueError, match=field):
        DetectorConfig(**kwargs)


def test_config_accepts_short_family_names_and_aruco_overrides():
    cfg = DetectorConfig(family="36h11", detector_parameters={"adaptiveThreshWinSizeStep": 20})
    assert cfg.family == "tag36h11"
    assert cfg.aruco_parameters().adaptiveThreshWinSizeStep == 20

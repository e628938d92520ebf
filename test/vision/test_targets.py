"""Targets: specs and their validation, mixed detection of tags and boards, occlusion, precision."""

import cv2
import numpy as np
import pytest

from rwhec_ros.core.lie import invert_transform, make_transform, rotation_distance
from rwhec_ros.vision.board_detection import estimate_board, points_precision
from rwhec_ros.vision.boards import AprilGridSpec, CharucoSpec
from rwhec_ros.vision.detection import DetectorConfig, RejectReason, pose_precision
from rwhec_ros.vision.intrinsics import CameraIntrinsics
from rwhec_ros.vision.render import RenderedBoard, RenderedTag, look_at, render_tags
from rwhec_ros.vision.target_detector import TargetDetector
from rwhec_ros.vision.targets import TargetSpec, validate_targets

CAM = CameraIntrinsics.pinhole(1024, 768, 900.0)
GRID = AprilGridSpec(4, 5, tag_size=0.06, tag_spacing=0.3, first_id=100)  # Kalibr-printed
CHARUCO = CharucoSpec(7, 5, square_size=0.05, marker_size=0.037, dictionary="DICT_5X5_100")


def errors(T_est, T_true):
    return (1000 * float(np.linalg.norm(T_est[:3, 3] - T_true[:3, 3])),
            float(np.degrees(rotation_distance(T_est[:3, :3], T_true[:3, :3]))))


def scene(rng):
    """Camera 1.6 m from a wall holding a grid, a ChArUco board and a single tag."""
    T_cam_world = invert_transform(look_at([0.25, -0.2, 1.6], [0.0, 0.0, 0.0], up=[0, 1, 0]))
    tilt = cv2.Rodrigues(np.array([0.0, 0.35, 0.0]))[0]
    truth = {
        "grid": T_cam_world @ make_transform(np.eye(3), [-0.33, 0.0, 0.0]),
        "charuco": T_cam_world @ make_transform(tilt, [0.3, 0.0, 0.0]),
        "tag_7": T_cam_world @ make_transform(np.eye(3), [0.0, 0.33, 0.0]),
    }
    items = [RenderedBoard(GRID, truth["grid"]), RenderedBoard(CHARUCO, truth["charuco"]),
             RenderedTag(7, truth["tag_7"], 0.1), RenderedTag(50, truth["tag_7"] @ make_transform(
                 np.eye(3), [0.0, -0.66, 0.0]), 0.1)]
    img = render_tags(CAM, items, noise_std=2.0, blur_sigma=0.6, rng=rng)
    return img, truth


TARGETS = [TargetSpec("grid", board=GRID), TargetSpec("charuco", board=CHARUCO),
           TargetSpec("tag_7", tag_id=7, tag_size=0.1)]


# OpenCV 4.11 (the newest 4.x that accepts numpy 1.26, as on a ROS 2 Jazzy machine; .ci/run's
# second line) detects boards measurably worse than 4.12+ on these two images: the ChArUco pose
# of the mixed image is 1.23 mm off (limit 1 mm) and the Kalibr grid with corner squares gives 8
# of 20 tags (limit 15; 16 with OpenCV 4.14). Recorded here (strict: a fix makes them fail).
OPENCV_BEFORE_4_12 = tuple(int(x) for x in cv2.__version__.split(".")[:2]) < (4, 12)
_OLD_OPENCV = pytest.mark.xfail(OPENCV_BEFORE_4_12, strict=True,
                                reason="board detection with OpenCV < 4.12 (see above)")


@_OLD_OPENCV
def test_mixed_tags_and_boards_in_one_image():
    img, truth = scene(np.random.default_rng(0))
    det = TargetDetector(TARGETS, DetectorConfig())
    res = det.detect(img, CAM)
    obs = res.by_name()
    assert set(obs) == {"grid", "charuco", "tag_7"}
    assert [r.reason for r in res.rejections] == [RejectReason.NOT_IN_CONFIGURATION.value]
    assert res.rejections[0].marker_id == 50
    assert obs["grid"].kind == "aprilgrid" and obs["grid"].n_corners >= 4 * 18
    assert obs["charuco"].kind == "charuco" and obs["charuco"].n_corners >= 20
    for name, o in obs.items():
        dt, dr = errors(o.T_cam_target, truth[name])
        R = o.T_cam_target[:3, :3]
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)  # a rotation
        if name == "tag_7":
            # One 10 cm tag (~55 px) at 1.7 m: measured 0.7 mm, 0.12 deg (perception.md).
            assert dt < 3.0 and dr < 0.5, (name, dt, dr)
        else:
            # Boards: tens of corners over ~0.35 m: measured 0.17 / 0.42 mm, 0.004 / 0.04 deg.
            assert dt < 1.0 and dr < 0.1, (name, dt, dr)
        assert o.pose_status == "unique" and o.flip_ratio > 3.0
        assert o.sigma is not None and o.kappa is not None and o.reprojection_rms_px < 0.3


def test_partly_occluded_board_still_gives_a_pose():
    T = invert_transform(look_at([0.05, 0.0, 1.0], [0.0, 0.0, 0.0], up=[0, 1, 0]))
    rng = np.random.default_rng(1)
    full = render_tags(CAM, [RenderedBoard(GRID, T)], noise_std=2.0, blur_sigma=0.6, rng=rng)
    img = full.copy()
    img[:, : CAM.width // 2 + 20] = 128  # cover the left half and a bit more
    det = TargetDetector([TargetSpec("grid", board=GRID)], DetectorConfig())
    o_full = det.detect(full, CAM).by_name()["grid"]
    o_half = det.detect(img, CAM).by_name()["grid"]
    assert o_full.n_corners == GRID.n_corners and 8 <= o_half.n_corners < GRID.n_corners / 2
    dt, dr = errors(o_half.T_cam_target, T)
    assert dt < 1.0 and dr < 0.1  # fewer corners, still sub-millimetre (measured ~0.1 mm)
    # The covariance model (without its floors) sees that the origin now lies outside the
    # corners seen, and that fewer corners were seen.
    def unfloored(o):
        return points_precision(o.object_points, o.T_cam_target, CAM, o.reprojection_rms_px,
                                sigma_floor_m=1e-12, rotation_std_floor_deg=1e-9)
    (s_full, k_full), (s_half, k_half) = unfloored(o_full), unfloored(o_half)
    assert s_half > 1.5 * s_full and k_half < k_full
    # Only one grid tag left: 4 corners < min_corners 8 -> rejected with the reason ...
    one = full.copy()
    keep = o_full.image_points[:4]
    x0, y0 = np.floor(keep.min(axis=0)).astype(int) - 12
    x1, y1 = np.ceil(keep.max(axis=0)).astype(int) + 12
    one[:] = 128
    one[y0:y1, x0:x1] = full[y0:y1, x0:x1]
    res = det.detect(one, CAM)
    assert not res.observations
    assert [r.reason for r in res.rejections] == [RejectReason.TOO_FEW_CORNERS.value]
    # ... and accepted with min_corners = 4.
    det4 = TargetDetector([TargetSpec("grid", board=GRID, min_corners=4)], DetectorConfig())
    assert det4.detect(one, CAM).by_name()["grid"].n_corners == 4


def test_duplicate_board_markers_are_dropped():
    T_cam_world = invert_transform(look_at([0.0, 0.0, 1.3], [0.0, 0.0, 0.0], up=[0, 1, 0]))
    T1 = T_cam_world @ make_transform(np.eye(3), [0.2, 0.0, 0.0])
    T2 = T_cam_world @ make_transform(np.eye(3), [-0.2, 0.0, 0.0])
    img = render_tags(CAM, [RenderedBoard(CHARUCO, T1), RenderedBoard(CHARUCO, T2)],
                      blur_sigma=0.6)
    res = TargetDetector([TargetSpec("charuco", board=CHARUCO)]).detect(img, CAM)
    assert not res.observations
    reasons = [r.reason for r in res.rejections]
    assert reasons.count(RejectReason.DUPLICATE_ID.value) == len(CHARUCO.marker_ids)
    assert reasons[-1] == RejectReason.TOO_FEW_CORNERS.value


def test_a_misplaced_grid_tag_is_dropped_as_outlier():
    """Given marker corners (no image refinement): one tag 3 px off (a wrong quad) is left out
    and the pose comes from the others."""
    grid = AprilGridSpec(3, 3, 0.05, 0.3, corner_squares=False)
    T = invert_transform(look_at([0.1, 0.05, 0.8], [0.0, 0.0, 0.0], up=[0, 1, 0]))
    rng = np.random.default_rng(3)
    markers = [(i, CAM.project_points(grid.marker_object_points(i), T)
                + rng.normal(0.0, 0.05, (4, 2))) for i in grid.marker_ids]
    markers[4] = (markers[4][0], markers[4][1] + [3.0, -2.0])
    config = DetectorConfig(corner_refinement="subpix")  # corners used as given
    gray = np.zeros((CAM.height, CAM.width), np.uint8)
    obs, rejections = estimate_board(gray, TargetSpec("g", board=grid), markers, CAM, config)
    assert rejections == [] and obs.outlier_corners == 4 and 4 not in obs.marker_ids
    dt, dr = errors(obs.T_cam_target, T)
    # 32 corners, 0.05 px noise: within 4 standard deviations of the covariance model.
    sigma, kappa = points_precision(obs.object_points, T, CAM, obs.reprojection_rms_px,
                                    sigma_floor_m=1e-12, rotation_std_floor_deg=1e-9)
    assert dt < 4000 * sigma and np.deg2rad(dr) < 4 / np.sqrt(2 * kappa), (dt, dr)
    assert obs.reprojection_rms_px < 0.1


@_OLD_OPENCV
def test_kalibr_corner_squares_need_the_extra_threshold_passes():
    """6 cm Kalibr tags at 2.2 m (~25 px): with aruco's default threshold alone the corner
    squares hide almost every tag; the extra passes recover most of them."""
    T = invert_transform(look_at([0.25, -0.2, 2.2], [0.0, 0.0, 0.0], up=[0, 1, 0]))
    img = render_tags(CAM, [RenderedBoard(GRID, T)], noise_std=2.0, blur_sigma=0.6,
                      rng=np.random.default_rng(0))
    spec = [TargetSpec("grid", board=GRID, min_corners=4)]
    single = TargetDetector(spec, grid_threshold_constants=(7.0,)).detect(img, CAM)
    multi = TargetDetector(spec).detect(img, CAM)
    n_single = sum(o.n_corners for o in single.observations) // 4
    n_multi = multi.by_name()["grid"].n_corners // 4
    assert n_single <= 5 and n_multi >= 15  # measured: 0 and 16 of 20 tags
    dt, dr = errors(multi.by_name()["grid"].T_cam_target, T)
    assert dt < 4.0 and dr < 0.3  # measured 1.3 mm, 0.10 deg (0.33 m board at 2.2 m)
    with pytest.raises(ValueError, match="grid_threshold_constants"):
        TargetDetector(spec, grid_threshold_constants=())


def test_points_precision_matches_monte_carlo_scatter():
    """Covariance model vs the scatter of PnP poses from noisy projected corners (no images)."""
    rng = np.random.default_rng(2)
    obj = np.concatenate([GRID.marker_object_points(i) for i in GRID.marker_ids])
    T = invert_transform(look_at([0.4, 0.2, 2.0], [0.0, 0.0, 0.0], up=[0, 1, 0]))
    clean = CAM.project_points(obj, T)
    noise_px = 0.5
    t_err, r_err = [], []
    for _ in range(300):
        noisy = clean + rng.normal(0.0, noise_px, clean.shape)
        ok, rvec, tvec = cv2.solvePnP(obj, noisy, np.array(CAM.K), None,
                                      flags=cv2.SOLVEPNP_ITERATIVE)
        R = cv2.Rodrigues(rvec)[0]
        t_err.append(tvec.ravel() - T[:3, 3])
        dR = R @ T[:3, :3].T
        r_err.append(cv2.Rodrigues(dR)[0].ravel())
    cov_t = np.cov(np.array(t_err).T)
    cov_r = np.cov(np.array(r_err).T)
    # The expected RMS of the 2D residuals for this noise: E[N rms^2] = (2N - 6) noise^2.
    n = len(obj)
    rms = noise_px * np.sqrt((2 * n - 6) / n)
    sigma, kappa = points_precision(obj, T, CAM, rms, pixel_noise_floor_px=1e-9,
                                    sigma_floor_m=1e-12, rotation_std_floor_deg=1e-9)
    sigma_rot = 1.0 / np.sqrt(2.0 * kappa)
    # 300 samples: the standard deviation estimates are within ~10% (chi-square); allow 20%.
    assert sigma == pytest.approx(np.sqrt(np.linalg.eigvalsh(cov_t)[-1]), rel=0.2)
    assert sigma_rot == pytest.approx(np.sqrt(np.linalg.eigvalsh(cov_r)[-1]), rel=0.2)
    # One tag: the same order as the single-tag model of detection.py (face-on, first order).
    tag = GRID.marker_object_points(100) - GRID.tag_centre(100)
    T_tag = make_transform(np.diag([1.0, -1.0, -1.0]), [0.0, 0.0, 1.5])
    s4, k4 = points_precision(tag, T_tag, CAM, 0.05, sigma_floor_m=1e-12,
                              rotation_std_floor_deg=1e-9)
    s1, k1 = pose_precision(0.05, 1.5, CAM.focal_px, GRID.tag_size, sigma_floor_m=1e-12,
                            rotation_std_floor_deg=1e-9)
    assert 0.5 < s4 / s1 < 2.0 and 0.25 < k4 / k1 < 4.0  # first-order model: factor-2 agreement


def test_target_spec_validation():
    with pytest.raises(ValueError, match="name"):
        TargetSpec("", tag_id=1, tag_size=0.1)
    with pytest.raises(ValueError, match="tag_id and tag_size"):
        TargetSpec("t", tag_id=1)
    with pytest.raises(ValueError, match="tag_id"):
        TargetSpec("t", tag_id=-1, tag_size=0.1)
    with pytest.raises(ValueError, match="tag_size"):
        TargetSpec("t", tag_id=1, tag_size=0.0)
    with pytest.raises(ValueError, match="no tag_id"):
        TargetSpec("b", tag_id=1, tag_size=0.1, board=GRID)
    with pytest.raises(ValueError, match="min_corners"):
        TargetSpec("b", board=GRID, min_corners=3)
    with pytest.raises(ValueError, match="min_corners 100 exceeds the 80"):
        TargetSpec("b", board=GRID, min_corners=100)
    assert TargetSpec("b", board=CHARUCO).kind == "charuco"


def test_validate_targets_rejects_overlapping_ids():
    grid = TargetSpec("grid", board=GRID)  # tag36h11 ids 100..119
    with pytest.raises(ValueError, match=r"'grid' and 'tag_103' both use marker id 103 of tag3"):
        validate_targets([grid, TargetSpec("tag_103", tag_id=103, tag_size=0.1)], "tag36h11")
    # Another family for the single tags: no clash.
    validate_targets([grid, TargetSpec("tag_3", tag_id=3, tag_size=0.1)], "tag25h9")
    # ChArUco (DICT_5X5_100 ids 0..16) beside tag36h11 tags with the same ids: fine.
    validate_targets([TargetSpec("c", board=CHARUCO), TargetSpec("t", tag_id=3, tag_size=0.1)],
                     "tag36h11")
    other = TargetSpec("c2", board=CharucoSpec(4, 4, 0.05, 0.04, "DICT_5X5_100", first_id=16))
    with pytest.raises(ValueError, match="marker id 16 of DICT_5X5_100"):
        validate_targets([TargetSpec("c", board=CHARUCO), other], "tag36h11")
    with pytest.raises(ValueError, match="duplicate target name 'grid'"):
        validate_targets([grid, TargetSpec("grid", tag_id=99, tag_size=0.1)], "tag36h11")
    with pytest.raises(ValueError, match="tag_id 40 is not in tag16h5"):
        validate_targets([TargetSpec("t", tag_id=40, tag_size=0.1)], "tag16h5")
    with pytest.raises(ValueError, match="both use"):
        TargetDetector([grid, TargetSpec("tag_103", tag_id=103, tag_size=0.1)])


def test_detect_validates_the_image():
    det = TargetDetector(TARGETS)
    with pytest.raises(ValueError, match="gray"):
        det.detect(np.zeros((10, 10), dtype=np.float32), CAM)
    with pytest.raises(ValueError, match="does not match"):
        det.detect(np.zeros((10, 10), dtype=np.uint8), CAM)
    assert det.detect(np.full((CAM.height, CAM.width), 128, np.uint8), CAM).observations == []


def test_only_examines_the_named_targets_and_reports_where_markers_are():
    img, truth = scene(np.random.default_rng(0))
    det = TargetDetector(TARGETS, DetectorConfig())
    full = det.detect(img, CAM)
    part = det.detect(img, CAM, only=["charuco"])
    assert sorted(part.skipped) == ["grid", "tag_7"]  # found, left unexamined
    assert [o.name for o in part.observations] == ["charuco"]
    # the target examined gets exactly the pose of a full detection
    np.testing.assert_array_equal(part.by_name()["charuco"].T_cam_target,
                                  full.by_name()["charuco"].T_cam_target)
    # markers found, per target, also those of no target (tag 50)
    assert {m for m, _ in full.markers["tag_7"]} == {7}
    assert {m for m, _ in full.markers[""]} == {50}
    assert len(full.markers["grid"]) >= 15 and set(full.markers) == {"grid", "charuco",
                                                                       "tag_7", ""}

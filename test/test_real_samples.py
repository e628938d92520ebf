"""The real third-party stop-and-go sets through ``samples`` (skipped without ``shared/data/real``).

* ``ic_charuco`` (industrial_calibration, eye-to-hand, ChArUco, today's detectors): read as it
  is, solved; the same pairs and estimate as the equivalent bag (1e-9); held-out residuals no
  worse than OpenCV's best robot-world/hand-eye method on the same pairs and folds.
* ``cct_chessboard_eye_in_hand`` (camera_calibration_toolkit): read as it is; without intrinsics
  the error says how to give them; with them a ``chessboard`` target, every view kept.
* ``ic_circle_10x10``: read as it is; a ``circles`` target with the larger origin circle, every
  view kept.

Every set keeps the views an independent OpenCV detector with its defaults accepts
(``benchmarks/real_data.md``: 15, 15, 6).
"""

from __future__ import annotations

import io
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from rwhec_ros.cli import EXIT_BAD_INPUT, EXIT_OK, EXIT_UNUSABLE, main
from rwhec_ros.core.lie import rotation_distance
from rwhec_ros.core.problem import Edge, Problem
from rwhec_ros.core.solve import solve
from rwhec_ros.data.dataset import Dataset
from rwhec_ros.data.sample_layouts import read_samples

REPO = Path(__file__).resolve().parents[1]
#: The developers' shared folder beside the repository (or beside the folder holding it, for a
#: checkout one level deeper).
SHARED = next((p for p in (REPO.parent / "shared", REPO.parent.parent / "shared") if p.is_dir()),
              REPO.parent / "shared")
REAL = SHARED / "data" / "real"
NS = 1_000_000_000


def real(name: str) -> Path:
    path = REAL / name
    if not path.is_dir():
        pytest.skip(f"no {path} (the developers' real data sets)")
    return path


def run(argv) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    code = main([str(a) for a in argv], stdout=out, stderr=err)
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def ic_charuco(tmp_path_factory):
    """``samples`` on ic_charuco: (exit code, stdout, output directory)."""
    folder = real("ic_charuco")
    out = tmp_path_factory.mktemp("ic_charuco") / "out"
    code, stdout, stderr = run(["samples", folder, "-o", out, "-q"])
    return code, stdout + stderr, out


def test_ic_charuco_is_read_and_solved(ic_charuco):
    code, text, out = ic_charuco
    # a result either way; the verdict is the data's (the set's README: a 3 % scale error of the
    # board or the focal length, no distortion given), printed first
    assert code in (EXIT_OK, EXIT_UNUSABLE), text
    doc = yaml.safe_load((out / "result.yaml").read_text())
    assert doc["certified"] is True
    assert doc["config"]["camera_carrier.frame"] == "base"  # static_camera: eye-to-hand
    data = Dataset.load(out / "dataset.yaml")
    (edge,) = data.edges
    # 16 images: 2.png shows 4 corners (< min_corners 8); 6.png and 7.png fit 1.03 px RMS, above
    # the 1 px floor but within 4x the camera's median corner noise (the gate scaled to it keeps
    # them; a fixed 1 px gate gave 13 pairs): 15, every view cv2.aruco.CharucoDetector accepts
    assert (edge.x, edge.y, len(edge.A)) == ("board", "cam0", 15)
    assert "images_targets_rejected:too_few_corners=1, images_used=15," in text, text
    cam = next(f for f in doc["frames"] if f["name"] == "cam0")
    # the README's OpenCV SHAH estimate of T_base_cam: (-0.0267, 1.2628, 0.2842) m; ours on the
    # same images agrees to the spread of the OpenCV methods there (~15 mm)
    assert np.linalg.norm(np.asarray(cam["translation"]) - [-0.0267, 1.2628, 0.2842]) < 0.02


def _held_out(A, B, fit, partitions, folds=5) -> tuple[float, float]:
    """Held-out |A X - Y B|, translation [m] and rotation [rad]: the RMS over the held-out pairs
    of ``folds`` folds (``perm[k::folds]``), averaged over the partitions ``perm``."""
    n = len(A)
    out = []
    for perm in partitions:
        t_err, r_err = [], []
        for k in range(folds):
            test = perm[k::folds]
            X, Y = fit(np.setdiff1d(np.arange(n), test))
            for i in test:
                L, R = A[i] @ X, Y @ B[i]
                t_err.append(np.linalg.norm(L[:3, 3] - R[:3, 3]))
                r_err.append(rotation_distance(L[:3, :3], R[:3, :3]))
        out.append((np.sqrt(np.mean(np.square(t_err))), np.sqrt(np.mean(np.square(r_err)))))
    return tuple(float(v) for v in np.mean(out, axis=0))


def test_ic_charuco_held_out_no_worse_than_opencv(ic_charuco):
    """The issue's bar: no worse than OpenCV's best method on held-out residuals (same pairs,
    same folds). cv2.calibrateRobotWorldHandEye solves T_cam_world T_world_base = T_cam_gripper
    T_gripper_base, i.e. A X = Y B with its (world2cam, base2gripper) = (A, B).

    With 15 pairs (3 per fold) one partition decides little: on the partition i::5 alone SHAH is
    0.4 % lower in translation (9.71 vs 9.75 mm), and on 13 pairs ours was lower in rotation on
    only 9 of 20 random partitions; so the residuals are averaged over 20 partitions (i::5 and 19
    seeded permutations), the same for every method."""
    _, _, out = ic_charuco
    (edge,) = Dataset.load(out / "dataset.yaml").edges
    A, B = np.asarray(edge.A), np.asarray(edge.B)
    rng = np.random.default_rng(0)
    partitions = [np.arange(len(A))] + [rng.permutation(len(A)) for _ in range(19)]

    def ours(idx):
        r = solve(Problem(["board"], ["cam0"], [Edge.build("board", "cam0", A[idx], B[idx],
                                                           edge.sigma[idx], edge.kappa[idx])]))
        return r.X[0], r.Y[0]

    def opencv(method):
        def fit(idx):
            R1, t1, R2, t2 = cv2.calibrateRobotWorldHandEye(
                [a[:3, :3] for a in A[idx]], [a[:3, 3] for a in A[idx]],
                [b[:3, :3] for b in B[idx]], [b[:3, 3] for b in B[idx]], method=method)
            X, Y = np.eye(4), np.eye(4)
            X[:3, :3], X[:3, 3], Y[:3, :3], Y[:3, 3] = R1, t1.ravel(), R2, t2.ravel()
            return X, Y
        return fit

    mine = _held_out(A, B, ours, partitions)
    theirs = [_held_out(A, B, opencv(m), partitions) for m in (
        cv2.CALIB_ROBOT_WORLD_HAND_EYE_SHAH, cv2.CALIB_ROBOT_WORLD_HAND_EYE_LI)]
    # measured (15 pairs): ours 9.87 mm / 1.428 deg, SHAH 10.12 mm / 1.458 deg, LI 23.98 mm /
    # 1.444 deg
    assert mine[0] <= min(t for t, _ in theirs), (mine, theirs)
    assert mine[1] <= min(r for _, r in theirs), (mine, theirs)


@pytest.mark.slow
def test_ic_charuco_equals_the_equivalent_bag(ic_charuco, tmp_path):
    """The same views as a rosbag2 recording (the PNG files as CompressedImage, the robot pose
    on /tf 0.3 s before and after each image: the stop-and-go rule pairs them) through ``bag``:
    the same pairs and estimate to 1e-9."""
    from rwhec_ros.cli.samples import samples_parameters
    from rwhec_ros.config import CalibratorConfig
    from rwhec_ros.data.rosbag import (
        CAMERA_INFO,
        COMPRESSED_IMAGE,
        TF_MESSAGE,
        message_from_fields,
        write_bag,
    )
    from rwhec_ros.messages import (
        intrinsics_to_camera_info_fields,
        ns_to_stamp_fields,
        transform_to_transform_stamped_fields,
    )

    _, _, out = ic_charuco
    folder = real("ic_charuco")
    samples = read_samples(folder)
    flat, invert, _ = samples_parameters(samples)
    assert not invert
    flat.update({"cameras.cam0.image_transport": "compressed", "pose_source.type": "tf",
                 "sync.detection_threads": 1})
    config = tmp_path / "config.yaml"
    config.write_text(CalibratorConfig.from_parameters(flat).to_yaml())
    intr = samples.intrinsics["cam0"].intrinsics(1600, 1200)
    msgs = [("/samples/cam0/camera_info", CAMERA_INFO, NS // 2, message_from_fields(
        CAMERA_INFO, intrinsics_to_camera_info_fields(intr, NS // 2, "cam0")))]
    for view, stamp in zip(samples.views, samples.stamps_ns(), strict=True):
        for dt in (-3 * NS // 10, 3 * NS // 10):
            fields = transform_to_transform_stamped_fields(view.T_parent_child, "base", "tool",
                                                           stamp + dt)
            msgs.append(("/tf", TF_MESSAGE, stamp + dt,
                         message_from_fields(TF_MESSAGE, {"transforms": [fields]})))
        msgs.sort(key=lambda m: m[2])
        msgs.append(("/samples/cam0/image/compressed", COMPRESSED_IMAGE, stamp,
                     message_from_fields(COMPRESSED_IMAGE, {
                         "header": {"stamp": ns_to_stamp_fields(stamp), "frame_id": "cam0"},
                         "format": "png", "data": view.images["cam0"].read_bytes()})))
    msgs.sort(key=lambda m: m[2])
    bag = write_bag(tmp_path / "bag", msgs)
    code, stdout, stderr = run(["bag", bag, "--config", config, "-o", tmp_path / "b", "-q"])
    assert code in (EXIT_OK, EXIT_UNUSABLE), stdout + stderr
    (eb,) = Dataset.load(tmp_path / "b" / "dataset.yaml").edges
    (es,) = Dataset.load(out / "dataset.yaml").edges
    assert np.array_equal(eb.stamps_ns, es.stamps_ns)
    np.testing.assert_allclose(eb.A, es.A, atol=1e-9)
    np.testing.assert_allclose(eb.B, es.B, atol=1e-9)
    fb = {f["name"]: np.asarray(f["matrix"])
          for f in yaml.safe_load((tmp_path / "b" / "result.yaml").read_text())["frames"]}
    fs = {f["name"]: np.asarray(f["matrix"])
          for f in yaml.safe_load((out / "result.yaml").read_text())["frames"]}
    for name in fs:
        np.testing.assert_allclose(fb[name], fs[name], atol=1e-9)


CCT_INTRINSICS = """image_width: 960
image_height: 540
camera_matrix: {rows: 3, cols: 3, data: [641.33, 0, 472.80, 0, 640.82, 290.47, 0, 0, 1]}
distortion_model: plumb_bob
distortion_coefficients: {rows: 1, cols: 5, data: [-0.3717, 0.1412, 0.0001, 0.0012, -0.021]}
"""


def test_cct_is_read_and_asks_for_intrinsics(tmp_path):
    folder = real("cct_chessboard_eye_in_hand")
    s = read_samples(folder)
    assert (s.layout, len(s.views), s.intrinsics) == ("camera_calibration_toolkit", 6,
                                                      {"cam0": None})
    assert [v.images["cam0"].name for v in s.views] == [f"{n}.jpg" for n in (0, 4, 8, 12, 16, 20)]
    code, out, err = run(["samples", folder, "--eye-in-hand", "-o", tmp_path / "o"])
    assert code == EXIT_BAD_INPUT
    assert "no intrinsics for camera cam0 (its layout ships no intrinsics): give them with " \
           "--intrinsics FILE" in err, err
    (tmp_path / "cct.yaml").write_text(CCT_INTRINSICS)  # the set's README's refitted values
    code, out, err = run(["samples", folder, "--eye-in-hand", "--intrinsics",
                          tmp_path / "cct.yaml", "-o", tmp_path / "o", "-q"])
    assert code in (EXIT_OK, EXIT_UNUSABLE), out + err
    (edge,) = Dataset.load(tmp_path / "o" / "dataset.yaml").edges
    assert len(edge.A) == 6
    cam = next(f for f in yaml.safe_load((tmp_path / "o" / "result.yaml").read_text())["frames"]
               if f["name"] == "cam0")
    # the README's OpenCV SHAH T_end_cam: (0.0921, -0.0074, 0.1357) m, PARK/TSAI 4 mm away
    assert np.linalg.norm(np.asarray(cam["translation"]) - [0.0921, -0.0074, 0.1357]) < 0.01


def test_ic_circle_grid_is_read(tmp_path):
    folder = real("ic_circle_10x10")
    s = read_samples(folder)
    assert (s.layout, len(s.views), s.mount) == ("industrial_calibration", 15, "eye_in_hand")
    assert s.target_words.startswith("modified circle grid 10 x 10 dots, 0.0254 m spacing")
    assert s.target_parameters["targets.board.origin_circle"] is True
    code, out, err = run(["samples", folder, "-o", tmp_path / "o", "-q"])
    # the verdict is the data's: their nominal intrinsics are ~3 % off (the set's README)
    assert code in (EXIT_OK, EXIT_UNUSABLE), out + err
    assert yaml.safe_load((tmp_path / "o" / "result.yaml").read_text())["certified"] is True
    (edge,) = Dataset.load(tmp_path / "o" / "dataset.yaml").edges
    assert (edge.x, edge.y, len(edge.A)) == ("board", "cam0", 15)


def test_ic_charuco_is_not_unusable_because_of_a_guessed_noise(ic_charuco):
    """Issue 34: the PnP's own precision (1 mm) is 3-4x below what these arm data fit (the
    robot's own error); with the noise estimated per camera the verdict no longer calls the
    result unusable for the fit, and the summary shows the estimate next to the given value."""
    code, text, out = ic_charuco
    assert code == EXIT_OK, text
    assert not text.startswith("UNUSABLE"), text
    doc = yaml.safe_load((out / "result.yaml").read_text())
    assert doc["certificate"]["weights"] == "estimated"
    cam = doc["noise"]["groups"]["cam0"]
    assert doc["noise"]["given"] == "reprojection"
    assert cam["translation"]["source"] == "estimated"
    # the residuals fit a few mm where the corners alone predict about 1 mm
    assert 2.0 < cam["sigma_m"] / cam["sigma_given_m"] < 8.0
    assert "cam0: sigma" in text and "from the reprojection" in text


def test_planted_turns_of_real_views_are_told_by_the_pose_stream(ic_charuco, tmp_path):
    """A board that looked the same turned by 180 deg would give each real view one of two
    labellings: the real views of ic_charuco (eye-to-hand) and ic_circle_10x10 (eye-in-hand),
    a random 40 % of them turned (``B F``), 20 draws each: the pose stream tells every turned
    view (``rwhec_ros.sync.board_turns``, the relative turns of real arm motion and real PnP
    poses)."""
    from rwhec_ros.sync.board_turns import TURN, resolve_turns

    _, _, out = ic_charuco
    code, text, err = run(["samples", real("ic_circle_10x10"), "-o", tmp_path / "o", "-q"])
    assert code in (EXIT_OK, EXIT_UNUSABLE), text + err
    for path in (out / "dataset.yaml", tmp_path / "o" / "dataset.yaml"):
        (edge,) = Dataset.load(path).edges
        rng = np.random.default_rng(0)
        for _ in range(20):
            planted = rng.random(edge.n) < 0.4
            B = np.array(edge.B)
            B[planted] = B[planted] @ TURN
            res = resolve_turns(edge.A, B)
            assert res.resolved.all(), path
            assert np.array_equal(res.turned, planted) or np.array_equal(res.turned, ~planted)

"""Reading what users have: intrinsics files, written poses, the manifest, other tools' folders."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from rwhec_ros.core.lie import make_transform, so3_exp, transform_to_quat_xyzw
from rwhec_ros.data.intrinsics_files import read_intrinsics_file
from rwhec_ros.data.pose_fields import pose_from_columns, pose_from_fields
from rwhec_ros.data.sample_layouts import read_samples
from rwhec_ros.data.samples import read_manifest, write_manifest

K = np.array([[601.5, 0.0, 318.2], [0.0, 603.25, 242.7], [0.0, 0.0, 1.0]])
D5 = np.array([-0.21, 0.07, 0.0011, -0.0007, -0.012])

# --- intrinsics ---------------------------------------------------------------------------------


def test_ros_camera_calibration_yaml(tmp_path):
    # the file camera_calibration's cameracalibrator writes (ost.yaml), numbers changed
    path = tmp_path / "ost.yaml"
    path.write_text(f"""image_width: 640
image_height: 480
camera_name: narrow_stereo
camera_matrix:
  rows: 3
  cols: 3
  data: {K.reshape(-1).tolist()}
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: {D5.tolist()}
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
projection_matrix:
  rows: 3
  cols: 4
  data: [600, 0, 318, 0, 0, 600, 242, 0, 0, 0, 1, 0]
""")
    f = read_intrinsics_file(path)
    intr = f.intrinsics()
    assert (f.format, intr.width, intr.height, intr.model) == ("ros_yaml", 640, 480, "plumb_bob")
    np.testing.assert_array_equal(intr.K, K)
    np.testing.assert_array_equal(intr.D, D5)


@pytest.mark.parametrize("ext", ["yaml", "xml"])
def test_opencv_file_storage(tmp_path, ext):
    path = tmp_path / f"calib.{ext}"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("cameraMatrix", K)
    fs.write("distCoeffs", D5[:4].reshape(1, 4))  # k1 k2 p1 p2: read as plumb_bob, k3 = 0
    fs.write("image_width", 640)
    fs.write("image_height", 480)
    fs.release()
    f = read_intrinsics_file(path)
    assert f.format == f"opencv_{ext}"
    intr = f.intrinsics()
    np.testing.assert_array_equal(intr.K, K)
    np.testing.assert_array_equal(intr.D, np.append(D5[:4], 0.0))
    assert intr.model == "plumb_bob"


def test_opencv_file_storage_without_size_takes_the_images(tmp_path):
    path = tmp_path / "calib.yaml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", np.zeros((8, 1)))
    fs.release()
    f = read_intrinsics_file(path)
    assert f.width is None and f.model == "rational_polynomial"
    assert (f.intrinsics(1280, 960).width, f.intrinsics(1280, 960).height) == (1280, 960)
    with pytest.raises(ValueError, match="no image size"):
        f.intrinsics()


def test_intrinsics_errors_name_the_file_and_the_keys(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("fx: 500\nfy: 500\n")
    with pytest.raises(ValueError, match=r"c\.yaml: no camera matrix .*camera_matrix.*has \['fx'"):
        read_intrinsics_file(path)
    path.write_text("camera_matrix: [1, 2, 3]\n")
    with pytest.raises(ValueError, match="expected 9 numbers"):
        read_intrinsics_file(path)
    path.write_text(f"camera_matrix: {K.tolist()}\ndistortion_coefficients: [1, 2, 3]\n")
    with pytest.raises(ValueError, match="3 distortion coefficients"):
        read_intrinsics_file(path)
    path.write_text(f"camera_matrix: {K.tolist()}\ndistortion_model: equidistant\n"
                    "distortion_coefficients: [0.1, 0.01, 0, 0]\nimage_width: 640\n"
                    "image_height: 480\n")
    assert read_intrinsics_file(path).intrinsics().model == "equidistant"
    with pytest.raises(ValueError, match="images are 320x240"):
        read_intrinsics_file(path).intrinsics(320, 240)
    with pytest.raises(ValueError, match="no such file"):
        read_intrinsics_file(tmp_path / "nope.yaml")


# --- poses --------------------------------------------------------------------------------------

T = make_transform(so3_exp(np.array([0.3, -1.1, 2.0])), [0.4, -0.2, 0.9])


def test_the_pose_forms_agree():
    q, t = transform_to_quat_xyzw(T)
    rvec = cv2.Rodrigues(T[:3, :3])[0].reshape(-1)  # OpenCV's own rotation vector
    forms = [{"translation": t.tolist(), "quaternion": q.tolist()},
             {"translation": t.tolist(), "rvec": rvec.tolist()},
             {"translation": t.tolist(), "rotation": T[:3, :3].tolist()},
             {"matrix": T.tolist()}]
    for fields in forms:
        np.testing.assert_allclose(pose_from_fields(fields, "p"), T, atol=1e-12)
    row = {f"g_t{a}": str(v) for a, v in zip("xyz", t, strict=True)}
    row.update({f"g_q{a}": str(v) for a, v in zip("xyzw", q, strict=True)})
    np.testing.assert_allclose(pose_from_columns(row, "g", "row 1"), T, atol=1e-12)


def test_bad_poses_are_refused_by_name():
    with pytest.raises(ValueError, match=r"v\.quaternion: quaternion norm 2"):
        pose_from_fields({"translation": [0, 0, 0], "quaternion": [0, 0, 0, 2]}, "v")
    with pytest.raises(ValueError, match=r"v\.rotation: not a rigid transform"):
        pose_from_fields({"translation": [0, 0, 0], "rotation": (2 * np.eye(3)).tolist()}, "v")
    with pytest.raises(ValueError, match="expected one of"):
        pose_from_fields({"translation": [0, 0, 0]}, "v")
    with pytest.raises(ValueError, match="together with"):
        pose_from_fields({"matrix": np.eye(4).tolist(), "translation": [0, 0, 0]}, "v")
    with pytest.raises(ValueError, match=r"v\.translation: expected shape \(3,\)"):
        pose_from_fields({"translation": [0, 0], "rvec": [0, 0, 0]}, "v")


# --- the manifest -------------------------------------------------------------------------------


def _manifest(tmp_path: Path, **changes) -> Path:
    q, t = transform_to_quat_xyzw(T)
    doc = {"samples": 1, "pose": {"parent": "base", "child": "tool0"}, "mount": "eye_in_hand",
           "views": [{"image": "a.png", "translation": t.tolist(), "quaternion": q.tolist()},
                     {"image": "b.png", "matrix": T.tolist(), "stamp": 3.5}]}
    doc.update(changes)
    path = tmp_path / "samples.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_manifest_round_trip(tmp_path):
    s = read_manifest(_manifest(tmp_path))
    assert (s.pose_parent, s.pose_child, s.mount, s.cameras) == ("base", "tool0",
                                                                  "eye_in_hand", ("cam0",))
    assert [v.images["cam0"].name for v in s.views] == ["a.png", "b.png"]
    assert s.intrinsics == {"cam0": None}
    again = read_manifest(write_manifest(s, tmp_path / "copy.yaml"))
    for a, b in zip(s.views, again.views, strict=True):
        np.testing.assert_allclose(a.T_parent_child, b.T_parent_child, atol=1e-12)
        assert a.images == b.images and a.stamp_ns == b.stamp_ns
    with pytest.raises(ValueError, match="has no stamp while others have one"):
        s.stamps_ns()


@pytest.mark.parametrize(("changes", "match"), [
    ({"mount": "on_the_table"}, "mount: expected one of"),
    ({"pose": {"parent": "base"}}, r"pose: expected \{parent: FRAME, child: FRAME\}"),
    ({"camera_carrier": "world"}, "camera_carrier: 'world' is neither"),
    ({"views": []}, "views: expected a non-empty list"),
    ({"cams": {}}, r"unknown keys \['cams'\]"),
    ({"views": [{"image": "a.png", "images": {"cam0": "a.png"}, "matrix": T.tolist()}]},
     r"views\[0\]: give 'image'"),
    ({"cameras": {"cam0": {}, "cam1": {}}},
     r"views\[0\]: 'image' with 2 cameras"),
])
def test_manifest_errors(tmp_path, changes, match):
    with pytest.raises(ValueError, match=match):
        read_manifest(_manifest(tmp_path, **changes))


# --- other tools' layouts, written here in their format -----------------------------------------


def test_industrial_calibration_layout(tmp_path):
    q, t = transform_to_quat_xyzw(T)
    (tmp_path / "poses").mkdir()
    for i in range(2):
        (tmp_path / "poses" / f"{i}.yaml").write_text(yaml.safe_dump(
            {"qw": float(q[3]), "x": float(t[0]), "y": float(t[1]), "z": float(t[2]),
             "qx": float(q[0]), "qy": float(q[1]), "qz": float(q[2])}))  # keys in any order
    (tmp_path / "cal_data.yaml").write_text(yaml.safe_dump({
        "data": [{"pose": f"poses/{i}.yaml", "image": f"images/{i}.png"} for i in range(2)],
        "target_finder": {"type": "CharucoGridTargetFinder", "rows": 7, "cols": 5,
                          "chessboard_dim": 0.036195, "aruco_marker_dim": 0.018256,
                          "dictionary": 10},
        "intrinsics": {"fx": 1352.0, "fy": 1356.1, "cx": 789.7, "cy": 627.3},
        "static_camera": True}))
    s = read_samples(tmp_path)
    assert (s.layout, s.mount, s.pose_parent, s.pose_child, s.frames_named) == (
        "industrial_calibration", "eye_to_hand", "base", "tool", False)
    np.testing.assert_allclose(s.views[1].T_parent_child, T, atol=1e-12)
    assert s.target_parameters["targets.board.dictionary"] == "DICT_6X6_250"
    assert (s.target_parameters["targets.board.squares_x"],
            s.target_parameters["targets.board.squares_y"]) == (5, 7)
    intr = s.intrinsics["cam0"].intrinsics(1600, 1200)
    assert intr.K[0, 0] == 1352.0 and intr.D.size == 0
    assert "without distortion" in s.notes[0]


def test_industrial_calibration_circle_grid_becomes_a_circles_target(tmp_path):
    """ModifiedCircleGridTargetFinder: rows x cols dots, spacing between centres, the origin dot
    larger: the configuration's circles target with circle_spacing and origin_circle."""
    from rwhec_ros.cli.samples import samples_parameters
    from rwhec_ros.config import CalibratorConfig
    from rwhec_ros.vision.grids import CircleGridSpec

    (tmp_path / "poses").mkdir()
    (tmp_path / "poses" / "0.yaml").write_text("x: 0.1\ny: 0.2\nz: 0.3\nqx: 0\nqy: 0\nqz: 0\n"
                                               "qw: 1\n")
    finder = {"type": "ModifiedCircleGridTargetFinder", "rows": 5, "cols": 7, "spacing": 0.03}
    cal = {"data": [{"image": "images/0.png", "pose": "poses/0.yaml"}],
           "intrinsics": {"fx": 550.0, "fy": 551.0, "cx": 320.0, "cy": 240.0},
           "target_finder": finder, "static_camera": False}
    (tmp_path / "cal_data.yaml").write_text(yaml.safe_dump(cal))
    s = read_samples(tmp_path)
    assert s.mount == "eye_in_hand"
    p = "targets.board."
    assert {k: v for k, v in s.target_parameters.items() if k.startswith(p)} == {
        p + "type": "circles", p + "rows": 5, p + "cols": 7, p + "circle_spacing": 0.03,
        p + "origin_circle": True}
    flat, _, _ = samples_parameters(s)  # what `samples` configures
    (spec,) = CalibratorConfig.from_parameters(flat).target_specs()
    assert spec.board == CircleGridSpec(7, 5, 0.03, origin_circle=True)
    del finder["spacing"]
    (tmp_path / "cal_data.yaml").write_text(yaml.safe_dump(cal))
    with pytest.raises(ValueError, match="cal_data.yaml: target_finder of type "
                                         "ModifiedCircleGridTargetFinder: 'spacing'"):
        read_samples(tmp_path)


def test_calibration_toolkit_layout(tmp_path):
    for n in (0, 4):
        (tmp_path / f"{n}.json").write_text(json.dumps({"end2base": T.tolist()}))
        cv2.imwrite(str(tmp_path / f"{n}.jpg"), np.zeros((8, 8), np.uint8))
    (tmp_path / "chessboard_config.json").write_text(json.dumps(
        {"pattern_id": "standard_chessboard", "parameters": {"width": 11, "height": 8,
                                                              "square_size": 0.02}}))
    s = read_samples(tmp_path)
    assert (s.layout, s.mount, s.intrinsics) == ("camera_calibration_toolkit", None,
                                                  {"cam0": None})
    assert [v.images["cam0"].name for v in s.views] == ["0.jpg", "4.jpg"]
    assert s.target_words == "chessboard 11 x 8 inner corners, 0.02 m squares"
    with pytest.raises(ValueError, match="no such file"):
        read_samples(tmp_path / "missing")
    with pytest.raises(ValueError, match="not a folder of views"):
        read_samples(tmp_path, "industrial_calibration")

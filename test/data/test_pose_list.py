"""Pose lists (OpenCV gripper2base + target2cam): the convention, CSV = YAML, poses = csv."""

from __future__ import annotations

import io
import re

import cv2
import numpy as np
import pytest
import yaml

from rwhec_ros.cli import EXIT_BAD_INPUT, EXIT_OK, main
from rwhec_ros.core.lie import invert_transform, make_transform, so3_exp, transform_to_quat_xyzw
from rwhec_ros.core.problem import Edge, Problem
from rwhec_ros.data.paper_csv import write_paper_csv
from rwhec_ros.data.pose_list import pose_list_problem, read_pose_list

T_GRIPPER_CAM = make_transform(so3_exp(np.array([0.2, -0.1, 1.4])), [0.05, -0.03, 0.11])
T_BASE_TARGET = make_transform(so3_exp(np.array([0.0, 0.1, 0.5])), [0.7, 0.2, 0.02])


def gripper_poses(rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """``T_base_gripper`` spread over +-0.6 rad and +-0.15 m around a pose above the target."""
    home = make_transform(so3_exp(np.array([np.pi, 0.0, 0.0])), [0.65, 0.2, 0.55])
    return [home @ make_transform(so3_exp(rng.uniform(-0.6, 0.6, 3)), rng.uniform(-0.15, 0.15, 3))
            for _ in range(n)]


def eye_in_hand_rows(rng, n=12, noise=0.0):
    """(gripper2base, target2cam) pairs of the eye-in-hand rig, target2cam with ``noise`` [m]
    and ``noise`` [rad] per axis."""
    rows = []
    for G in gripper_poses(rng, n):
        T_cam_target = invert_transform(T_GRIPPER_CAM) @ invert_transform(G) @ T_BASE_TARGET
        if noise:
            T_cam_target = T_cam_target @ make_transform(so3_exp(rng.normal(0, noise, 3)),
                                                         rng.normal(0, noise, 3))
        rows.append((G, T_cam_target))
    return rows


def write_csv(path, rows, camera="cam0", target="target"):
    head = ["camera", "target"] + [f"gripper2base_{c}" for c in
                                   ("tx", "ty", "tz", "qx", "qy", "qz", "qw")] + \
        [f"target2cam_{c}" for c in ("tx", "ty", "tz", "rvec_x", "rvec_y", "rvec_z")]
    lines = ["# a pose list", ",".join(head)]
    for G, B in rows:
        q, t = transform_to_quat_xyzw(G)
        rvec = cv2.Rodrigues(B[:3, :3])[0].ravel()
        vals = [*t, *q, *B[:3, 3], *rvec]
        lines.append(",".join([camera, target] + [repr(float(v)) for v in vals]))
    path.write_text("\n".join(lines) + "\n")
    return path


def write_yaml(path, rows, mount="eye_in_hand", camera="cam0", target="target"):
    pairs = [{"camera": camera, "target": target, "gripper2base": {"matrix": G.tolist()},
              "target2cam": {"translation": B[:3, 3].tolist(), "rotation": B[:3, :3].tolist()}}
             for G, B in rows]
    path.write_text(yaml.safe_dump({"pose_list": 1, "mount": mount,
                                    "frames": {"base": "base_link", "gripper": "tool0"},
                                    "pairs": pairs}))
    return path


def run(argv):
    out, err = io.StringIO(), io.StringIO()
    code = main([str(a) for a in argv], stdout=out, stderr=err)
    return code, out.getvalue(), err.getvalue()


def frames(path):
    return {f["name"]: np.asarray(f["matrix"])
            for f in yaml.safe_load(path.read_text())["frames"]}


def test_convention_matches_opencv_calibrate_hand_eye(tmp_path):
    """Noise-free eye-in-hand rows: OpenCV's calibrateHandEye(gripper2base, target2cam) returns
    cam2gripper; ours returns Y = T_gripper_cam from the same file. Both must be the truth."""
    rows = eye_in_hand_rows(np.random.default_rng(0))
    R, t = cv2.calibrateHandEye([G[:3, :3] for G, _ in rows], [G[:3, 3] for G, _ in rows],
                                [B[:3, :3] for _, B in rows], [B[:3, 3] for _, B in rows],
                                method=cv2.CALIB_HAND_EYE_PARK)
    np.testing.assert_allclose(make_transform(R, t.ravel()), T_GRIPPER_CAM, atol=1e-6)
    code, out, err = run(["poses", write_csv(tmp_path / "p.csv", rows), "--eye-in-hand",
                          "-o", tmp_path / "o", "-q"])
    assert code == EXIT_OK, out + err
    got = frames(tmp_path / "o" / "result.yaml")
    np.testing.assert_allclose(got["cam0"], T_GRIPPER_CAM, atol=1e-6)   # Y = T_gripper_cam
    np.testing.assert_allclose(got["target"], T_BASE_TARGET, atol=1e-6)  # X = T_base_target
    doc = yaml.safe_load((tmp_path / "o" / "result.yaml").read_text())
    cam = next(f for f in doc["frames"] if f["name"] == "cam0")
    assert (cam["parent"], doc["source"]["mount"]) == ("gripper", "eye_in_hand")


def test_eye_to_hand_reads_the_same_file_the_other_way(tmp_path):
    """Eye-to-hand: the camera fixed at T_base_cam, the target on the gripper at
    T_gripper_target; gripper2base is A as it is."""
    rng = np.random.default_rng(1)
    T_base_cam = make_transform(so3_exp(np.array([2.8, 0.3, -0.2])), [0.6, 0.1, 1.2])
    T_gripper_target = make_transform(so3_exp(np.array([0.1, 0.2, 0.3])), [0.0, 0.02, 0.08])
    rows = [(G, invert_transform(T_base_cam) @ G @ T_gripper_target)
            for G in gripper_poses(rng, 10)]
    path = write_yaml(tmp_path / "p.yaml", rows, mount="eye_to_hand")
    code, out, err = run(["poses", path, "-o", tmp_path / "o", "-q"])
    assert code == EXIT_OK, out + err
    got = frames(tmp_path / "o" / "result.yaml")
    np.testing.assert_allclose(got["cam0"], T_base_cam, atol=1e-6)
    np.testing.assert_allclose(got["target"], T_gripper_target, atol=1e-6)
    doc = yaml.safe_load((tmp_path / "o" / "result.yaml").read_text())
    parents = {f["name"]: f["parent"] for f in doc["frames"]}
    assert parents == {"cam0": "base_link", "target": "tool0"}  # the file's frame names


def test_csv_and_yaml_read_the_same_pairs(tmp_path):
    rows = eye_in_hand_rows(np.random.default_rng(2), noise=0.002)
    a = read_pose_list(write_csv(tmp_path / "p.csv", rows))
    b = read_pose_list(write_yaml(tmp_path / "p.yaml", rows))
    for p, r in zip(a.pairs, b.pairs, strict=True):
        np.testing.assert_allclose(p.T_base_gripper, r.T_base_gripper, atol=1e-12)
        np.testing.assert_allclose(p.T_cam_target, r.T_cam_target, atol=1e-12)
    assert (a.mount, b.mount) == (None, "eye_in_hand")


def test_poses_is_solved_like_csv(tmp_path):
    """The same pairs as a pose list and in the paper's CSV layout give the same estimate."""
    rng = np.random.default_rng(3)
    rows = eye_in_hand_rows(rng, 14, noise=0.003)
    path = write_csv(tmp_path / "p.csv", rows, camera="cam_0", target="tag_0")
    problem = pose_list_problem(read_pose_list(path), "eye_in_hand", sigma=0.005, kappa=400.0)
    A = np.array([invert_transform(G) for G, _ in rows])
    np.testing.assert_allclose(problem.edges[0].A, A, atol=1e-12)
    write_paper_csv(Problem(["tag_0"], ["cam_0"], [Edge.build("tag_0", "cam_0", A, np.array(
        [B for _, B in rows]))]), tmp_path / "paper")
    common = ["--sigma", "0.005", "--kappa", "400", "-q"]
    code, out_p, err = run(["poses", path, "--eye-in-hand", "-o", tmp_path / "p", *common])
    assert code == EXIT_OK, out_p + err
    code, out_c, err = run(["csv", tmp_path / "paper", "--camera-carrier", "gripper",
                            "--tag-carrier", "base", "-o", tmp_path / "c", *common])
    assert code == EXIT_OK, out_c + err
    # the same verdict line but for the suboptimality bound, a number at rounding level (~1e-9)
    # whose last digit follows the BLAS of the machine
    rho = r"rho_hat=[0-9.e+-]+"
    first_p, first_c = out_p.splitlines()[0], out_c.splitlines()[0]
    assert re.sub(rho, "rho_hat=~", first_p) == re.sub(rho, "rho_hat=~", first_c)
    for line in (first_p, first_c):
        assert float(re.search(r"rho_hat=([0-9.e+-]+)\)", line).group(1)) < 1e-6, line
    got_p, got_c = frames(tmp_path / "p" / "result.yaml"), frames(tmp_path / "c" / "result.yaml")
    for name in ("cam_0", "tag_0"):
        # the paper CSV stores 18 digits; the solve is deterministic: equal to rounding
        np.testing.assert_allclose(got_p[name], got_c[name], atol=1e-9)


@pytest.mark.parametrize(("text", "match"), [
    ("camera,gripper2base_tx\ncam0,1\n", r"p\.csv:1: header needs gripper2base_tx"),
    ("gripper2base_tx,gripper2base_ty,gripper2base_tz,gripper2base_qx,gripper2base_qy,"
     "gripper2base_qz,gripper2base_qw,target2cam_tx,target2cam_ty,target2cam_tz,target2cam_qx,"
     "target2cam_qy,target2cam_qz,target2cam_qw\n0,0,0,0,0,0,1,0,0,x,0,0,0,1\n",
     r"p\.csv:2: column target2cam_tz: not a number"),
    ("gripper2base_tx,gripper2base_ty,gripper2base_tz,gripper2base_qx,gripper2base_qy,"
     "gripper2base_qz,gripper2base_qw,target2cam_tx,target2cam_ty,target2cam_tz\n"
     "0,0,0,0,0,0,1,0,0,1\n", r"p\.csv:2: give target2cam_qx"),
])
def test_csv_errors_name_file_line_and_column(tmp_path, text, match):
    (tmp_path / "p.csv").write_text(text)
    with pytest.raises(ValueError, match=match):
        read_pose_list(tmp_path / "p.csv")


def test_mount_is_required_for_a_csv(tmp_path):
    path = write_csv(tmp_path / "p.csv", eye_in_hand_rows(np.random.default_rng(4), 4))
    code, out, err = run(["poses", path, "-o", tmp_path / "o"])
    assert code == EXIT_BAD_INPUT and "--eye-in-hand (cameras on the gripper" in err, err

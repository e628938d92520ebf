"""Synthetic stop-and-go views for the samples, pose-list and capture tests (no ROS).

An arm with its base frame ``base`` and flange ``tool0``; eye-in-hand: camera ``cam0`` on the
flange at ``T_TOOL_CAM``, a ChArUco board and tag 3 fixed on the table (``T_BASE_BOARD``,
``T_BASE_TAG``); eye-to-hand: the same camera fixed in ``base`` at the flange's first pose, the
targets on the flange. Views: camera positions on a cap above the targets, each aimed near them
(seeded), rendered with mild blur and noise and written as PNG files.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from rwhec_ros.core.lie import invert_transform, make_transform, so3_exp
from rwhec_ros.vision.boards import CharucoSpec
from rwhec_ros.vision.intrinsics import CameraIntrinsics
from rwhec_ros.vision.render import RenderedBoard, RenderedTag, look_at, render_tags

INTRINSICS = CameraIntrinsics(640, 480, [[560.0, 0, 322.0], [0, 558.0, 241.0], [0, 0, 1]],
                              [0.02, -0.01, 0.0005, -0.0003, 0.0])
BOARD = CharucoSpec(5, 4, square_size=0.05, marker_size=0.038, dictionary="DICT_4X4_250")
TAG_ID, TAG_SIZE = 3, 0.06
T_TOOL_CAM = make_transform(so3_exp(np.array([0.05, -0.03, 1.2])), [0.04, -0.02, 0.09])
T_BASE_BOARD = make_transform(so3_exp(np.array([0.0, 0.0, 0.3])), [0.6, 0.1, 0.0])
T_BASE_TAG = T_BASE_BOARD @ make_transform(np.eye(3), [0.2, 0.0, 0.0])

#: The configuration's target sections for BOARD and the tag (the manifest's ``targets:`` and
#: ``tags:`` keys, nested).
TARGETS = {"names": ["board"],
           "board": {"type": "charuco", "squares_x": 5, "squares_y": 4, "square_size": 0.05,
                     "marker_size": 0.038, "dictionary": "DICT_4X4_250"}}
TAGS = {"family": "tag36h11", "ids": [TAG_ID], "default_size": TAG_SIZE}


@dataclass
class Views:
    """Rendered views: per view the image file and ``T_base_tool0`` (the robot pose)."""

    files: list[Path]
    T_base_tool: list[np.ndarray]
    T_cam_board: list[np.ndarray]
    mount: str


def camera_poses(rng: np.random.Generator, n: int, centre: np.ndarray) -> list[np.ndarray]:
    """``T_base_cam`` for ``n`` views above ``centre`` (0.45-0.65 m away, tilted up to ~35 deg,
    rolled up to ~40 deg, aim jittered by 3 cm)."""
    out = []
    for i in range(n):
        az = 2 * np.pi * i / n + rng.uniform(-0.3, 0.3)
        tilt = rng.uniform(0.15, 0.6)
        dist = rng.uniform(0.45, 0.65)
        pos = centre + dist * np.array([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az),
                                        np.cos(tilt)])
        aim = centre + rng.uniform(-0.03, 0.03, 3) * [1, 1, 0]
        up = np.array([np.cos(az + rng.uniform(-0.7, 0.7)), np.sin(az + rng.uniform(-0.7, 0.7)),
                       0.0])
        out.append(look_at(pos, aim, up))
    return out


def render_views(directory: Path, rng: np.random.Generator, n: int = 8, *,
                 mount: str = "eye_in_hand", ext: str = ".png") -> Views:
    """Write ``n`` views into ``directory`` (``images/<i><ext>``) and return them."""
    (directory / "images").mkdir(parents=True, exist_ok=True)
    centre = (T_BASE_BOARD[:3, 3] + T_BASE_TAG[:3, 3]) / 2
    files, tools, boards = [], [], []
    for i, T_base_cam in enumerate(camera_poses(rng, n, centre)):
        if mount == "eye_in_hand":
            T_base_tool = T_base_cam @ invert_transform(T_TOOL_CAM)
            T_cam_board = invert_transform(T_base_cam) @ T_BASE_BOARD
            T_cam_tag = invert_transform(T_base_cam) @ T_BASE_TAG
        else:  # the camera fixed where the first view's camera is; targets move with the tool
            # the relative camera-target poses of the eye-in-hand views, realised by the tool
            T_cam_board = invert_transform(T_base_cam) @ T_BASE_BOARD
            T_cam_tag = invert_transform(T_base_cam) @ T_BASE_TAG
            # targets on the tool at T_BASE_BOARD relative to a tool at the identity
            T_base_tool = FIXED_CAM @ T_cam_board @ invert_transform(T_BASE_BOARD)
        img = render_tags(INTRINSICS, [RenderedBoard(BOARD, T_cam_board),
                                       RenderedTag(TAG_ID, T_cam_tag, TAG_SIZE)],
                          blur_sigma=0.6, noise_std=1.5, rng=rng, supersample=2)
        path = directory / "images" / f"{i}{ext}"
        cv2.imwrite(str(path), img)
        files.append(path)
        tools.append(T_base_tool)
        boards.append(T_cam_board)
    return Views(files, tools, boards, mount)


#: Eye-to-hand: ``T_base_cam`` of the fixed camera (the tool carries the targets at
#: ``T_tool_board = T_BASE_BOARD``).
FIXED_CAM = make_transform(so3_exp(np.array([2.9, 0.2, 0.1])), [0.5, 0.2, 1.1])


def manifest(views: Views, *, pose_form: str = "quaternion", stamps=None) -> dict:
    """A samples manifest (a mapping) of ``views``: one camera cam0, the board and the tag."""
    from rwhec_ros.core.lie import transform_to_quat_xyzw

    entries = []
    for i, (f, T) in enumerate(zip(views.files, views.T_base_tool, strict=True)):
        entry = {"image": str(f.relative_to(f.parent.parent))}
        if pose_form == "quaternion":
            q, t = transform_to_quat_xyzw(T)
            entry.update(translation=t.tolist(), quaternion=q.tolist())
        else:
            entry["matrix"] = T.tolist()
        if stamps is not None:
            entry["stamp"] = float(stamps[i])
        entries.append(entry)
    return {"samples": 1, "pose": {"parent": "base", "child": "tool0"}, "mount": views.mount,
            "cameras": {"cam0": {"intrinsics": "cam0.yaml"}}, "targets": TARGETS, "tags": TAGS,
            "views": entries}


def ros_intrinsics_yaml(intr: CameraIntrinsics = INTRINSICS) -> str:
    """``intr`` as a ROS camera_calibration YAML file."""
    K = np.asarray(intr.K).reshape(-1).tolist()
    D = np.asarray(intr.D).reshape(-1).tolist()
    return (f"image_width: {intr.width}\nimage_height: {intr.height}\ncamera_name: cam0\n"
            f"camera_matrix:\n  rows: 3\n  cols: 3\n  data: {K}\n"
            f"distortion_model: {intr.model}\n"
            f"distortion_coefficients:\n  rows: 1\n  cols: {len(D)}\n  data: {D}\n"
            "rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n")

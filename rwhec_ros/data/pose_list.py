"""Pose lists: robot poses and target-in-camera poses, the inputs of OpenCV's ``calibrateHandEye``.

For users who ran their own detection (PnP): one row per image and target, the robot pose
``gripper2base`` and the target pose ``target2cam`` in OpenCV's names. OpenCV's ``X2Y`` is the
transform that maps ``X`` coordinates into ``Y``, ``T_Y_X`` in our notation:

* ``gripper2base`` = ``T_base_gripper`` (``R_gripper2base``, ``t_gripper2base``): the robot's
  forward kinematics, the pose of the flange in the base frame;
* ``target2cam`` = ``T_cam_target`` (``R_target2cam``, ``t_target2cam``, e.g. ``solvePnP``'s
  ``rvec``, ``tvec``) = our ``B``.

In ``A_i X_j = Y_k B_i`` (cameras Y, targets X):

* eye-in-hand: ``A = T_gripper_base`` = inv(gripper2base), ``X = T_base_target``,
  ``Y = T_gripper_cam`` (OpenCV's ``cam2gripper``, what ``calibrateHandEye`` returns);
* eye-to-hand: ``A = T_base_gripper`` = gripper2base, ``X = T_gripper_target``,
  ``Y = T_base_cam`` (OpenCV's ``cam2base``).

(For eye-to-hand OpenCV's ``calibrateHandEye`` is called with ``base2gripper`` in place of
``gripper2base`` and returns ``cam2base``; here the file always holds ``gripper2base`` and the
mount says which.) Translations are in metres, in the units of the target's size for ``B``.

CSV layout (a header row; ``#`` comments; one row per pair; here wrapped, one line in the
file)::

    camera,target,gripper2base_tx,gripper2base_ty,gripper2base_tz,
      gripper2base_qx,gripper2base_qy,gripper2base_qz,gripper2base_qw,
      target2cam_tx,target2cam_ty,target2cam_tz,
      target2cam_rvec_x,target2cam_rvec_y,target2cam_rvec_z
    cam0,board,0.41,-0.12,0.52,0,1,0,0,0.02,-0.01,0.61,3.1,0.02,-0.05

Each pose's rotation is a quaternion ``<pose>_qx, _qy, _qz, _qw`` (scalar last) or a rotation
vector ``<pose>_rvec_x, _y, _z`` [rad]. ``camera`` and ``target`` are optional (default ``cam0``
and ``target``); other columns (e.g. ``view``) are ignored. YAML layout::

    pose_list: 1
    mount: eye_in_hand                      # or eye_to_hand
    frames: {base: base_link, gripper: tool0}   # optional names of the two robot frames
    pairs:
      - camera: cam0                        # optional
        target: board                       # optional
        gripper2base: {translation: [0.41, -0.12, 0.52], quaternion: [0, 1, 0, 0]}
        target2cam: {translation: [0.02, -0.01, 0.61], rvec: [3.1, 0.02, -0.05]}

with the pose forms of :mod:`rwhec_ros.data.pose_fields` (also 3 x 3 ``rotation`` and 4 x 4
``matrix``).
"""

from __future__ import annotations

import csv
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..core.lie import invert_transform
from ..core.problem import Edge, Problem
from .pose_fields import pose_from_columns, pose_from_fields
from .samples import MOUNTS

__all__ = ["PosePair", "PoseList", "read_pose_list", "pose_list_problem", "robot_frames",
           "POSE_LIST_VERSION", "DEFAULT_CAMERA", "DEFAULT_TARGET"]

POSE_LIST_VERSION = 1
DEFAULT_CAMERA = "cam0"
DEFAULT_TARGET = "target"
_DEFAULT_FRAMES = {"base": "base", "gripper": "gripper"}


@dataclass(frozen=True)
class PosePair:
    """One row: ``camera`` saw ``target`` with the robot at ``T_base_gripper``."""

    camera: str
    target: str
    T_base_gripper: np.ndarray
    T_cam_target: np.ndarray
    where: str = ""


@dataclass(frozen=True)
class PoseList:
    """A read pose list: its pairs, the mount and robot frame names when the file gives them."""

    source: str
    pairs: tuple[PosePair, ...]
    mount: str | None = None
    frames: dict[str, str] = field(default_factory=dict)


def _name(value: Any, default: str, where: str) -> str:
    if value is None or (isinstance(value, str) and not value.strip()):
        return default
    text = str(value).strip()
    if any(c.isspace() for c in text):
        raise ValueError(f"{where}: expected a frame name without spaces, got {value!r}")
    return text


def _read_csv(path: Path) -> PoseList:
    with open(path, encoding="utf-8", newline="") as fh:
        lines = [(n, ln) for n, ln in enumerate(fh, start=1)
                 if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise ValueError(f"{path}: empty (expected a header row and one row per pair)")
    reader = csv.DictReader([ln for _, ln in lines], skipinitialspace=True)
    header = [h.strip() for h in (reader.fieldnames or [])]
    reader.fieldnames = header
    for prefix in ("gripper2base", "target2cam"):
        if not all(f"{prefix}_t{a}" in header for a in "xyz"):
            raise ValueError(f"{path}:{lines[0][0]}: header needs {prefix}_tx, {prefix}_ty, "
                             f"{prefix}_tz and {prefix}_qx.._qw or {prefix}_rvec_x.._z; got "
                             f"{header}")
    pairs = []
    for (lineno, _), row in zip(lines[1:], reader, strict=True):
        where = f"{path}:{lineno}"
        if None in row:
            raise ValueError(f"{where}: more fields than the header's {len(header)}")
        pairs.append(PosePair(
            _name(row.get("camera"), DEFAULT_CAMERA, f"{where}: camera"),
            _name(row.get("target"), DEFAULT_TARGET, f"{where}: target"),
            pose_from_columns(row, "gripper2base", where),
            pose_from_columns(row, "target2cam", where), where))
    if not pairs:
        raise ValueError(f"{path}: a header but no rows")
    return PoseList(str(path), tuple(pairs))


def _read_yaml(path: Path) -> PoseList:
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not YAML ({exc})") from None
    if not isinstance(doc, Mapping) or not isinstance(doc.get("pairs"), list):
        raise ValueError(f"{path}: expected a mapping with pairs: [...]")
    unknown = sorted(set(doc) - {"pose_list", "mount", "frames", "pairs"})
    if unknown:
        raise ValueError(f"{path}: unknown keys {unknown} (pose_list, mount, frames, pairs)")
    version = doc.get("pose_list", POSE_LIST_VERSION)
    if version != POSE_LIST_VERSION:
        raise ValueError(f"{path}: pose_list: format version {version!r}, this reader knows "
                         f"{POSE_LIST_VERSION}")
    mount = doc.get("mount")
    if mount is not None and mount not in MOUNTS:
        raise ValueError(f"{path}: mount: expected one of {list(MOUNTS)}, got {mount!r}")
    frames = doc.get("frames") or {}
    if not isinstance(frames, Mapping) or set(frames) - {"base", "gripper"}:
        raise ValueError(f"{path}: frames: expected {{base: FRAME, gripper: FRAME}}, got "
                         f"{frames!r}")
    frames = {k: _name(v, _DEFAULT_FRAMES[k], f"{path}: frames.{k}") for k, v in frames.items()}
    pairs = []
    for i, entry in enumerate(doc["pairs"]):
        where = f"{path}: pairs[{i}]"
        if not isinstance(entry, Mapping):
            raise ValueError(f"{where}: expected a mapping, got {entry!r}")
        bad = sorted(set(entry) - {"camera", "target", "gripper2base", "target2cam", "view"})
        if bad:
            raise ValueError(f"{where}: unknown keys {bad} (camera, target, gripper2base, "
                             "target2cam)")
        for key in ("gripper2base", "target2cam"):
            if key not in entry:
                raise ValueError(f"{where}: {key} is missing")
        pairs.append(PosePair(_name(entry.get("camera"), DEFAULT_CAMERA, f"{where}.camera"),
                              _name(entry.get("target"), DEFAULT_TARGET, f"{where}.target"),
                              pose_from_fields(entry["gripper2base"], f"{where}.gripper2base"),
                              pose_from_fields(entry["target2cam"], f"{where}.target2cam"),
                              where))
    if not pairs:
        raise ValueError(f"{path}: pairs: empty")
    return PoseList(str(path), tuple(pairs), mount, dict(frames))


def read_pose_list(path: str | Path) -> PoseList:
    """Read a pose list (``.csv``, else YAML; module docstring). ``ValueError`` names the file,
    the line or entry and the field."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such file")
    return _read_csv(path) if path.suffix.lower() == ".csv" else _read_yaml(path)


def robot_frames(pose_list: PoseList, mount: str, *, base: str | None = None,
                 gripper: str | None = None) -> tuple[str, str]:
    """``(camera carrier, target carrier)`` frame names for ``mount``: the robot's gripper and
    base frames (the file's ``frames``, else ``base``/``gripper`` arguments, else ``base`` and
    ``gripper``)."""
    b = pose_list.frames.get("base") or base or _DEFAULT_FRAMES["base"]
    g = pose_list.frames.get("gripper") or gripper or _DEFAULT_FRAMES["gripper"]
    return (g, b) if mount == "eye_in_hand" else (b, g)


def pose_list_problem(pose_list: PoseList, mount: str, *, sigma: float, kappa: float,
                      unknown_scale: bool = False, min_pairs: int = 1) -> Problem:
    """The problem ``A_i X_j = Y_k B_i`` of a pose list (module docstring for ``A``, ``X``,
    ``Y``): targets are X, cameras Y, one edge per (target, camera) with its pairs in file order;
    edges with fewer than ``min_pairs`` pairs are left out (``ValueError`` if none is left)."""
    if mount not in MOUNTS:
        raise ValueError(f"mount: expected one of {list(MOUNTS)}, got {mount!r}")
    groups: dict[tuple[str, str], list[PosePair]] = {}
    for p in pose_list.pairs:
        groups.setdefault((p.target, p.camera), []).append(p)
    edges = []
    for (x, y), pairs in groups.items():
        if len(pairs) < min_pairs:
            continue
        T = np.array([p.T_base_gripper for p in pairs])
        A = invert_transform(T) if mount == "eye_in_hand" else T
        B = np.array([p.T_cam_target for p in pairs])
        edges.append(Edge.build(x, y, A, B, sigma=sigma, kappa=kappa))
    if not edges:
        raise ValueError(f"{pose_list.source}: no (target, camera) edge has {min_pairs} pairs")
    x_names = list(dict.fromkeys(e.x for e in edges))
    y_names = list(dict.fromkeys(e.y for e in edges))
    if set(x_names) & set(y_names):
        raise ValueError(f"{pose_list.source}: names used both as camera and as target: "
                         f"{sorted(set(x_names) & set(y_names))}")
    return Problem(x_names, y_names, edges, unknown_scale=unknown_scale)

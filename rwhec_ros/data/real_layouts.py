"""Readers of folders of hand-eye samples as other tools write them: images with one robot pose
each, the camera intrinsics and the target.

Two layouts (three real data sets; ``benchmarks/real_data.py``):

* **industrial_calibration** (ros-industrial): ``cal_data.yaml`` with ``data:`` (a list of
  ``{image: images/N.png, pose: poses/N.yaml}``), ``intrinsics: {fx, fy, cx, cy}`` (no
  distortion), ``target_finder`` (``CharucoGridTargetFinder``: ``rows``, ``cols`` squares,
  ``chessboard_dim``, ``aruco_marker_dim``, ``dictionary`` as OpenCV's enum number;
  ``ModifiedCircleGridTargetFinder``: ``rows``, ``cols``, ``spacing``, a larger origin circle)
  and ``static_camera`` (true: the camera is fixed, the target on the robot). ``poses/N.yaml``:
  ``x y z qx qy qz qw`` = ``T_base_tool`` (metres, keys in any order).
* **camera_calibration_toolkit**: ``N.jpg`` (or ``.png``) with ``N.json`` holding ``end2base``
  (4x4 ``T_base_end``, row-major list of rows, metres), ``chessboard_config.json``
  (``parameters: {width, height, square_size}``: inner corners) and no intrinsics; eye-in-hand.
  The intrinsics are refitted here by ``cv2.calibrateCamera`` on the chessboard corners of the
  same views (``cv2.findChessboardCornersSB``), as the toolkit itself does (stated in
  :attr:`SampleSet.intrinsics_source`).

Either way a :class:`SampleSet` comes out: the images (read on demand), each view's pose
``T_base_tool``, the intrinsics, the target as a :class:`~rwhec_ros.vision.targets.TargetSpec`
and the mount; :meth:`SampleSet.parameters` gives the calibrator parameters (carriers, pose
source) that read the poses the right way round (eye-in-hand: the cameras on the tool, the
target in the base; eye-to-hand: the other way), so the samples go through the same session as
images and poses from the node or a bag (:func:`feed_session`).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from ..core.lie import make_transform
from ..vision.boards import CharucoSpec
from ..vision.grids import ChessboardSpec, CircleGridSpec
from ..vision.intrinsics import CameraIntrinsics
from ..vision.targets import TargetSpec

__all__ = ["SampleView", "SampleSet", "read_samples", "read_industrial_calibration",
           "read_calibration_toolkit", "feed_session", "LAYOUTS", "CAMERA", "TARGET",
           "BASE_FRAME", "TOOL_FRAME"]

#: Names given to the one camera and the one target of a sample folder.
CAMERA = "camera"
TARGET = "target"
BASE_FRAME = "base"
TOOL_FRAME = "tool"
#: Layout names of :func:`read_samples`.
LAYOUTS = ("industrial_calibration", "camera_calibration_toolkit")

# OpenCV's cv2.aruco predefined dictionary enum -> name (industrial_calibration stores the number).
_ARUCO_ENUM = {getattr(cv2.aruco, n): n for n in dir(cv2.aruco)
               if n.startswith("DICT_") and isinstance(getattr(cv2.aruco, n), int)}


@dataclass(frozen=True)
class SampleView:
    """One view: its image file and the robot pose ``T_base_tool`` (4, 4) at it."""

    image: Path
    T_base_tool: np.ndarray

    def gray(self) -> np.ndarray:
        """The image as (H, W) uint8 (``ValueError`` when it cannot be read)."""
        img = cv2.imread(str(self.image), cv2.IMREAD_GRAYSCALE)
        if img is None:
            raise ValueError(f"{self.image}: not a readable image")
        return img


@dataclass(frozen=True)
class SampleSet:
    """A folder of hand-eye samples (module docstring).

    Attributes
    ----------
    name : str
        The folder's name.
    layout : str
        One of :data:`LAYOUTS`.
    views : tuple of SampleView
        In the order of the folder's list (numeric order of the file names otherwise).
    intrinsics : CameraIntrinsics
    intrinsics_source : str
        Where the intrinsics come from, in words.
    target : TargetSpec
        Named :data:`TARGET`.
    camera_on_tool : bool
        Eye-in-hand (True) or a fixed camera with the target on the tool (False).
    """

    name: str
    layout: str
    views: tuple[SampleView, ...]
    intrinsics: CameraIntrinsics
    intrinsics_source: str
    target: TargetSpec
    camera_on_tool: bool

    def parameters(self) -> dict[str, Any]:
        """Flat calibrator parameters of this rig: carriers, pose source (``T_base_tool`` as
        ``pose_source.parent -> child``), the camera and the target; add the solver, noise and
        detection settings. ``A = T_<camera carrier>_<target carrier>`` then reads the poses
        the right way round for the mount."""
        from ..config.targets import target_parameters

        cam, tgt = (TOOL_FRAME, BASE_FRAME) if self.camera_on_tool else (BASE_FRAME, TOOL_FRAME)
        flat: dict[str, Any] = {
            "camera_carrier.frame": cam, "camera_carrier.moving": cam == TOOL_FRAME,
            "tag_carrier.frame": tgt, "tag_carrier.moving": tgt == TOOL_FRAME,
            "pose_source.type": "tf", "pose_source.parent": BASE_FRAME,
            "pose_source.child": TOOL_FRAME,
            "cameras.names": [CAMERA],
            f"cameras.{CAMERA}.image_topic": f"/{CAMERA}/image_raw",
            f"cameras.{CAMERA}.camera_info_topic": f"/{CAMERA}/camera_info",
            "tags.family": "tag36h11", "tags.ids": [],
            "targets.names": [self.target.name],
        }
        flat.update(target_parameters(self.target))
        return flat


def _read_yaml(path: Path) -> Any:
    try:
        with open(path, encoding="utf-8") as f:
            return yaml.safe_load(f)
    except (OSError, yaml.YAMLError) as exc:
        raise ValueError(f"{path}: cannot read: {exc}") from None


def _number(d: dict, key: str, where: Path) -> float:
    try:
        v = float(d[key])
    except (KeyError, TypeError, ValueError):
        raise ValueError(f"{where}: {key}: missing or not a number") from None
    if not np.isfinite(v):
        raise ValueError(f"{where}: {key}: not finite, got {v!r}")
    return v


def _pose_yaml(path: Path) -> np.ndarray:
    """``T_base_tool`` of an industrial_calibration pose file (``x y z qx qy qz qw``)."""
    d = _read_yaml(path)
    if not isinstance(d, dict):
        raise ValueError(f"{path}: expected a mapping with x y z qx qy qz qw")
    t = [_number(d, k, path) for k in ("x", "y", "z")]
    q = np.array([_number(d, k, path) for k in ("qx", "qy", "qz", "qw")])
    n = np.linalg.norm(q)
    if not abs(n - 1.0) < 1e-3:
        raise ValueError(f"{path}: quaternion norm {n:.6f}, expected 1")
    from scipy.spatial.transform import Rotation

    return make_transform(Rotation.from_quat(q / n).as_matrix(), np.array(t))


def _ic_target(finder: dict, where: Path) -> TargetSpec:
    kind = str(finder.get("type", ""))
    try:
        if kind == "CharucoGridTargetFinder":
            enum = int(finder["dictionary"])
            if enum not in _ARUCO_ENUM:
                raise ValueError(f"dictionary {enum} is not one of OpenCV's")
            board = CharucoSpec(int(finder["cols"]), int(finder["rows"]),
                                float(finder["chessboard_dim"]),
                                float(finder["aruco_marker_dim"]), _ARUCO_ENUM[enum])
        elif kind == "ModifiedCircleGridTargetFinder":
            board = CircleGridSpec(int(finder["cols"]), int(finder["rows"]),
                                   float(finder["spacing"]), origin_circle=True)
        else:
            raise ValueError(f"type {kind!r} is not supported (CharucoGridTargetFinder, "
                             f"ModifiedCircleGridTargetFinder)")
    except (KeyError, TypeError) as exc:
        raise ValueError(f"{where}: target_finder: missing or bad key {exc}") from None
    except ValueError as exc:
        raise ValueError(f"{where}: target_finder: {exc}") from None
    return TargetSpec(TARGET, board=board, min_corners=min(8, board.n_corners))


def read_industrial_calibration(folder: str | Path) -> SampleSet:
    """A folder of industrial_calibration's layout (module docstring)."""
    root = Path(folder)
    cal = root / "cal_data.yaml"
    doc = _read_yaml(cal)
    if not isinstance(doc, dict) or not isinstance(doc.get("data"), list):
        raise ValueError(f"{cal}: expected a mapping with a 'data' list")
    views = []
    for i, item in enumerate(doc["data"]):
        if not isinstance(item, dict) or "image" not in item or "pose" not in item:
            raise ValueError(f"{cal}: data[{i}] must have 'image' and 'pose'")
        views.append(SampleView(root / str(item["image"]), _pose_yaml(root / str(item["pose"]))))
    intr = doc.get("intrinsics")
    if not isinstance(intr, dict):
        raise ValueError(f"{cal}: intrinsics: missing")
    first = views[0].gray() if views else None
    if first is None:
        raise ValueError(f"{cal}: data: no views")
    intrinsics = CameraIntrinsics.pinhole(first.shape[1], first.shape[0],
                                          _number(intr, "fx", cal), _number(intr, "fy", cal),
                                          _number(intr, "cx", cal), _number(intr, "cy", cal))
    return SampleSet(root.name, LAYOUTS[0], tuple(views), intrinsics,
                     "cal_data.yaml's intrinsics (no distortion)",
                     _ic_target(doc.get("target_finder") or {}, cal),
                     camera_on_tool=not bool(doc.get("static_camera", False)))


def _refit_intrinsics(grays: list[np.ndarray], spec: ChessboardSpec,
                      where: Path) -> tuple[CameraIntrinsics, str]:
    """``cv2.calibrateCamera`` (plumb_bob) on the chessboard corners of ``grays``, in OpenCV's
    own order and board frame (``x`` along a row, ``y`` down the rows, ``z`` into the board:
    right-handed for the order OpenCV returns; the intrinsics do not depend on the frame)."""
    cols, rows = spec.pattern_size
    grid = np.zeros((rows * cols, 3), np.float32)
    grid[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * spec.square_size
    obj, img = [], []
    for g in grays:
        ok, corners = cv2.findChessboardCornersSB(g, spec.pattern_size)
        if ok:
            obj.append(grid)
            img.append(np.asarray(corners, dtype=np.float32).reshape(-1, 1, 2))
    if len(obj) < 3:
        raise ValueError(f"{where}: the chessboard is found in {len(obj)} images, at least 3 "
                         f"are needed to refit the intrinsics")
    h, w = grays[0].shape
    rms, K, D, _, _ = cv2.calibrateCamera(obj, img, (w, h), None, None)
    intr = CameraIntrinsics(w, h, K, np.asarray(D, dtype=float).reshape(-1)[:5], "plumb_bob")
    return intr, (f"refitted by cv2.calibrateCamera from the chessboard in {len(obj)} of the "
                  f"{len(grays)} views (RMS {rms:.3f} px)")


def read_calibration_toolkit(folder: str | Path) -> SampleSet:
    """A folder of camera_calibration_toolkit's layout (module docstring)."""
    root = Path(folder)
    cfg_path = root / "chessboard_config.json"
    try:
        cfg = json.loads(cfg_path.read_text(encoding="utf-8"))
        p = cfg["parameters"]
        spec = ChessboardSpec(int(p["width"]), int(p["height"]), float(p["square_size"]))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{cfg_path}: cannot read the chessboard: {exc}") from None
    views = []
    for js in sorted(root.glob("*.json"), key=lambda q: (len(q.stem), q.stem)):
        if not js.stem.isdigit():
            continue
        image = next((js.with_suffix(s) for s in (".jpg", ".png") if js.with_suffix(s).exists()),
                     None)
        if image is None:
            continue
        try:
            T = np.asarray(json.loads(js.read_text(encoding="utf-8"))["end2base"], dtype=float)
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ValueError(f"{js}: end2base: {exc}") from None
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ValueError(f"{js}: end2base must be a finite 4x4 matrix")
        views.append(SampleView(image, T))
    if not views:
        raise ValueError(f"{root}: no N.json with N.jpg/N.png")
    intrinsics, source = _refit_intrinsics([v.gray() for v in views], spec, root)
    return SampleSet(root.name, LAYOUTS[1], tuple(views), intrinsics, source,
                     TargetSpec(TARGET, board=spec, min_corners=8), camera_on_tool=True)


def read_samples(folder: str | Path) -> SampleSet:
    """The sample folder in whichever layout it has (``cal_data.yaml``: industrial_calibration;
    ``chessboard_config.json``: camera_calibration_toolkit)."""
    root = Path(folder)
    if (root / "cal_data.yaml").is_file():
        return read_industrial_calibration(root)
    if (root / "chessboard_config.json").is_file():
        return read_calibration_toolkit(root)
    raise ValueError(f"{root}: not a known sample layout (no cal_data.yaml, no "
                     f"chessboard_config.json)")


def feed_session(session, samples: SampleSet, *,
                 on_image: Callable[[int, Any], None] | None = None) -> None:
    """Give every view of ``samples`` to ``session`` (a
    :class:`~rwhec_ros.session.CalibrationSession` configured with
    :meth:`SampleSet.parameters`) as the CLI's replay does: the camera's intrinsics, then each
    image with its pose at a stamp one second after the previous (``add_image`` with the pose,
    as from tf). ``on_image(index, outcome)`` sees each image's outcome."""
    session.set_camera_info(CAMERA, samples.intrinsics)
    for i, view in enumerate(samples.views):
        outcome = session.add_image(CAMERA, (i + 1) * 1_000_000_000, view.gray(),
                                    T_parent_child=view.T_base_tool)
        if on_image is not None:
            on_image(i, outcome)

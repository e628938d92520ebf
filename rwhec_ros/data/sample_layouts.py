"""The stop-and-go folders of other tools, read as they are into a :class:`~.samples.SampleSet`.

* **industrial_calibration** (ros-industrial): ``cal_data.yaml`` with ``data: [{image, pose}]``
  (paths relative to it), ``intrinsics: {fx, fy, cx, cy}`` (no distortion: read as none, and
  said so), ``static_camera`` (true: eye-to-hand, false: eye-in-hand), ``target_finder``; each
  ``poses/N.yaml`` holds ``x y z`` [m] and ``qx qy qz qw`` = ``T_base_tool`` (the flange), so the
  pose frames are ``base`` -> ``tool``. Targets: ``CharucoGridTargetFinder`` (``rows``,
  ``cols``, ``chessboard_dim``, ``aruco_marker_dim``, ``dictionary`` as OpenCV's enum number)
  becomes a ``charuco`` target ``board``; ``ModifiedCircleGridTargetFinder`` (``rows``,
  ``cols``, ``spacing`` between dot centres, the bottom-left dot larger) a ``circles`` target
  with ``origin_circle: true`` where this installation has that type.
* **camera_calibration_toolkit** (yizhongzhang1989): ``N.jpg`` (or ``.png``) with ``N.json``
  holding ``end2base``, the 4 x 4 ``T_base_end`` (rows, metres); frames ``base`` -> ``end``. No
  intrinsics are shipped (the toolkit calibrates them from the same images): they must be given
  (``--intrinsics FILE``). ``chessboard_config.json`` (``standard_chessboard``, ``width`` x
  ``height`` inner corners, ``square_size``) becomes a ``chessboard`` target ``board`` where
  this installation has that type. The folder does not say how the camera is mounted.

Both name their frames generically (``frames_named`` False): with a configuration, its carrier
frames replace them (the fixed carrier is the base). Their target words go into every message
about the target, so that a missing target type is explained with the data's own description.
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from .intrinsics_files import IntrinsicsFile
from .pose_fields import check_rigid, pose_from_fields
from .samples import SampleSet, SampleView, read_manifest

__all__ = ["read_samples", "read_industrial_calibration", "read_calibration_toolkit",
           "LAYOUTS", "MANIFEST_NAME", "BOARD_NAME"]

#: The manifest's file name when a folder is given.
MANIFEST_NAME = "samples.yaml"
#: Layouts :func:`read_samples` knows, by name (``--layout``).
LAYOUTS = ("manifest", "industrial_calibration", "camera_calibration_toolkit")
#: Target frame name of the layouts' single board.
BOARD_NAME = "board"
#: The target name of a layout whose target is one marker.
MARKER_NAME = "marker"
_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


def _load_yaml(path: Path) -> Any:
    try:
        return yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not YAML ({exc})") from None
    except OSError as exc:
        raise ValueError(f"{path}: cannot read it ({exc})") from None


def _target_types() -> tuple[str, ...]:
    from ..config.specs import TARGET_TYPES

    return tuple(TARGET_TYPES)


def _aruco_name(value: Any, where: str) -> str:
    """OpenCV's ``cv2.aruco.DICT_*`` name of an enum number (or a name as given)."""
    import cv2

    if isinstance(value, str):
        return value
    names = [n for n in dir(cv2.aruco) if n.startswith("DICT_") and getattr(cv2.aruco, n) == value]
    if isinstance(value, bool) or not names:
        raise ValueError(f"{where}: dictionary {value!r} is no cv2.aruco dictionary number")
    return names[0]


def _ic_target(finder: Any, where: str) -> tuple[dict[str, Any], str]:
    """Flat target parameters and words of an industrial_calibration ``target_finder``."""
    if not isinstance(finder, Mapping):
        return {}, "no target_finder"
    kind = str(finder.get("type", ""))
    p = f"targets.{BOARD_NAME}."
    if kind == "CharucoGridTargetFinder":
        try:
            params = {"targets.names": [BOARD_NAME], p + "type": "charuco",
                      p + "squares_x": int(finder["cols"]), p + "squares_y": int(finder["rows"]),
                      p + "square_size": float(finder["chessboard_dim"]),
                      p + "marker_size": float(finder["aruco_marker_dim"]),
                      p + "dictionary": _aruco_name(finder["dictionary"], where)}
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{where}: target_finder of type {kind}: {exc}") from None
        words = (f"ChArUco {params[p + 'squares_x']} x {params[p + 'squares_y']} squares of "
                 f"{params[p + 'square_size']} m, {params[p + 'dictionary']}")
        return params, words
    if kind == "ModifiedCircleGridTargetFinder":
        words = (f"modified circle grid {finder.get('rows')} x {finder.get('cols')} dots, "
                 f"{finder.get('spacing')} m spacing, big origin dot")
        if "circles" not in _target_types():
            return {}, words
        try:
            return {"targets.names": [BOARD_NAME], p + "type": "circles",
                    p + "rows": int(finder["rows"]), p + "cols": int(finder["cols"]),
                    p + "circle_spacing": float(finder["spacing"]),
                    p + "origin_circle": True}, words
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{where}: target_finder of type {kind}: {exc}") from None
    return {}, f"target_finder type {kind!r}"


def read_industrial_calibration(directory: str | Path) -> SampleSet:
    """An industrial_calibration folder (module docstring); ``ValueError`` naming the file."""
    directory = Path(directory)
    cal = directory / "cal_data.yaml"
    doc = _load_yaml(cal)
    if not isinstance(doc, Mapping) or not isinstance(doc.get("data"), list):
        raise ValueError(f"{cal}: expected industrial_calibration's data: [{{image, pose}}]")
    views = []
    for i, entry in enumerate(doc["data"]):
        where = f"{cal}: data[{i}]"
        if not isinstance(entry, Mapping) or "image" not in entry or "pose" not in entry:
            raise ValueError(f"{where}: expected {{image: FILE, pose: FILE}}, got {entry!r}")
        pose_path = directory / str(entry["pose"])
        pose = _load_yaml(pose_path)
        keys = ("x", "y", "z", "qx", "qy", "qz", "qw")
        if not isinstance(pose, Mapping) or any(k not in pose for k in keys):
            raise ValueError(f"{pose_path}: expected the keys {list(keys)}, got {pose!r}")
        T = pose_from_fields({"translation": [pose[k] for k in "xyz"],
                              "quaternion": [pose[k] for k in ("qx", "qy", "qz", "qw")]},
                             str(pose_path))
        views.append(SampleView(f"view {i} ({entry['image']})",
                                {"cam0": directory / str(entry["image"])}, T))
    if not views:
        raise ValueError(f"{cal}: data: no views")
    notes = []
    intr = doc.get("intrinsics")
    intrinsics: IntrinsicsFile | None = None
    if isinstance(intr, Mapping):
        try:
            fx, fy, cx, cy = (float(intr[k]) for k in ("fx", "fy", "cx", "cy"))
        except (KeyError, TypeError, ValueError):
            raise ValueError(f"{cal}: intrinsics: expected fx, fy, cx, cy, got {intr!r}") from None
        K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
        intrinsics = IntrinsicsFile(f"{cal} (intrinsics)", "industrial_calibration", K,
                                    np.zeros(0), "plumb_bob")
        notes.append(f"{cal.name}: intrinsics fx {fx:g}, fy {fy:g}, cx {cx:g}, cy {cy:g} "
                     "without distortion (none given); --intrinsics FILE replaces them")
    static = doc.get("static_camera")
    mount = None if static is None else ("eye_to_hand" if bool(static) else "eye_in_hand")
    params, words = _ic_target(doc.get("target_finder"), str(cal))
    return SampleSet(source=str(directory), layout="industrial_calibration", pose_parent="base",
                     pose_child="tool", frames_named=False, cameras=("cam0",),
                     views=tuple(views), intrinsics={"cam0": intrinsics}, mount=mount,
                     target_parameters=params, target_words=words, notes=tuple(notes))


def _number_key(path: Path):
    return (0, int(path.stem), "") if path.stem.isdigit() else (1, 0, path.stem)


def _cct_target(directory: Path) -> tuple[dict[str, Any], str]:
    path = directory / "chessboard_config.json"
    if not path.is_file():
        return {}, "no chessboard_config.json"
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        params = doc["parameters"]
        kind = str(doc.get("pattern_id", ""))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{path}: expected pattern_id and parameters ({exc})") from None
    if kind == "grid_board" and _one_marker(params):
        return _cct_marker(params, path)
    if kind != "standard_chessboard":
        return {}, f"pattern {kind!r} of {path.name}"
    try:
        cols, rows, square = int(params["width"]), int(params["height"]), float(
            params["square_size"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{path}: parameters: expected width, height, square_size ({exc})"
                         ) from None
    words = f"chessboard {cols} x {rows} inner corners, {square} m squares"
    if "chessboard" not in _target_types():
        return {}, words
    p = f"targets.{BOARD_NAME}."
    return {"targets.names": [BOARD_NAME], p + "type": "chessboard", p + "cols": cols,
            p + "rows": rows, p + "square_size": square}, words


def _one_marker(params: Any) -> bool:
    try:
        return int(params.get("width", 0)) == 1 and int(params.get("height", 0)) == 1
    except (AttributeError, TypeError, ValueError):
        return False


def _cct_marker(params: Any, path: Path) -> tuple[dict[str, Any], str]:
    """A toolkit ``grid_board`` of one marker (1 x 1): a single tag of its ArUco dictionary, id
    0 (OpenCV's first id of a grid board), the side of its black square ``marker_size``."""
    try:
        size = float(params["marker_size"])
        family = _aruco_name(params.get("dictionary_id", "DICT_6X6_250"),
                             f"{path}: parameters.dictionary_id")
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{path}: parameters: expected marker_size and dictionary_id ({exc})"
                         ) from None
    words = f"one ArUco marker ({family}, id 0) of {size} m"
    p = f"targets.{MARKER_NAME}."
    return {"targets.names": [MARKER_NAME], p + "type": "tag", p + "tag_id": 0,
            p + "tag_size": size, "tags.family": family}, words


def read_calibration_toolkit(directory: str | Path) -> SampleSet:
    """A camera_calibration_toolkit folder (module docstring); ``ValueError`` naming the file."""
    directory = Path(directory)
    views = []
    for js in sorted(directory.glob("*.json"), key=_number_key):
        try:
            doc = json.loads(js.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise ValueError(f"{js}: not JSON ({exc})") from None
        if not isinstance(doc, Mapping) or "end2base" not in doc:
            continue
        image = next((js.with_suffix(s) for s in _IMAGE_SUFFIXES if js.with_suffix(s).is_file()),
                     None)
        if image is None:
            raise ValueError(f"{js}: no image {js.stem}.jpg/.png beside it")
        try:
            T = np.asarray(doc["end2base"], dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{js}: end2base: not a 4 x 4 matrix of numbers") from None
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ValueError(f"{js}: end2base: expected a finite 4 x 4 matrix, got shape "
                             f"{T.shape}")
        views.append(SampleView(f"view {js.stem} ({image.name})", {"cam0": image},
                                check_rigid(T, f"{js}: end2base")))
    if not views:
        raise ValueError(f"{directory}: no N.json with end2base")
    params, words = _cct_target(directory)
    return SampleSet(source=str(directory), layout="camera_calibration_toolkit",
                     pose_parent="base", pose_child="end", frames_named=False,
                     cameras=("cam0",), views=tuple(views), intrinsics={"cam0": None},
                     target_parameters=params, target_words=words)


def _is_toolkit(directory: Path) -> bool:
    for js in directory.glob("*.json"):
        if re.fullmatch(r"\d+", js.stem):
            try:
                return "end2base" in json.loads(js.read_text(encoding="utf-8"))
            except (OSError, ValueError, TypeError):
                return False
    return False


def read_samples(path: str | Path, layout: str = "auto") -> SampleSet:
    """Read a folder of views in any known layout (``layout="auto"``: a manifest file, or a
    folder with ``samples.yaml``, ``cal_data.yaml`` or ``N.json`` files with ``end2base``).

    Raises ``ValueError`` naming the path and what was looked for when nothing fits.
    """
    path = Path(path)
    if layout not in ("auto",) + LAYOUTS:
        raise ValueError(f"layout: expected auto or one of {list(LAYOUTS)}, got {layout!r}")
    if not path.exists():
        raise ValueError(f"{path}: no such file or directory")
    if path.is_file():
        if layout not in ("auto", "manifest"):
            raise ValueError(f"{path}: a file; the {layout} layout is a folder")
        return read_manifest(path)
    if layout in ("auto", "manifest") and (path / MANIFEST_NAME).is_file():
        return read_manifest(path / MANIFEST_NAME)
    if layout in ("auto", "industrial_calibration") and (path / "cal_data.yaml").is_file():
        return read_industrial_calibration(path)
    if layout in ("auto", "camera_calibration_toolkit") and _is_toolkit(path):
        return read_calibration_toolkit(path)
    raise ValueError(f"{path}: not a folder of views this reader knows: no {MANIFEST_NAME} (our "
                     "manifest), no cal_data.yaml (industrial_calibration), no N.json with "
                     "end2base (camera_calibration_toolkit)" +
                     (f" for --layout {layout}" if layout != "auto" else ""))

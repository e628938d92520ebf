"""Camera intrinsics from the files users already have.

:func:`read_intrinsics_file` reads

* the ROS ``camera_calibration`` / ``camera_info_manager`` YAML: ``image_width``,
  ``image_height``, ``camera_matrix: {rows: 3, cols: 3, data: [9]}``, ``distortion_model``,
  ``distortion_coefficients: {rows: 1, cols: n, data: [n]}`` (``rectification_matrix`` and
  ``projection_matrix`` are not used: images are not rectified);
* OpenCV ``cv2.FileStorage`` YAML (``%YAML:1.0``, ``!!opencv-matrix``) and XML
  (``<opencv_storage>``), as ``calibrateCamera`` samples write them: the camera matrix under
  one of :data:`MATRIX_KEYS`, the distortion under one of :data:`DISTORTION_KEYS`, the size as
  ``image_width``/``image_height`` (or ``width``/``height``, or ``image_size``/``imageSize``
  ``[w, h]``), optionally ``distortion_model``;
* plain YAML/JSON with the same keys, matrices as nested lists, flat lists of 9, or ROS's
  ``{data: [...]}``.

Distortion without a named model is OpenCV's order: 0 (none), 4 ``k1 k2 p1 p2`` (read as
``plumb_bob`` with ``k3 = 0``), 5 ``plumb_bob``, 8 ``rational_polynomial``; 12 or 14
coefficients (thin prism, tilt) only when the terms beyond the eighth are zero. A fisheye
(``equidistant``) file must say ``distortion_model: equidistant``: its 4 coefficients cannot be
told from ``k1 k2 p1 p2``. The image size may be absent; the caller then takes it from the
images (:meth:`IntrinsicsFile.intrinsics`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..vision.intrinsics import DISTORTION_MODELS, CameraIntrinsics

__all__ = ["IntrinsicsFile", "read_intrinsics_file", "MATRIX_KEYS", "DISTORTION_KEYS"]

#: Names under which files hold the camera matrix (first found wins).
MATRIX_KEYS = ("camera_matrix", "cameraMatrix", "Camera_Matrix", "K", "intrinsic_matrix",
               "intrinsics", "M")
#: Names under which files hold the distortion coefficients.
DISTORTION_KEYS = ("distortion_coefficients", "dist_coeffs", "distCoeffs",
                   "Distortion_Coefficients", "distortion", "D", "dist")
_WIDTH_KEYS = ("image_width", "width", "imageWidth")
_HEIGHT_KEYS = ("image_height", "height", "imageHeight")
_SIZE_KEYS = ("image_size", "imageSize", "size")


@dataclass(frozen=True)
class IntrinsicsFile:
    """Intrinsics read from one file; ``width``/``height`` None when the file has none."""

    path: str
    format: str
    K: np.ndarray
    D: np.ndarray
    model: str
    width: int | None = None
    height: int | None = None

    def intrinsics(self, width: int | None = None, height: int | None = None
                   ) -> CameraIntrinsics:
        """:class:`CameraIntrinsics` with the file's size, else ``width`` x ``height`` (the
        images'); ``ValueError`` naming the file when neither is known or they differ."""
        if self.width is not None and width is not None and (self.width, self.height) != (
                width, height):
            raise ValueError(f"{self.path}: intrinsics for {self.width}x{self.height} images, "
                             f"but the images are {width}x{height}")
        w = self.width if self.width is not None else width
        h = self.height if self.height is not None else height
        if w is None or h is None:
            raise ValueError(f"{self.path}: no image size (image_width/image_height) in the "
                             "file and no image to take it from")
        try:
            return CameraIntrinsics(width=w, height=h, K=self.K, D=self.D, model=self.model)
        except ValueError as exc:
            raise ValueError(f"{self.path}: {exc}") from None


def _distortion(D: np.ndarray, model: str | None, where: str) -> tuple[np.ndarray, str]:
    """``(D, model)`` for :class:`CameraIntrinsics` (module docstring for the rules)."""
    D = np.asarray(D, dtype=float).reshape(-1)
    if model:
        if model not in DISTORTION_MODELS:
            raise ValueError(f"{where}: distortion_model {model!r} is not supported (supported: "
                             f"{sorted(DISTORTION_MODELS)})")
        if model == "plumb_bob" and D.size == 4:
            D = np.append(D, 0.0)
        return D, model
    n = D.size
    if n in (0, 5):
        return D, "plumb_bob"
    if n == 4:
        return np.append(D, 0.0), "plumb_bob"
    if n == 8:
        return D, "rational_polynomial"
    if n in (12, 14) and not np.any(D[8:]):
        return D[:8], "rational_polynomial"
    raise ValueError(f"{where}: {n} distortion coefficients {D.tolist()}: supported are 0, 4, "
                     "5 and 8 (OpenCV's k1 k2 p1 p2 [k3 [k4 k5 k6]]), or a distortion_model")


def _matrix(value: Any, where: str) -> np.ndarray:
    """A 3 x 3 camera matrix from a nested list, a flat list of 9 or ROS's ``{data: [...]}``."""
    if isinstance(value, Mapping):
        if "data" not in value:
            raise ValueError(f"{where}: expected {{rows, cols, data}}, got the keys "
                             f"{sorted(value)}")
        value = value["data"]
    try:
        K = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: not a matrix of numbers: {value!r}") from None
    if K.size != 9:
        raise ValueError(f"{where}: expected 9 numbers (3 x 3), got {K.size}")
    return K.reshape(3, 3)


def _vector(value: Any, where: str) -> np.ndarray:
    if isinstance(value, Mapping):
        value = value.get("data", value)
    try:
        return np.asarray(value if value is not None else [], dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: not a list of numbers: {value!r}") from None


def _first(doc: Mapping[str, Any], keys: tuple[str, ...]) -> tuple[str | None, Any]:
    for k in keys:
        if k in doc and doc[k] is not None:
            return k, doc[k]
    return None, None


def _size(doc: Mapping[str, Any], where: str) -> tuple[int | None, int | None]:
    _, w = _first(doc, _WIDTH_KEYS)
    _, h = _first(doc, _HEIGHT_KEYS)
    if w is None or h is None:
        key, size = _first(doc, _SIZE_KEYS)
        if size is not None:
            s = _vector(size, f"{where}: {key}")
            if s.size != 2:
                raise ValueError(f"{where}: {key}: expected [width, height], got {s.tolist()}")
            w, h = s
    if w is None or h is None:
        return None, None
    try:
        wi, hi = int(w), int(h)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: image size {w!r} x {h!r} is not two integers") from None
    if wi != float(w) or hi != float(h) or wi <= 0 or hi <= 0:
        raise ValueError(f"{where}: image size {w!r} x {h!r} is not two positive integers")
    return wi, hi


def _from_mapping(doc: Mapping[str, Any], path: str, fmt: str) -> IntrinsicsFile:
    key, value = _first(doc, MATRIX_KEYS)
    if key is None:
        raise ValueError(f"{path}: no camera matrix (looked for {list(MATRIX_KEYS)}; the file "
                         f"has {sorted(map(str, doc))})")
    K = _matrix(value, f"{path}: {key}")
    dkey, dvalue = _first(doc, DISTORTION_KEYS)
    D = _vector(dvalue, f"{path}: {dkey}") if dkey is not None else np.zeros(0)
    model = doc.get("distortion_model") or None
    D, model = _distortion(D, None if model is None else str(model), path)
    w, h = _size(doc, path)
    return IntrinsicsFile(path, fmt, K, D, model, w, h)


def _read_file_storage(path: Path) -> IntrinsicsFile:
    """An OpenCV FileStorage YAML/XML through ``cv2.FileStorage``."""
    import cv2

    where = str(path)
    try:
        fs = cv2.FileStorage(where, cv2.FILE_STORAGE_READ)
    except cv2.error as exc:
        raise ValueError(f"{where}: not readable as an OpenCV FileStorage file "
                         f"({str(exc).strip()})") from None
    try:
        if not fs.isOpened():
            raise ValueError(f"{where}: not readable as an OpenCV FileStorage file")
        root = fs.root()
        doc: dict[str, Any] = {}
        for key in root.keys():
            node = fs.getNode(key)
            if node.isString():
                doc[key] = node.string()
            elif node.isReal() or node.isInt():
                doc[key] = node.real()
            elif node.isSeq():
                doc[key] = [node.at(i).real() for i in range(node.size())]
            else:
                mat = node.mat()
                if mat is not None:
                    doc[key] = np.asarray(mat, dtype=float)
    finally:
        fs.release()
    fmt = "opencv_xml" if path.suffix.lower() == ".xml" else "opencv_yaml"
    return _from_mapping(doc, where, fmt)


def read_intrinsics_file(path: str | Path) -> IntrinsicsFile:
    """Read the intrinsics of one camera (module docstring for the formats).

    Raises
    ------
    ValueError
        Naming the file: unreadable, no camera matrix (listing the keys looked for and the keys
        present), a wrong shape, an unsupported distortion model or count.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"intrinsics file {str(path)!r}: no such file")
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise ValueError(f"intrinsics file {str(path)!r}: cannot read it ({exc})") from None
    head = text.lstrip()[:64]
    if head.startswith("%YAML") or head.startswith("<?xml") or head.startswith("<opencv"):
        return _read_file_storage(path)
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not YAML/JSON ({exc})") from None
    if not isinstance(doc, Mapping):
        raise ValueError(f"{path}: expected a mapping of keys (camera_matrix, ...), got "
                         f"{type(doc).__name__}")
    ros = isinstance(doc.get("camera_matrix"), Mapping)
    return _from_mapping(doc, str(path), "ros_yaml" if ros else "yaml")

"""Stop-and-go samples: a folder of views, each an image per camera plus the robot pose there.

The data users already have from an arm moved from pose to pose ("take sample"): per view one
image per camera and the robot's pose at that view, per camera its intrinsics. This module holds
the common representation (:class:`SampleSet`) and our own manifest format; the layouts of other
tools are read by :mod:`rwhec_ros.data.sample_layouts`. ``rwhec-calibrate samples`` feeds a
:class:`SampleSet` through the live session (:mod:`rwhec_ros.cli.samples`).

Manifest (``samples.yaml``; paths relative to the file)::

    samples: 1                      # format version
    pose:                           # every view's pose is T_<parent>_<child>: it maps
      parent: base_link             #   <child> coordinates into <parent> (tf's lookup of
      child: tool0                  #   parent -> child, e.g. the arm's base -> flange)
    mount: eye_in_hand              # cameras on pose.child (eye_in_hand) or on pose.parent
                                    # (eye_to_hand); or camera_carrier: <one of the two frames>
    cameras:                        # optional with a single camera (then named cam0)
      cam0: {intrinsics: cam0.yaml} # ROS camera_calibration YAML, OpenCV FileStorage YAML/XML
    targets:                        # optional: the configuration's targets/tags sections
      names: [board]
      board: {type: charuco, squares_x: 5, squares_y: 7, square_size: 0.036,
              marker_size: 0.018, dictionary: DICT_6X6_250}
    views:
      - image: images/0.png         # one camera; several: images: {cam0: a.png, cam1: b.png}
        translation: [0.41, -0.12, 0.52]      # metres
        quaternion: [0.0, 1.0, 0.0, 0.0]      # x, y, z, w
      - image: images/1.png
        matrix: [[1, 0, 0, 0.4], [0, 1, 0, 0.1], [0, 0, 1, 0.5], [0, 0, 0, 1]]
        stamp: 12.5                 # optional [s]; default: the view's number + 1

Pose forms: :mod:`rwhec_ros.data.pose_fields` (also ``rvec`` and a 3 x 3 ``rotation``). In
``A_i X = Y B_i`` (cameras Y, targets X): eye-in-hand ``A = T_child_parent`` (the inverse of the
written pose), ``X = T_parent_target``, ``Y = T_child_cam``; eye-to-hand ``A = T_parent_child``
(as written), ``X = T_child_target``, ``Y = T_parent_cam``; ``B = T_cam_target`` from the image.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..config.parameter_file import flatten_parameters
from .intrinsics_files import IntrinsicsFile, read_intrinsics_file
from .pose_fields import pose_from_fields

__all__ = ["SampleView", "SampleSet", "MOUNTS", "MANIFEST_VERSION", "read_manifest",
           "manifest_document", "write_manifest"]

MANIFEST_VERSION = 1
#: ``mount`` values: the cameras ride on the pose's child (the flange) or its parent (the base).
MOUNTS = ("eye_in_hand", "eye_to_hand")
_NS_PER_S = 1_000_000_000
_VIEW_KEYS = {"image", "images", "stamp", "translation", "quaternion", "rvec", "rotation",
              "matrix", "name"}
_TOP_KEYS = {"samples", "pose", "mount", "camera_carrier", "cameras", "targets", "tags", "views"}


@dataclass(frozen=True)
class SampleView:
    """One stop of the robot: an image per camera and the pose there.

    Attributes
    ----------
    name : str
        How messages name the view (``view 3 (images/3.png)``).
    images : dict of str to Path
        Camera name -> image file (PNG, JPEG, ... as ``cv2.imdecode`` reads).
    T_parent_child : ndarray (4, 4)
        The robot pose ``T_<pose_parent>_<pose_child>`` of the :class:`SampleSet`.
    stamp_ns : int or None
        When the view was taken [ns], if known.
    """

    name: str
    images: dict[str, Path]
    T_parent_child: np.ndarray
    stamp_ns: int | None = None


@dataclass(frozen=True)
class SampleSet:
    """A folder of views (module docstring).

    Attributes
    ----------
    source : str
        The manifest or folder read.
    layout : str
        ``manifest``, ``industrial_calibration`` or ``camera_calibration_toolkit``.
    pose_parent, pose_child : str
        The frames of every view's pose ``T_parent_child`` (parent: the robot base, child: the
        flange for the tool layouts).
    frames_named : bool
        False when the layout does not name its frames (``pose_parent`` is the robot's base and
        ``pose_child`` its flange under made-up names): a configuration's frames replace them.
    cameras : tuple of str
    views : tuple of SampleView
    intrinsics : dict of str to IntrinsicsFile or None
        Per camera; None where the data ship none (``--intrinsics`` must give them).
    mount : str or None
        ``eye_in_hand`` / ``eye_to_hand`` when the data say so.
    camera_carrier : str or None
        The pose frame carrying the cameras, when the data name it instead of ``mount``.
    target_parameters : dict
        Flat ``targets.*`` / ``tags.*`` parameters of the target the data describe ({} if none).
    target_words : str
        The data's own description of the target (for messages).
    notes : tuple of str
        What the reader noticed and the user should know (printed as notes).
    """

    source: str
    layout: str
    pose_parent: str
    pose_child: str
    cameras: tuple[str, ...]
    views: tuple[SampleView, ...]
    intrinsics: dict[str, IntrinsicsFile | None]
    frames_named: bool = True
    mount: str | None = None
    camera_carrier: str | None = None
    target_parameters: dict[str, Any] = field(default_factory=dict)
    target_words: str = ""
    notes: tuple[str, ...] = ()

    def stamps_ns(self) -> list[int]:
        """One stamp per view [ns]: the given ones (strictly increasing), else view ``i`` at
        ``i + 1`` seconds."""
        given = [v.stamp_ns for v in self.views]
        if all(s is None for s in given):
            return [(i + 1) * _NS_PER_S for i in range(len(self.views))]
        if any(s is None for s in given):
            missing = next(v.name for v in self.views if v.stamp_ns is None)
            raise ValueError(f"{self.source}: {missing} has no stamp while others have one: give "
                             "every view a stamp or none")
        for a, b, v in zip(given, given[1:], self.views[1:], strict=False):
            if b <= a:
                raise ValueError(f"{self.source}: {v.name}: stamp {b / 1e9:g} s is not after the "
                                 f"previous view's {a / 1e9:g} s (views in the order taken)")
        return [int(s) for s in given]


def _where(path: Path, what: str) -> str:
    return f"{path}: {what}"


def _frame(value: Any, where: str) -> str:
    if not isinstance(value, str) or not value.strip() or any(c.isspace() for c in value.strip()):
        raise ValueError(f"{where}: expected a frame name (no spaces), got {value!r}")
    return value.strip()


def _view(i: int, entry: Any, base: Path, cameras: tuple[str, ...] | None, path: Path
          ) -> SampleView:
    where = _where(path, f"views[{i}]")
    if not isinstance(entry, Mapping):
        raise ValueError(f"{where}: expected a mapping (image, pose, stamp), got {entry!r}")
    unknown = sorted(set(entry) - _VIEW_KEYS)
    if unknown:
        raise ValueError(f"{where}: unknown keys {unknown} (a view has image or images, the "
                         "pose as translation + quaternion/rvec/rotation or matrix, stamp, name)")
    if ("image" in entry) == ("images" in entry):
        raise ValueError(f"{where}: give 'image' (one camera) or 'images' (camera -> file)")
    if "image" in entry:
        if cameras is not None and len(cameras) != 1:
            raise ValueError(f"{where}: 'image' with {len(cameras)} cameras {list(cameras)}: "
                             "use images: {camera: file}")
        images = {cameras[0] if cameras else "cam0": entry["image"]}
    else:
        images = entry["images"]
        if not isinstance(images, Mapping) or not images:
            raise ValueError(f"{where}.images: expected a mapping camera -> file, got "
                             f"{images!r}")
        if cameras is not None:
            bad = sorted(set(map(str, images)) - set(cameras))
            if bad:
                raise ValueError(f"{where}.images: cameras {bad} are not in cameras "
                                 f"{list(cameras)}")
    files = {}
    for cam, name in images.items():
        if not isinstance(name, str) or not name:
            raise ValueError(f"{where}: image of {cam!r}: expected a file name, got {name!r}")
        files[str(cam)] = base / name
    pose = pose_from_fields({k: v for k, v in entry.items()
                             if k in ("translation", "quaternion", "rvec", "rotation", "matrix")},
                            where)
    stamp = entry.get("stamp")
    if stamp is not None:
        try:
            seconds = float(stamp)
        except (TypeError, ValueError):
            seconds = float("nan")
        if not np.isfinite(seconds) or seconds < 0:
            raise ValueError(f"{where}.stamp: expected seconds >= 0, got {stamp!r}")
        stamp = int(round(seconds * _NS_PER_S))
    label = str(entry.get("name") or f"view {i}")
    shown = ", ".join(str(p.relative_to(base)) if p.is_relative_to(base) else str(p)
                      for p in files.values())
    return SampleView(f"{label} ({shown})", files, pose, stamp)


def read_manifest(path: str | Path) -> SampleSet:
    """Read a samples manifest (module docstring).

    Raises
    ------
    ValueError
        Naming the file and the entry: unknown keys, a missing ``pose`` frame or ``views``, a
        bad pose (:func:`~rwhec_ros.data.pose_fields.pose_from_fields`), a camera of a view not
        in ``cameras``, an unreadable intrinsics file. Image files are checked when read.
    """
    path = Path(path)
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not YAML ({exc})") from None
    if not isinstance(doc, Mapping) or "views" not in doc:
        raise ValueError(f"{path}: not a samples manifest (a mapping with pose and views)")
    unknown = sorted(set(doc) - _TOP_KEYS)
    if unknown:
        raise ValueError(f"{path}: unknown keys {unknown}; a manifest has {sorted(_TOP_KEYS)}")
    version = doc.get("samples", MANIFEST_VERSION)
    if version != MANIFEST_VERSION:
        raise ValueError(f"{path}: samples: format version {version!r}, this reader knows "
                         f"{MANIFEST_VERSION}")
    pose = doc.get("pose")
    if not isinstance(pose, Mapping) or "parent" not in pose or "child" not in pose:
        raise ValueError(f"{path}: pose: expected {{parent: FRAME, child: FRAME}} (each view's "
                         f"pose is T_parent_child), got {pose!r}")
    parent = _frame(pose["parent"], _where(path, "pose.parent"))
    child = _frame(pose["child"], _where(path, "pose.child"))
    if parent == child:
        raise ValueError(f"{path}: pose: parent and child are both {parent!r}")
    mount = doc.get("mount")
    if mount is not None and mount not in MOUNTS:
        raise ValueError(f"{path}: mount: expected one of {list(MOUNTS)}, got {mount!r}")
    carrier = doc.get("camera_carrier")
    if carrier is not None and carrier not in (parent, child):
        raise ValueError(f"{path}: camera_carrier: {carrier!r} is neither pose.parent "
                         f"{parent!r} nor pose.child {child!r}")
    base = path.parent
    cams_doc = doc.get("cameras")
    intrinsics: dict[str, IntrinsicsFile | None] = {}
    cameras: tuple[str, ...] | None = None
    if cams_doc is not None:
        if not isinstance(cams_doc, Mapping) or not cams_doc:
            raise ValueError(f"{path}: cameras: expected a mapping name -> {{intrinsics: FILE}}")
        cameras = tuple(str(c) for c in cams_doc)
        for cam, spec in cams_doc.items():
            spec = spec or {}
            if not isinstance(spec, Mapping) or set(spec) - {"intrinsics"}:
                raise ValueError(f"{path}: cameras.{cam}: expected {{intrinsics: FILE}}, got "
                                 f"{spec!r}")
            file = spec.get("intrinsics")
            intrinsics[str(cam)] = None if file is None else read_intrinsics_file(base / file)
    views_doc = doc["views"]
    if not isinstance(views_doc, list) or not views_doc:
        raise ValueError(f"{path}: views: expected a non-empty list")
    views = tuple(_view(i, v, base, cameras, path) for i, v in enumerate(views_doc))
    if cameras is None:
        cameras = tuple(sorted({c for v in views for c in v.images}))
        intrinsics = dict.fromkeys(cameras)
    targets: dict[str, Any] = {}
    for key in ("targets", "tags"):
        if key in doc:
            if not isinstance(doc[key], Mapping):
                raise ValueError(f"{path}: {key}: expected the configuration's {key} section")
            targets.update(flatten_parameters({key: doc[key]}))
    return SampleSet(source=str(path), layout="manifest", pose_parent=parent, pose_child=child,
                     cameras=cameras, views=views, intrinsics=intrinsics, mount=mount,
                     camera_carrier=carrier, target_parameters=targets)


def manifest_document(samples: SampleSet, base: str | Path) -> dict[str, Any]:
    """The manifest of ``samples`` as a mapping, image paths relative to ``base`` where they
    lie under it; poses as translation + quaternion (x, y, z, w). Intrinsics and targets are
    not written (give them in the manifest by hand or with ``--intrinsics``/``--config``)."""
    from ..core.lie import transform_to_quat_xyzw

    base = Path(base)

    def rel(p: Path) -> str:
        return str(p.relative_to(base)) if p.is_relative_to(base) else str(p)

    views = []
    for v in samples.views:
        q, t = transform_to_quat_xyzw(v.T_parent_child)
        entry: dict[str, Any] = (
            {"image": rel(next(iter(v.images.values())))} if len(samples.cameras) == 1
            else {"images": {c: rel(p) for c, p in v.images.items()}})
        entry["translation"] = [float(x) for x in t]
        entry["quaternion"] = [float(x) for x in q]
        if v.stamp_ns is not None:
            entry["stamp"] = v.stamp_ns / _NS_PER_S
        views.append(entry)
    doc: dict[str, Any] = {"samples": MANIFEST_VERSION,
                           "pose": {"parent": samples.pose_parent, "child": samples.pose_child}}
    if samples.mount is not None:
        doc["mount"] = samples.mount
    doc["views"] = views
    return doc


def write_manifest(samples: SampleSet, path: str | Path) -> Path:
    """Write :func:`manifest_document` of ``samples`` to ``path`` (relative image paths)."""
    path = Path(path)
    path.write_text(yaml.safe_dump(manifest_document(samples, path.parent), sort_keys=False),
                    encoding="utf-8")
    return path

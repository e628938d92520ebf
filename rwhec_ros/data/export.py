"""Calibrated frames in the forms a robot description uses: a URDF/xacro snippet and a plain YAML.

Input everywhere: a sequence of ``(parent, child, T_parent_child)`` -- the carrier frame, the
calibrated frame and the 4x4 transform mapping child coordinates to parent coordinates (what
:meth:`rwhec_ros.data.results.FrameNaming.transforms` returns for a result).

* :func:`urdf_snippet` -- a ``<robot>`` element holding, per frame, ``<link name=child/>`` and a
  ``<joint type="fixed">`` with ``<parent link=parent/>``, ``<child link=child/>`` and
  ``<origin xyz=... rpy=...>``. URDF's ``rpy`` are fixed-axis roll, pitch, yaw:
  ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (scipy's extrinsic ``"xyz"`` Euler angles). The file is
  valid xacro: include it from the robot's xacro with
  ``<xacro:include filename="$(find my_robot_description)/urdf/calibration.urdf.xacro"/>``;
  its links and joints then join the robot (the carriers must be links of that robot).
* :func:`frames_yaml` -- per frame ``parent``, ``child``, ``xyz`` [m], ``rpy`` [rad, same
  convention] and ``quaternion_xyzw``, plus optional metadata.
* :func:`urdf_fixed_joints` -- reads the fixed joints of a URDF text back (for checks).

Numbers are written with Python's shortest round-trip ``repr``, so reading them back recovers
each transform to floating-point precision.
"""

from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from ..core.lie import transform_to_quat_xyzw

__all__ = [
    "rpy_from_matrix",
    "matrix_from_rpy",
    "urdf_snippet",
    "frames_yaml",
    "frames_document",
    "urdf_fixed_joints",
]

XACRO_NS = "http://www.ros.org/wiki/xacro"


def rpy_from_matrix(R: np.ndarray) -> np.ndarray:
    """URDF ``(roll, pitch, yaw)`` [rad] of a rotation matrix: ``R = Rz(yaw) Ry(pitch) Rx(roll)``.

    At ``pitch = +-pi/2`` (gimbal lock) scipy sets ``yaw`` to 0 and ``roll`` carries the rest;
    the angles still reproduce ``R``.
    """
    with warnings.catch_warnings():  # scipy warns at gimbal lock; the angles remain valid
        warnings.simplefilter("ignore", UserWarning)
        return Rotation.from_matrix(np.asarray(R, dtype=float)).as_euler("xyz")


def matrix_from_rpy(rpy: Sequence[float]) -> np.ndarray:
    """Rotation matrix (3, 3) of URDF ``(roll, pitch, yaw)``: ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    return Rotation.from_euler("xyz", np.asarray(rpy, dtype=float).reshape(3)).as_matrix()


def _check_frames(frames: Sequence[tuple[str, str, np.ndarray]]) -> list[tuple[str, str,
                                                                               np.ndarray]]:
    out, children = [], {}
    for i, item in enumerate(frames):
        try:
            parent, child, T = item
        except (TypeError, ValueError):
            raise ValueError(f"frames[{i}] must be (parent, child, T_parent_child), "
                             f"got {item!r}") from None
        for field, value in (("parent", parent), ("child", child)):
            if not isinstance(value, str) or not value.strip():
                raise ValueError(f"frames[{i}]: {field} must be a non-empty string, "
                                 f"got {value!r}")
        if parent == child:
            raise ValueError(f"frames[{i}]: parent and child are both {parent!r}")
        if child in children:
            raise ValueError(f"frames[{i}]: child {child!r} already has parent "
                             f"{children[child]!r} (a link has one parent)")
        children[child] = parent
        T = np.asarray(T, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ValueError(f"frames[{i}] ({child}): T must be a finite 4x4 array, "
                             f"got shape {T.shape}")
        R = T[:3, :3]
        if not (np.allclose(R.T @ R, np.eye(3), atol=1e-6) and np.linalg.det(R) > 0
                and np.allclose(T[3], [0.0, 0.0, 0.0, 1.0])):
            raise ValueError(f"frames[{i}] ({child}): T is not a rigid transform "
                             f"(rotation part not orthonormal with det +1, or last row not "
                             f"0 0 0 1)")
        out.append((parent, child, T))
    return out


def _numbers(values: np.ndarray) -> str:
    return " ".join(repr(float(v)) for v in np.asarray(values, dtype=float).reshape(-1))


def urdf_snippet(
    frames: Sequence[tuple[str, str, np.ndarray]],
    *,
    robot_name: str = "rwhec_calibration",
    comment: str = "",
    declare_links: bool = True,
) -> str:
    """URDF/xacro text with one fixed joint per calibrated frame (module docstring).

    Parameters
    ----------
    frames : sequence of (str, str, ndarray (4, 4))
        ``(parent, child, T_parent_child)``; parents are the carrier links, children the
        calibrated frames (each child once).
    robot_name : str
        ``name`` of the ``<robot>`` element (ignored by ``xacro:include``).
    comment : str
        Text of a comment at the top (e.g. the certificate status and the date).
    declare_links : bool
        Also declare each child as an empty ``<link>`` (default; the calibrated frames are new
        links). Set False when the robot description declares them already.

    Returns
    -------
    str
        XML text with declaration, ending in a newline.

    Raises
    ------
    ValueError
        Naming the frame index for an empty name, a child given twice or a non-rigid ``T``.
    """
    checked = _check_frames(frames)
    robot = ET.Element("robot", {"name": str(robot_name), "xmlns:xacro": XACRO_NS})
    robot.append(ET.Comment(
        " Generated by rwhec_ros. Include from a xacro robot description with "
        "<xacro:include filename=\"...this file...\"/>; every parent link must exist there. "
        "origin rpy: fixed-axis roll, pitch, yaw [rad], R = Rz(yaw) Ry(pitch) Rx(roll). "))
    if comment:
        robot.append(ET.Comment(" " + comment.replace("--", "- -") + " "))
    for parent, child, T in checked:
        if declare_links:
            ET.SubElement(robot, "link", {"name": child})
        joint = ET.SubElement(robot, "joint", {"name": f"{child}_joint", "type": "fixed"})
        ET.SubElement(joint, "parent", {"link": parent})
        ET.SubElement(joint, "child", {"link": child})
        ET.SubElement(joint, "origin", {"xyz": _numbers(T[:3, 3]),
                                        "rpy": _numbers(rpy_from_matrix(T[:3, :3]))})
    ET.indent(robot, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"


def frames_document(
    frames: Sequence[tuple[str, str, np.ndarray]],
    *,
    metadata: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The mapping :func:`frames_yaml` writes: ``metadata`` (if any) and ``frames``."""
    doc: dict[str, Any] = {}
    if metadata:
        doc["metadata"] = {str(k): v for k, v in metadata.items()}
    entries = []
    for parent, child, T in _check_frames(frames):
        q, t = transform_to_quat_xyzw(T)
        entries.append({
            "parent": parent,
            "child": child,
            "xyz": [float(v) for v in t],
            "rpy": [float(v) for v in rpy_from_matrix(T[:3, :3])],
            "quaternion_xyzw": [float(v) for v in q],
        })
    doc["frames"] = entries
    return doc


def frames_yaml(
    frames: Sequence[tuple[str, str, np.ndarray]],
    *,
    metadata: Mapping[str, Any] | None = None,
) -> str:
    """Plain YAML of the frames: per frame ``parent``, ``child``, ``xyz`` [m], ``rpy`` [rad,
    URDF convention] and ``quaternion_xyzw``; ``metadata`` (plain values) first if given."""
    head = ("# Calibrated frames (rwhec_ros). T_parent_child: xyz [m]; rpy [rad] fixed-axis "
            "roll, pitch, yaw (R = Rz(yaw) Ry(pitch) Rx(roll)); quaternion (x, y, z, w).\n")
    return head + yaml.safe_dump(frames_document(frames, metadata=metadata), sort_keys=False,
                                 default_flow_style=None)


def urdf_fixed_joints(text: str) -> list[tuple[str, str, np.ndarray]]:
    """``(parent, child, T_parent_child)`` of every fixed joint in a URDF text (document order).

    Raises
    ------
    ValueError
        For text that is not XML, or a fixed joint without parent/child or with a malformed
        origin.
    """
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise ValueError(f"not valid XML: {exc}") from None
    out = []
    for joint in root.iter("joint"):
        if joint.get("type") != "fixed":
            continue
        name = joint.get("name", "?")
        parent, child = joint.find("parent"), joint.find("child")
        if parent is None or child is None or not parent.get("link") or not child.get("link"):
            raise ValueError(f"joint {name!r}: needs <parent link=.../> and <child link=.../>")
        origin = joint.find("origin")
        xyz, rpy = np.zeros(3), np.zeros(3)
        if origin is not None:
            try:
                xyz = np.array([float(v) for v in origin.get("xyz", "0 0 0").split()])
                rpy = np.array([float(v) for v in origin.get("rpy", "0 0 0").split()])
            except ValueError:
                raise ValueError(f"joint {name!r}: origin xyz/rpy must be numbers") from None
            if xyz.shape != (3,) or rpy.shape != (3,):
                raise ValueError(f"joint {name!r}: origin xyz and rpy need 3 numbers each")
        T = np.eye(4)
        T[:3, :3] = matrix_from_rpy(rpy)
        T[:3, 3] = xyz
        out.append((parent.get("link"), child.get("link"), T))
    return out

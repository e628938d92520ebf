"""A reference calibration to check new data against (bring-up, :mod:`rwhec_ros.session.bringup`).

Three sources, one :class:`Reference` (frame name -> ``T_<carrier>_<frame>`` as the solver
estimates it: cameras (Y) in the camera carrier, targets (X) in the tag carrier):

* a previous result (``result.yaml`` of the node or the CLI, or a ``check.yaml`` of an earlier
  check, :func:`reference_from_result`): the frames by name, with each frame's covariance
  (``null`` entries: that axis is unknown): the predicted one times the larger of the squared
  noise ratios of the result's fit (``verdict_details.fit``: the translation and the rotation
  noise the residuals showed against the stated noise); without them the ``a_posteriori`` one
  (one variance factor for both, which understates the translation's when the stated
  translation noise is off by more than the rotation's), else the predicted one. Frames marked
  ``usable: false`` are left out (with a note);
* the frames as a robot description holds them (:func:`reference_from_transforms`): a
  ``frames.yaml`` written by :mod:`rwhec_ros.data.export`, a URDF / xacro file (its fixed joints,
  composed from the carrier down to the frame, :func:`fixed_chain`), or the transforms the node
  looks up on tf (robot_state_publisher from the URDF). Each configured frame is found under its
  published child name (``<frame><output.frame_suffix>``, as this package's outputs name it)
  or under its own sensor frame name; its parent must be the configured carrier. These sources
  carry no covariance: the reference is taken as exact (say so with the answer).

:func:`read_reference` reads a file and picks the reader from its content.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from ..core.lie import transform_from_quat_xyzw
from ..core.problem import check_transforms
from ..errors import describe_os_error, describe_yaml_error
from .export import matrix_from_rpy, urdf_fixed_joints

__all__ = ["Reference", "reference_from_result", "reference_from_transforms", "fixed_chain",
           "read_reference"]


@dataclass
class Reference:
    """A stored calibration.

    Attributes
    ----------
    frames : dict of str to ndarray (4, 4)
        Frame name -> ``T_<carrier>_<frame>``.
    covariance : dict of str to ndarray (6, 6)
        Frame name -> covariance of ``[dt (m), phi (rad)]`` in the carrier (left perturbation,
        :data:`rwhec_ros.core.analysis.uncertainty.CONVENTION`); NaN entries: axis unknown. A
        frame without an entry is taken as exact.
    parents : dict of str to str
        Frame name -> its carrier as the source names it ("" when unknown).
    source : str
        What was read, in words (for the answer).
    notes : list of str
        Frames left out and why.
    """

    frames: dict[str, np.ndarray]
    covariance: dict[str, np.ndarray] = field(default_factory=dict)
    parents: dict[str, str] = field(default_factory=dict)
    source: str = ""
    notes: list[str] = field(default_factory=list)

    @property
    def has_covariance(self) -> bool:
        return bool(self.covariance)


def _matrix(value, where: str) -> np.ndarray:
    try:
        T = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: expected a 4x4 matrix of numbers, got {value!r}") from None
    return check_transforms(T, what=where, rotation_tol=1e-5)[0]


def _covariance(value) -> np.ndarray | None:
    if value is None:
        return None
    try:
        C = np.array([[np.nan if v is None else float(v) for v in row] for row in value])
    except (TypeError, ValueError):
        return None
    return C if C.shape == (6, 6) else None


def _noise_scale(doc: Mapping) -> float | None:
    """The larger squared noise ratio of a result's fit (``verdict_details.fit``), or None."""
    fit = (doc.get("verdict_details") or {}).get("fit") if isinstance(
        doc.get("verdict_details"), Mapping) else None
    if not isinstance(fit, Mapping):
        return None
    try:
        ratios = [float(fit["noise_ratio_translation"]), float(fit["noise_ratio_rotation"])]
    except (KeyError, TypeError, ValueError):
        return None
    if not all(np.isfinite(r) and r > 0 for r in ratios):
        return None
    return max(ratios) ** 2


def reference_from_result(doc: Mapping, where: str = "result", *,
                          a_posteriori: bool = True) -> Reference:
    """The frames of a result mapping (:func:`rwhec_ros.data.results.load_result`'s): ``matrix``
    per frame by ``name``, its ``parent``, and its covariance (module docstring; with
    ``a_posteriori`` False the predicted one as it is). ``ValueError`` naming ``where`` and the
    frame for a malformed entry."""
    scale = _noise_scale(doc) if a_posteriori else None
    frames_in = doc.get("frames")
    if not isinstance(frames_in, list) or not frames_in:
        raise ValueError(f"{where}: no frames (key 'frames' missing or empty)")
    ref = Reference({}, source=f"result {where}")
    for i, f in enumerate(frames_in):
        if not isinstance(f, Mapping) or "name" not in f or "matrix" not in f:
            raise ValueError(f"{where}: frames[{i}]: expected name and matrix, got {f!r}")
        name = str(f["name"])
        if f.get("usable") is False:
            why = "; ".join(f.get("why") or []) or "unusable"
            ref.notes.append(f"{name}: left out of the reference (usable: false in {where}: "
                             f"{why})")
            continue
        ref.frames[name] = _matrix(f["matrix"], f"{where}: frame {name} matrix")
        ref.parents[name] = str(f.get("parent", ""))
        predicted = _covariance(f.get("covariance"))
        post = f.get("a_posteriori") if a_posteriori else None
        C = _covariance(post.get("covariance") if isinstance(post, Mapping) else None)
        if scale is not None and predicted is not None:
            C = scale * predicted
        elif C is None or not np.isfinite(C).any():
            C = predicted
        if C is not None:
            ref.covariance[name] = C
    if not ref.frames:
        raise ValueError(f"{where}: no usable frame in the reference")
    return ref


def fixed_chain(joints: Sequence[tuple[str, str, np.ndarray]], parent: str, child: str
                ) -> np.ndarray | None:
    """``T_parent_child`` composed along the fixed joints ``(parent, child, T_parent_child)``
    from ``parent`` down to ``child`` (a URDF's tree: each link has one parent), or None when
    ``child`` does not hang below ``parent`` through fixed joints alone."""
    up = {c: (p, T) for p, c, T in joints}
    T = np.eye(4)
    link = child
    for _ in range(len(up) + 1):
        if link == parent:
            return T
        if link not in up:
            return None
        p, Tj = up[link]
        T = Tj @ T
        link = p
    return None


def reference_from_transforms(
    transforms: Sequence[tuple[str, str, np.ndarray]],
    frames: Mapping[str, tuple[str, Sequence[str]]],
    where: str,
    *,
    compose: bool = False,
) -> Reference:
    """The frames of ``(parent, child, T_parent_child)`` entries (a frames.yaml, a URDF's fixed
    joints, tf lookups).

    ``frames`` maps each frame name to ``(carrier, child names to look for)`` (e.g. the
    published ``cam0_optical_calibrated`` and the sensor frame ``cam0_optical``); the first
    child name found is used, and its parent must be the carrier (with ``compose``: any chain of
    fixed joints from the carrier down to it). Frames found nowhere are named in the notes;
    ``ValueError`` when none is found.
    """
    ref = Reference({}, source=where)
    direct = {c: (p, np.asarray(T, float)) for p, c, T in transforms}
    for name, (carrier, children) in frames.items():
        found = None
        for child in children:
            if compose:
                T = fixed_chain(transforms, carrier, child)
                if T is not None:
                    found = T
                    break
            elif child in direct:
                p, T = direct[child]
                if p != carrier:
                    ref.notes.append(f"{name}: {child} has parent {p} in {where}, not the "
                                     f"carrier {carrier}: left out")
                    break
                found = T
                break
        if found is None:
            if not any(n.startswith(f"{name}:") for n in ref.notes):
                ref.notes.append(f"{name}: none of {list(children)} under {carrier} in {where}")
            continue
        ref.frames[name] = check_transforms(found, what=f"{where}: {name}",
                                            rotation_tol=1e-5)[0]
        ref.parents[name] = carrier
    if not ref.frames:
        raise ValueError(f"{where}: none of the frames {sorted(frames)} found ("
                         + "; ".join(ref.notes) + ")")
    return ref


def _frames_yaml_entries(doc: Mapping, where: str) -> list[tuple[str, str, np.ndarray]]:
    out = []
    for i, f in enumerate(doc.get("frames") or []):
        if not isinstance(f, Mapping) or "parent" not in f or "child" not in f:
            raise ValueError(f"{where}: frames[{i}]: expected parent, child and xyz, got {f!r}")
        try:
            xyz = np.asarray(f.get("xyz"), float).reshape(3)
            if f.get("quaternion_xyzw") is not None:
                T = transform_from_quat_xyzw(np.asarray(f["quaternion_xyzw"], float), xyz)
            else:
                T = np.eye(4)
                T[:3, :3] = matrix_from_rpy(np.asarray(f.get("rpy"), float).reshape(3))
                T[:3, 3] = xyz
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{where}: frames[{i}] ({f.get('child')}): {exc}") from None
        out.append((str(f["parent"]), str(f["child"]), T))
    return out


def read_reference(path: str | Path, frames: Mapping[str, tuple[str, Sequence[str]]]
                   | None = None) -> Reference:
    """A reference from a file: a result / check YAML (frames with ``matrix``), a frames.yaml
    (frames with ``xyz``) or a URDF / xacro (XML). ``frames`` (see
    :func:`reference_from_transforms`) is needed for the last two. ``ValueError`` naming the
    file for anything unreadable."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ValueError(f"reference {path}: cannot read ({describe_os_error(exc)})") from None
    where = str(path)
    if text.lstrip().startswith("<"):
        if frames is None:
            raise ValueError(f"reference {path}: a URDF needs the configuration's frames")
        return reference_from_transforms(urdf_fixed_joints(text), frames, f"URDF {where}",
                                         compose=True)
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ValueError(describe_yaml_error(path, exc)) from None
    if not isinstance(doc, Mapping) or not isinstance(doc.get("frames"), list):
        raise ValueError(f"reference {path}: expected a result.yaml, check.yaml or frames.yaml "
                         "(a mapping with a 'frames' list) or a URDF")
    entries = doc["frames"]
    if entries and isinstance(entries[0], Mapping) and "matrix" in entries[0]:
        return reference_from_result(doc, where)
    if frames is None:
        raise ValueError(f"reference {path}: a frames.yaml needs the configuration's frames")
    return reference_from_transforms(_frames_yaml_entries(doc, where), frames,
                                     f"frames.yaml {where}")

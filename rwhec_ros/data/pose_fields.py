"""One rigid transform written by a person: the pose forms of the samples manifest and pose lists.

A pose ``T_a_b`` (maps ``b`` coordinates into ``a``; metres) is written as one of

* ``translation: [x, y, z]`` + ``quaternion: [x, y, z, w]`` (scalar LAST, as ROS and scipy);
* ``translation`` + ``rvec: [rx, ry, rz]`` (OpenCV's rotation vector: axis times angle [rad]);
* ``translation`` + ``rotation: [[...], [...], [...]]`` (3 x 3, rows);
* ``matrix: [[...] x 4]`` (4 x 4, rows, last row ``0 0 0 1``).

Quaternions go through :func:`rwhec_ros.messages.quaternion_to_rotation`, the conversion of the
``PoseStamped``/``TransformStamped`` messages of a bag, so the same quaternion gives the same
matrix on both routes. A quaternion whose norm is off by more than
:data:`~rwhec_ros.messages.QUAT_NORM_TOL` and a rotation matrix off orthonormal by more than
:data:`ROTATION_TOL` are refused (not silently fixed): numbers that far off are a wrong column,
not rounding. Errors are ``ValueError`` naming ``where`` (file, view, field).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from types import SimpleNamespace
from typing import Any

import numpy as np

from ..core.lie import make_transform, project_to_so3, so3_exp
from ..messages import quaternion_to_rotation

__all__ = ["POSE_FORMS", "ROTATION_TOL", "pose_from_fields", "pose_from_columns", "check_rigid"]

#: Largest ``max |R^T R - I|`` and ``|det R - 1|`` of a written rotation matrix (six printed
#: digits give about 1e-6; a wrong or transposed matrix is off by O(1)).
ROTATION_TOL = 1e-4

#: The key sets of the accepted forms, for the error message.
POSE_FORMS = ("translation + quaternion [x, y, z, w]", "translation + rvec [rx, ry, rz]",
              "translation + rotation (3 x 3)", "matrix (4 x 4)")


def _numbers(value: Any, shape: tuple[int, ...], where: str) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: expected numbers of shape {shape}, got {value!r}") from None
    if a.shape != shape:
        raise ValueError(f"{where}: expected shape {shape}, got {a.shape}: {value!r}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{where}: non-finite value in {a.tolist()}")
    return a


def check_rigid(T: np.ndarray, where: str, tol: float = ROTATION_TOL) -> np.ndarray:
    """``T`` (4, 4) with its rotation projected onto SO(3) (the nearest rotation, a change of
    at most about ``tol``) if it is a rigid transform within ``tol``, else ``ValueError``."""
    R = T[:3, :3]
    orth = float(np.abs(R.T @ R - np.eye(3)).max())
    det = float(np.linalg.det(R))
    last = float(np.abs(T[3] - [0.0, 0.0, 0.0, 1.0]).max())
    if max(orth, abs(det - 1.0)) > tol or last > 0:
        raise ValueError(f"{where}: not a rigid transform (max |R^T R - I| = {orth:.3g}, det R = "
                         f"{det:.6g}, last row {T[3].tolist()}; tolerance {tol:g})")
    return make_transform(project_to_so3(R), T[:3, 3])


def _rotation_from_quaternion(q: Sequence[float], where: str) -> np.ndarray:
    x, y, z, w = _numbers(q, (4,), where)
    return quaternion_to_rotation(SimpleNamespace(x=x, y=y, z=z, w=w), field=where)


def pose_from_fields(fields: Mapping[str, Any], where: str) -> np.ndarray:
    """The transform (4, 4) of one written pose (module docstring for the forms).

    Raises
    ------
    ValueError
        Naming ``where``: not a mapping, no form or two forms, wrong shapes, non-finite values,
        a quaternion of the wrong norm, a rotation that is not one.
    """
    if not isinstance(fields, Mapping):
        raise ValueError(f"{where}: expected a mapping with one of {list(POSE_FORMS)}, got "
                         f"{fields!r}")
    rotations = [k for k in ("quaternion", "rvec", "rotation") if k in fields]
    if "matrix" in fields:
        extra = sorted(set(fields) & {"translation", "quaternion", "rvec", "rotation"})
        if extra:
            raise ValueError(f"{where}: 'matrix' together with {extra}: give one form of "
                             f"{list(POSE_FORMS)}")
        T = _numbers(fields["matrix"], (4, 4), f"{where}.matrix")
        return check_rigid(T, f"{where}.matrix")
    if "translation" not in fields or len(rotations) != 1:
        found = sorted(k for k in fields if k in ("translation", "quaternion", "rvec",
                                                   "rotation", "matrix"))
        raise ValueError(f"{where}: expected one of {list(POSE_FORMS)}, got the keys {found}")
    t = _numbers(fields["translation"], (3,), f"{where}.translation")
    key = rotations[0]
    if key == "quaternion":  # rotations by construction: used as they are
        return make_transform(_rotation_from_quaternion(fields[key], f"{where}.quaternion"), t)
    if key == "rvec":
        return make_transform(so3_exp(_numbers(fields[key], (3,), f"{where}.rvec")), t)
    R = _numbers(fields[key], (3, 3), f"{where}.rotation")
    return check_rigid(make_transform(R, t), f"{where}.rotation")


def pose_from_columns(row: Mapping[str, str], prefix: str, where: str) -> np.ndarray:
    """The transform (4, 4) named ``prefix`` in one CSV row: ``<prefix>_tx, _ty, _tz`` [m] and
    ``<prefix>_qx, _qy, _qz, _qw`` or ``<prefix>_rvec_x, _rvec_y, _rvec_z`` [rad]."""
    def num(col: str) -> float:
        text = row.get(col)
        if text is None or not str(text).strip():
            raise ValueError(f"{where}: column {col} is empty or missing")
        try:
            return float(text)
        except ValueError:
            raise ValueError(f"{where}: column {col}: not a number: {text!r}") from None

    fields: dict[str, Any] = {"translation": [num(f"{prefix}_t{a}") for a in "xyz"]}
    has_q = any(row.get(f"{prefix}_q{a}") not in (None, "") for a in "xyzw")
    has_r = any(row.get(f"{prefix}_rvec_{a}") not in (None, "") for a in "xyz")
    if has_q == has_r:
        raise ValueError(f"{where}: give {prefix}_qx.._qw or {prefix}_rvec_x.._z "
                         f"(exactly one of the two)")
    if has_q:
        fields["quaternion"] = [num(f"{prefix}_q{a}") for a in "xyzw"]
    else:
        fields["rvec"] = [num(f"{prefix}_rvec_{a}") for a in "xyz"]
    return pose_from_fields(fields, where)

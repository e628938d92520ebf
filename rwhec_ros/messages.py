"""Message conversions: the only module that knows ``*_msgs`` field names.

Everything here is duck-typed on field names, so the same code serves rclpy messages and the
``rosbags`` dataclasses (``rosbags.typesys``, ``Stores.ROS2_JAZZY``), and it imports neither: the
module is usable and tested without ROS. Messages going out are described as plain nested dicts
(field name -> value) that the node copies into its message objects (:func:`fill_message`).

Frames: a ``geometry_msgs/PoseStamped`` with ``header.frame_id = parent`` whose pose is that of a
``child`` body gives ``T_parent_child``; a ``geometry_msgs/TransformStamped`` gives
``T_<header.frame_id>_<child_frame_id>``. Quaternions are ``(x, y, z, w)`` as in the messages.

Quaternion policy (:func:`quaternion_to_rotation`): a non-finite or zero quaternion, or one whose
norm differs from 1 by more than ``quat_norm_tol`` (default ``1e-3``), raises ``ValueError`` naming
the field; a quaternion within the tolerance is normalised (publishers round to float32 or print
few digits, which leaves norms like 0.9999).
"""

from __future__ import annotations

import array
from collections.abc import Mapping, Sequence
from typing import Any

import cv2
import numpy as np

from .core.lie import make_transform, transform_to_quat_xyzw
from .vision.compressed import compressed_to_gray as _compressed_to_gray
from .vision.image import image_to_gray as _raw_image_to_gray
from .vision.intrinsics import DISTORTION_MODELS, CameraIntrinsics

__all__ = [
    "QUAT_NORM_TOL",
    "LEVEL_OK",
    "LEVEL_WARN",
    "LEVEL_ERROR",
    "LEVEL_STALE",
    "stamp_to_ns",
    "ns_to_stamp_fields",
    "quaternion_to_rotation",
    "pose_stamped_to_transform",
    "transform_stamped_to_transform",
    "camera_info_to_intrinsics",
    "image_to_gray",
    "compressed_image_to_gray",
    "transform_to_transform_stamped_fields",
    "transform_to_pose_stamped_fields",
    "gray_to_image_fields",
    "bgr_to_image_fields",
    "gray_to_compressed_image_fields",
    "intrinsics_to_camera_info_fields",
    "diagnostic_rows",
    "fill_message",
]

#: Default largest ``| |q| - 1 |`` that is silently normalised.
QUAT_NORM_TOL = 1e-3

#: ``diagnostic_msgs/DiagnosticStatus`` levels as integers; the node converts them to the
#: one-byte ``bytes`` that the Jazzy message field (an ``octet``) requires: ``bytes([level])``.
LEVEL_OK, LEVEL_WARN, LEVEL_ERROR, LEVEL_STALE = 0, 1, 2, 3
#: Diagnostic level of each verdict level.
_VERDICT_LEVELS = {"good": LEVEL_OK, "caution": LEVEL_WARN, "unusable": LEVEL_ERROR}

_NS = 1_000_000_000


def stamp_to_ns(stamp: Any) -> int:
    """Integer nanoseconds of a ``builtin_interfaces/Time`` (fields ``sec``, ``nanosec``).

    Raises ``ValueError`` for a negative ``nanosec`` or one of a second or more.
    """
    sec = int(stamp.sec)
    nanosec = int(stamp.nanosec)
    if not 0 <= nanosec < _NS:
        raise ValueError(f"header.stamp.nanosec: must be in [0, 1e9), got {nanosec}")
    return sec * _NS + nanosec


def ns_to_stamp_fields(stamp_ns: int) -> dict[str, int]:
    """``{"sec", "nanosec"}`` of integer nanoseconds (floor division, also for negatives)."""
    stamp_ns = int(stamp_ns)
    return {"sec": stamp_ns // _NS, "nanosec": stamp_ns % _NS}


def quaternion_to_rotation(
    q: Any, *, field: str, quat_norm_tol: float = QUAT_NORM_TOL
) -> np.ndarray:
    """Rotation matrix (3, 3) of a message quaternion (fields ``x, y, z, w``).

    Parameters
    ----------
    q : geometry_msgs/Quaternion-like
    field : str
        Dotted field name used in error messages (e.g. ``"pose.orientation"``).
    quat_norm_tol : float
        Largest accepted ``| |q| - 1 |``; accepted quaternions are normalised.

    Raises
    ------
    ValueError
        Non-finite component, zero quaternion, or norm off by more than ``quat_norm_tol``.
    """
    v = np.array([q.x, q.y, q.z, q.w], dtype=float)
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{field}: non-finite quaternion (x, y, z, w) = {v.tolist()}")
    norm = float(np.linalg.norm(v))
    if norm == 0.0:
        raise ValueError(f"{field}: zero quaternion (x, y, z, w) = {v.tolist()}")
    if abs(norm - 1.0) > quat_norm_tol:
        raise ValueError(
            f"{field}: quaternion norm {norm:.6g} differs from 1 by more than {quat_norm_tol:g} "
            f"(x, y, z, w) = {v.tolist()}"
        )
    x, y, z, w = v / norm
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _vector(v: Any, *, field: str) -> np.ndarray:
    out = np.array([v.x, v.y, v.z], dtype=float)
    if not np.all(np.isfinite(out)):
        raise ValueError(f"{field}: non-finite value (x, y, z) = {out.tolist()}")
    return out


def pose_stamped_to_transform(
    msg: Any, *, quat_norm_tol: float = QUAT_NORM_TOL
) -> tuple[int, str, np.ndarray]:
    """``(stamp_ns, header.frame_id, T_parent_child (4, 4))`` of a ``geometry_msgs/PoseStamped``.

    ``header.frame_id`` is the parent frame; the pose is the child body's pose in it. Raises
    ``ValueError`` naming the field (``pose.position``, ``pose.orientation``,
    ``header.stamp.nanosec``); see the module docstring for the quaternion policy.
    """
    stamp_ns = stamp_to_ns(msg.header.stamp)
    R = quaternion_to_rotation(
        msg.pose.orientation, field="pose.orientation", quat_norm_tol=quat_norm_tol
    )
    t = _vector(msg.pose.position, field="pose.position")
    return stamp_ns, str(msg.header.frame_id), make_transform(R, t)


def transform_stamped_to_transform(
    msg: Any, *, quat_norm_tol: float = QUAT_NORM_TOL
) -> tuple[int, str, str, np.ndarray]:
    """``(stamp_ns, parent, child, T_parent_child)`` of a ``geometry_msgs/TransformStamped``.

    ``parent = header.frame_id``, ``child = child_frame_id`` (tf2's convention: the transform
    maps child coordinates to parent coordinates).
    """
    stamp_ns = stamp_to_ns(msg.header.stamp)
    R = quaternion_to_rotation(
        msg.transform.rotation, field="transform.rotation", quat_norm_tol=quat_norm_tol
    )
    t = _vector(msg.transform.translation, field="transform.translation")
    return stamp_ns, str(msg.header.frame_id), str(msg.child_frame_id), make_transform(R, t)


def camera_info_to_intrinsics(msg: Any) -> CameraIntrinsics:
    """:class:`CameraIntrinsics` of a ``sensor_msgs/CameraInfo`` (``width, height, k, d,
    distortion_model``); raises ``ValueError`` for an invalid one (e.g. an all-zero ``k`` of an
    uncalibrated driver)."""
    return CameraIntrinsics.from_camera_info(msg)


def compressed_image_to_gray(msg: Any) -> np.ndarray:
    """(height, width) uint8 grayscale of a ``sensor_msgs/CompressedImage`` (JPEG, PNG, ...).

    Raises ``ValueError`` for empty, undecodable or truncated data or an unsupported format
    (see :func:`rwhec_ros.vision.compressed.compressed_to_gray`).
    """
    return _compressed_to_gray(msg.data, str(msg.format))


def image_to_gray(msg: Any) -> np.ndarray:
    """(height, width) uint8 grayscale of a ``sensor_msgs/Image``.

    Raises ``ValueError`` for an unsupported ``encoding`` or a buffer shorter than
    ``step * height`` (see :func:`rwhec_ros.vision.image.image_to_gray`).
    """
    return _raw_image_to_gray(
        msg.data,
        int(msg.width),
        int(msg.height),
        str(msg.encoding),
        int(msg.step),
        int(msg.is_bigendian),
    )


# --------------------------------------------------------------------------------------------
# outgoing messages as field dicts


def _header(stamp_ns: int, frame_id: str) -> dict[str, Any]:
    return {"stamp": ns_to_stamp_fields(stamp_ns), "frame_id": str(frame_id)}


def transform_to_transform_stamped_fields(
    T: np.ndarray, parent: str, child: str, stamp_ns: int
) -> dict[str, Any]:
    """Fields of a ``geometry_msgs/TransformStamped`` carrying ``T_parent_child`` (4, 4)."""
    q, t = transform_to_quat_xyzw(np.asarray(T, dtype=float))
    return {
        "header": _header(stamp_ns, parent),
        "child_frame_id": str(child),
        "transform": {
            "translation": {"x": float(t[0]), "y": float(t[1]), "z": float(t[2])},
            "rotation": {"x": float(q[0]), "y": float(q[1]), "z": float(q[2]),
                         "w": float(q[3])},
        },
    }


def transform_to_pose_stamped_fields(
    T_parent_child: np.ndarray, parent: str, stamp_ns: int
) -> dict[str, Any]:
    """Fields of a ``geometry_msgs/PoseStamped``: the pose ``T_parent_child`` in ``parent``."""
    q, t = transform_to_quat_xyzw(np.asarray(T_parent_child, dtype=float))
    return {
        "header": _header(stamp_ns, parent),
        "pose": {
            "position": {"x": float(t[0]), "y": float(t[1]), "z": float(t[2])},
            "orientation": {"x": float(q[0]), "y": float(q[1]), "z": float(q[2]),
                            "w": float(q[3])},
        },
    }


def gray_to_image_fields(gray: np.ndarray, stamp_ns: int, frame_id: str) -> dict[str, Any]:
    """Fields of a ``mono8`` ``sensor_msgs/Image`` of a (H, W) uint8 array (``data`` as bytes)."""
    g = np.ascontiguousarray(gray)
    if g.ndim != 2 or g.dtype != np.uint8:
        raise ValueError(f"gray: expected a (H, W) uint8 array, got {g.dtype} {g.shape}")
    return _raw_image_fields(g, "mono8", stamp_ns, frame_id)


def bgr_to_image_fields(bgr: np.ndarray, stamp_ns: int, frame_id: str) -> dict[str, Any]:
    """Fields of a ``bgr8`` ``sensor_msgs/Image`` of a (H, W, 3) uint8 array (e.g.
    :func:`rwhec_ros.vision.annotate.annotate_detections`)."""
    b = np.ascontiguousarray(bgr)
    if b.ndim != 3 or b.shape[2] != 3 or b.dtype != np.uint8:
        raise ValueError(f"bgr: expected a (H, W, 3) uint8 array, got {b.dtype} {b.shape}")
    return _raw_image_fields(b, "bgr8", stamp_ns, frame_id)


def _raw_image_fields(a: np.ndarray, encoding: str, stamp_ns: int, frame_id: str
                      ) -> dict[str, Any]:
    return {
        "header": _header(stamp_ns, frame_id),
        "height": int(a.shape[0]),
        "width": int(a.shape[1]),
        "encoding": encoding,
        "is_bigendian": 0,
        "step": int(a.shape[1] * (a.shape[2] if a.ndim == 3 else 1)),
        "data": a.tobytes(),
    }


def gray_to_compressed_image_fields(
    gray: np.ndarray, stamp_ns: int, frame_id: str, *, codec: str = "jpeg", quality: int = 95
) -> dict[str, Any]:
    """Fields of a ``sensor_msgs/CompressedImage`` of a (H, W) uint8 array, as
    ``image_transport``'s ``compressed`` plugin publishes a ``mono8`` image: ``format``
    ``"mono8; jpeg compressed mono8"`` (``codec="jpeg"``, ``quality`` 1-100, the plugin's
    default 95) or ``"mono8; png compressed "`` (``codec="png"``; ``quality`` unused)."""
    g = np.ascontiguousarray(gray)
    if g.ndim != 2 or g.dtype != np.uint8:
        raise ValueError(f"gray: expected a (H, W) uint8 array, got {g.dtype} {g.shape}")
    if codec == "jpeg":
        if isinstance(quality, bool) or not isinstance(quality, int) or not 1 <= quality <= 100:
            raise ValueError(f"quality: expected an integer in [1, 100], got {quality!r}")
        ok, buf = cv2.imencode(".jpg", g, [cv2.IMWRITE_JPEG_QUALITY, quality])
        fmt = "mono8; jpeg compressed mono8"
    elif codec == "png":
        ok, buf = cv2.imencode(".png", g)
        fmt = "mono8; png compressed "
    else:
        raise ValueError(f"codec: expected 'jpeg' or 'png', got {codec!r}")
    if not ok:  # pragma: no cover - OpenCV encodes every uint8 image
        raise ValueError(f"gray: OpenCV could not encode it as {codec}")
    return {"header": _header(stamp_ns, frame_id), "format": fmt, "data": buf.tobytes()}


def intrinsics_to_camera_info_fields(
    intrinsics: CameraIntrinsics, stamp_ns: int, frame_id: str
) -> dict[str, Any]:
    """Fields of a ``sensor_msgs/CameraInfo`` (``r`` identity, ``p = [K | 0]``; no distortion is
    written as the model's full number of zero coefficients)."""
    K = np.asarray(intrinsics.K, dtype=float)
    D = np.asarray(intrinsics.D, dtype=float)
    if D.size == 0:
        D = np.zeros(DISTORTION_MODELS[intrinsics.model])
    P = np.zeros((3, 4))
    P[:, :3] = K
    return {
        "header": _header(stamp_ns, frame_id),
        "height": int(intrinsics.height),
        "width": int(intrinsics.width),
        "distortion_model": str(intrinsics.model),
        "d": [float(x) for x in D],
        "k": [float(x) for x in K.reshape(-1)],
        "r": [float(x) for x in np.eye(3).reshape(-1)],
        "p": [float(x) for x in P.reshape(-1)],
    }


def diagnostic_rows(
    edges: Sequence[Mapping[str, Any]],
    counters: Mapping[str, int],
    *,
    identifiable: bool | None = None,
    verdict: str = "",
    prefix: str = "rwhec_calibrator",
    hardware_id: str = "",
    calibration: tuple[str, str] | None = None,
    accuracy: Sequence[tuple[str, str]] = (),
) -> list[dict[str, Any]]:
    """``diagnostic_msgs/DiagnosticStatus`` rows from the session's diagnostics.

    Parameters
    ----------
    edges : sequence of mapping
        :meth:`rwhec_ros.session.CalibrationSession.diagnostics` (per edge: ``x``, ``y``,
        ``pairs``, ``status``, ``identifiable`` (bool or None), ``reasons``).
    counters : mapping of str to int
        :meth:`~rwhec_ros.session.CalibrationSession.counters`.
    identifiable, verdict : bool or None, str
        Whole-problem verdict of the identifiability report (``IdentifiabilityReport
        .identifiable`` / ``.verdict``); an edge that is not identifiable on its own may still be
        fixed through its component (paper Theorems 1 and 3). None: judge by the edges alone.
    calibration : (str, str), optional
        ``(level, headline)`` of the latest calibration's verdict
        (:class:`~rwhec_ros.core.verdict.Verdict`: ``good``, ``caution`` or ``unusable`` and its
        first line): the session row is then at least OK, WARN or ERROR respectively, and its
        message starts with ``last calibration: <headline>``.
    accuracy : sequence of (str, str)
        The latest calibration's accuracy as ``(key, value)`` pairs
        (:meth:`rwhec_ros.session.accuracy.Accuracy.diagnostic_values`: ``std <frame>``,
        ``largest_std``, ``worst_held_out_edge``, ``next_motion``), added to the session row;
        its ``next_motion`` also ends the row's message.

    Returns
    -------
    list of dict
        ``name``, ``level`` (int, one of the ``LEVEL_*``), ``message``, ``hardware_id`` and
        ``values`` (list of ``(key, value)`` string pairs). The first row summarises the session
        (ERROR with no pairs at all, WARN while the problem (or, without a verdict, an edge) is
        not identifiable), then one row per edge (WARN when not identifiable on its own).
    """
    rows = []
    n_pairs = int(sum(int(e.get("pairs", 0)) for e in edges))
    n_ok = sum(1 for e in edges if e.get("identifiable") is True)
    ok = (n_ok == len(edges)) if identifiable is None else bool(identifiable)
    summary = f"{n_ok}/{len(edges)} edges identifiable on their own, {n_pairs} pairs"
    if n_pairs == 0:
        level, message = LEVEL_ERROR, "no measurement pairs yet"
    else:
        level = LEVEL_OK if ok else LEVEL_WARN
        # the verdict already counts the edges identifiable on their own: only the pairs added
        message = f"{verdict}; {n_pairs} pairs" if verdict else summary
    values = [(str(k), str(v)) for k, v in sorted(counters.items())]
    if verdict:
        values.insert(0, ("identifiability", verdict))
    if calibration is not None:
        cal_level, headline = calibration
        level = max(level, _VERDICT_LEVELS.get(cal_level, LEVEL_WARN))
        message = f"last calibration: {headline}; {message}"
        values.insert(0, ("last_calibration", headline))
        values.insert(0, ("verdict", cal_level))
    accuracy = [(str(k), str(v)) for k, v in accuracy]
    values += accuracy
    motion = dict(accuracy).get("next_motion")
    if motion:
        message += f"; next motion: {motion}"
    rows.append(
        {
            "name": f"{prefix}: session",
            "level": level,
            "message": message,
            "hardware_id": hardware_id,
            "values": values,
        }
    )
    for e in edges:
        ident = e.get("identifiable")
        lvl = LEVEL_OK if ident is True else LEVEL_WARN
        reasons = list(e.get("reasons", ()))
        msg = f"{e.get('status', '')}: {e.get('pairs', 0)} pairs"
        if reasons:
            msg += " (" + "; ".join(str(r) for r in reasons) + ")"
        values = [(str(k), str(v)) for k, v in e.items() if k != "reasons"]
        values.append(("reasons", "; ".join(str(r) for r in reasons)))
        rows.append(
            {
                "name": f"{prefix}: edge ({e.get('x')}, {e.get('y')})",
                "level": lvl,
                "message": msg,
                "hardware_id": hardware_id,
                "values": values,
            }
        )
    return rows


def fill_message(msg: Any, fields: Mapping[str, Any]) -> Any:
    """Copy a field dict into a message object in place (nested dicts recurse) and return it.

    ``bytes`` values become ``array.array('B')`` (accepted by rclpy's ``uint8[]`` setters without
    a per-element check); lists of floats stay lists. Works for any object with settable
    attributes, e.g. rclpy messages.
    """
    for key, value in fields.items():
        if isinstance(value, Mapping):
            fill_message(getattr(msg, key), value)
        elif isinstance(value, (bytes, bytearray)):
            setattr(msg, key, array.array("B", value))
        else:
            setattr(msg, key, value)
    return msg

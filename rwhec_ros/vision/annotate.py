"""What the calibrator sees: a camera image with every detected tag and board drawn on it.

:func:`annotate_detections` draws, on a BGR copy of the grayscale image, each marker found
(:attr:`TargetDetectionResult.markers <rwhec_ros.vision.targets.TargetDetectionResult>`; a
chessboard or circle grid: the outline of its grid points) outlined, and one label per target with
its name and marker id(s) (``grid`` for a chessboard or circle grid):

* **green** (:data:`KEPT`): the target's pose became a pair of the calibration; the corners used
  by the pose are marked with small circles;
* **orange** (:data:`REJECTED`): anything else, with the reason: the detector's rejection
  (``ambiguous_pose``, ``too_few_corners``, ``reprojection_error``, ...), ``not_in_configuration``
  for a marker of no target, ``no_motion`` when the motion gate left it unexamined, ``no_new_pair``
  when its pose was fine but the keyframe test kept no new pair (too little motion since the
  last pair of that edge).

The node publishes the result on ``~/detections`` (:mod:`rwhec_ros.ros.node`); this module is
ROS-free and only uses OpenCV's drawing functions.
"""

from __future__ import annotations

from collections.abc import Collection

import cv2
import numpy as np

from .targets import TargetDetectionResult

__all__ = ["annotate_detections", "target_statuses", "KEPT", "REJECTED"]

#: BGR colour of a target kept as a pair.
KEPT = (0, 255, 0)
#: BGR colour of a rejected target or marker (orange).
REJECTED = (0, 165, 255)


def target_statuses(detection: TargetDetectionResult,
                    kept: Collection[str]) -> dict[str, tuple[bool, str]]:
    """Per target found in the image (``""``: markers of no target): ``(kept, reason)``, the
    reason ``""`` for a kept target, else the first rejection of that target (a whole-target
    rejection before a single marker's), ``no_motion`` or ``no_new_pair`` (module docstring)."""
    kept = set(kept)
    observed = {o.name for o in detection.observations}
    names = list(dict.fromkeys([*detection.markers, *observed]))
    out: dict[str, tuple[bool, str]] = {}
    for name in names:
        if name == "":
            out[name] = (False, "not_in_configuration")
        elif name in kept:
            out[name] = (True, "")
        elif name in detection.skipped:
            out[name] = (False, "no_motion")
        elif name in observed:
            out[name] = (False, "no_new_pair")
        else:
            own = [r for r in detection.rejections if r.name == name]
            own.sort(key=lambda r: r.marker_id != -1)  # whole-target reasons first
            out[name] = (False, own[0].reason if own else "rejected")
    return out


def _label(canvas: np.ndarray, text: str, anchor: np.ndarray, colour, scale: float,
           thickness: int) -> None:
    """``text`` above ``anchor`` (x, y) on a black box, kept inside the image."""
    font = cv2.FONT_HERSHEY_SIMPLEX
    (w, h), base = cv2.getTextSize(text, font, scale, thickness)
    H, W = canvas.shape[:2]
    x = int(np.clip(anchor[0], 0, max(0, W - w - 2)))
    y = int(np.clip(anchor[1] - 4 - base, h + 2, H - base - 2))  # the box ends above anchor
    cv2.rectangle(canvas, (x - 1, y - h - 2), (x + w + 1, y + base), (0, 0, 0), cv2.FILLED)
    cv2.putText(canvas, text, (x, y), font, scale, colour, thickness, cv2.LINE_AA)


def annotate_detections(
    gray: np.ndarray,
    detection: TargetDetectionResult,
    kept: Collection[str] = (),
    *,
    title: str = "",
) -> np.ndarray:
    """A BGR copy of ``gray`` with the detections drawn (module docstring).

    Parameters
    ----------
    gray : ndarray, shape (H, W), uint8
        The image the detector searched.
    detection : TargetDetectionResult
        What it found (:meth:`TargetDetector.detect
        <rwhec_ros.vision.target_detector.TargetDetector.detect>`).
    kept : collection of str
        Targets whose pair was kept (:attr:`ImageOutcome.kept
        <rwhec_ros.session.outcomes.ImageOutcome>`).
    title : str
        Written in the top-left corner (e.g. the camera name), if not empty.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
        BGR image (``bgr8``); ``gray`` is not modified.
    """
    img = np.asarray(gray)
    if img.ndim != 2 or img.dtype != np.uint8:
        raise ValueError(f"gray: expected a (H, W) uint8 array, got {img.dtype} {img.shape}")
    canvas = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    size = min(img.shape)
    thickness = max(1, int(round(size / 400)))
    scale = max(0.35, size / 1200)
    statuses = target_statuses(detection, kept)
    by_name = {o.name: o for o in detection.observations}
    labels = []
    for name, (ok, reason) in statuses.items():
        colour = KEPT if ok else REJECTED
        markers = detection.markers.get(name, [])
        for marker_id, quad in markers:
            pts = np.round(np.asarray(quad, dtype=float).reshape(-1, 1, 2)).astype(np.int32)
            cv2.polylines(canvas, [pts], True, colour, thickness, cv2.LINE_AA)
            if name == "":  # markers of no target: one label each
                labels.append((f"id {marker_id}: {reason}", pts.reshape(-1, 2), colour))
        obs = by_name.get(name)
        if ok and obs is not None:
            for p in np.round(obs.image_points).astype(int):
                cv2.circle(canvas, (int(p[0]), int(p[1])), thickness + 1, colour, thickness)
        if name == "" or not markers:
            continue
        ids = sorted(m for m, _ in markers if m >= 0)
        id_text = ("grid" if not ids else f"id {ids[0]}" if len(ids) == 1
                   else f"{len(ids)} markers")
        text = f"{name} ({id_text})" + ("" if ok else f": {reason}")
        labels.append((text, np.concatenate([np.reshape(q, (-1, 2)) for _, q in markers]),
                       colour))
    for text, pts, colour in labels:
        top_left = np.array([pts[:, 0].min(), pts[:, 1].min()])
        _label(canvas, text, top_left, colour, scale, thickness)
    if title:
        _label(canvas, title, np.array([2.0, 0.0]), (255, 255, 255), scale, thickness)
    return canvas

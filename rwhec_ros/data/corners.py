"""What a data set keeps for the reprojection error per camera: corners, intrinsics, tag sizes.

A data set (:class:`rwhec_ros.data.dataset.Dataset`) written by the session keeps, besides the
pairs, each pair's detected corners (``DatasetEdge.corners_px``: a tag's four; a board's, with
their board-frame points ``DatasetEdge.corner_points_m``), the cameras' intrinsics and the tag
sizes, so that the calibration can be checked in pixels
(:func:`rwhec_ros.vision.reprojection.reprojection_errors`). All three are optional: data sets
written before they were kept, or from the paper's CSV files, have none and still load.

File keys (in the data set's YAML; the corners go into the ``.npz`` with the other arrays when
the data set is large)::

    intrinsics:
      cam_0: {width: 640, height: 480, model: plumb_bob,
              K: [fx, 0, cx, 0, fy, cy, 0, 0, 1], D: [k1, k2, p1, p2, k3]}
    tag_sizes_m: {tag_0: 0.16}
    edges:
    - x: tag_0
      y: cam_0
      ...
      corners_px:          # per pair 4 corners (u, v) [px], order TAG_CORNERS_UNIT; .nan: none
      - [[u0, v0], [u1, v1], [u2, v2], [u3, v3]]
    - x: board_0           # a board: the corners seen, padded with .nan to the most of any pair
      y: cam_0
      ...
      corners_px:
      - [[u0, v0], ..., [uK, vK], [.nan, .nan], ...]
      corner_points_m:     # the same corners in the board frame [m]; .nan where corners_px is
      - [[x0, y0, 0.0], ..., [xK, yK, 0.0], [.nan, .nan, .nan], ...]
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..vision.intrinsics import CameraIntrinsics
from ..vision.reprojection import CornerObservation

__all__ = ["intrinsics_to_dict", "intrinsics_from_dict", "check_tag_sizes", "pairs_at_pose",
           "corner_observations", "corner_data"]


def intrinsics_to_dict(intrinsics: CameraIntrinsics) -> dict[str, Any]:
    """``{width, height, model, K (9, row-major), D}`` as plain Python."""
    return {"width": int(intrinsics.width), "height": int(intrinsics.height),
            "model": str(intrinsics.model),
            "K": [float(v) for v in np.asarray(intrinsics.K).reshape(-1)],
            "D": [float(v) for v in np.asarray(intrinsics.D).reshape(-1)]}


def intrinsics_from_dict(value: Any, where: str) -> CameraIntrinsics:
    """The inverse of :func:`intrinsics_to_dict`; ``ValueError`` naming ``where`` and the key."""
    if isinstance(value, CameraIntrinsics):
        return value
    if not isinstance(value, Mapping):
        raise ValueError(f"{where}: expected a mapping with width, height, K, D, got {value!r}")
    missing = [k for k in ("width", "height", "K") if k not in value]
    if missing:
        raise ValueError(f"{where}: missing key {missing[0]!r}")
    try:
        return CameraIntrinsics(width=value["width"], height=value["height"],
                                K=np.asarray(value["K"], dtype=float),
                                D=np.asarray(value.get("D") or [], dtype=float),
                                model=str(value.get("model", "plumb_bob")))
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{where}: {exc}") from None


def check_tag_sizes(sizes: Any, x_names) -> dict[str, float]:
    """Tag frame -> edge length [m] (finite, > 0, a tag of the data set)."""
    if not isinstance(sizes, Mapping):
        raise ValueError(f"tag_sizes_m: expected a mapping tag -> size, got {sizes!r}")
    out = {}
    for tag, size in sizes.items():
        if tag not in x_names:
            raise ValueError(f"tag_sizes_m: {tag!r} is not a tag (X frame) of the data set")
        if isinstance(size, bool) or not isinstance(size, (int, float, np.floating)) or not (
                np.isfinite(size) and size > 0):
            raise ValueError(f"tag_sizes_m[{tag!r}]: must be finite and > 0, got {size!r}")
        out[str(tag)] = float(size)
    return out


def pairs_at_pose(A_pairs: np.ndarray, A: np.ndarray) -> np.ndarray:
    """Indices of the pairs among ``A_pairs`` (n, 4, 4) whose ``A`` is ``A`` (to 1e-9): how a
    corner observation finds its pair (it keeps the pair's ``A``, not its index)."""
    return np.flatnonzero(np.abs(np.asarray(A_pairs) - np.asarray(A)).max(axis=(1, 2)) <= 1e-9)


def corner_observations(dataset) -> list[CornerObservation]:
    """One :class:`~rwhec_ros.vision.reprojection.CornerObservation` per pair of ``dataset``
    that has corners and whose camera has intrinsics: a tag's pair when the tag has a size, a
    board's with its board-frame points (the corners seen); empty when the data set keeps no
    corners."""
    out = []
    for e in dataset.edges:
        if e.corners_px is None or e.y not in dataset.intrinsics:
            continue
        if e.corner_points_m is not None:
            for A, c, p in zip(e.A, e.corners_px, e.corner_points_m, strict=True):
                seen = np.isfinite(c).all(axis=1)
                if seen.any():
                    out.append(CornerObservation(e.x, e.y, A, c[seen], object_points=p[seen]))
            continue
        size = dataset.tag_sizes_m.get(e.x)
        if size is None:
            continue
        for A, c in zip(e.A, e.corners_px, strict=True):
            if np.isfinite(c).all():
                out.append(CornerObservation(e.x, e.y, A, c, size))
    return out


def corner_data(dataset) -> tuple[list[CornerObservation], dict[str, CameraIntrinsics]] | None:
    """``(observations, intrinsics)`` of ``dataset`` for the reprojection error
    (:func:`corner_observations`), or None when it has none (or ``dataset`` is None)."""
    if dataset is None:
        return None
    obs = corner_observations(dataset)
    return (obs, dict(dataset.intrinsics)) if obs else None

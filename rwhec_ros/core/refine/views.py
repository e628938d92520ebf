"""The corner data of the refinement: every kept corner of every target view as flat arrays.

A *view* is one target seen in one image: the pair's pose-stream transform ``A``
(``T_<camera carrier>_<tag carrier>`` at the image stamp), the camera (a Y frame), the target (an
X frame), its detected corners in distorted pixels and the same corners in the target frame
(nominal metres: for an unknown scale the true points are these over ``alpha``). The views come
from any objects with the attributes ``x``, ``y``, ``A``, ``corners_px`` and a method
``target_points(alpha)`` (:class:`rwhec_ros.vision.reprojection.CornerObservation` has them), so
the core needs nothing of the vision package.

Views whose ``A`` are the same matrix (bit for bit) come from the same pose-stream sample --
several targets in one image, several cameras at one stamp, several images at one rest pose of
a stop-and-go capture -- and share its error: they form one *pose group*, the unit of the pose
noise in :mod:`.model`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["CornerViews", "corner_views"]


@dataclass(frozen=True)
class CornerViews:
    """The views of :func:`corner_views` (module docstring); ``V`` views, ``N`` corners, ``G``
    pose groups.

    Attributes
    ----------
    x_names, y_names : tuple of str
        The frames of the estimate (X: targets, Y: cameras), in its order.
    view_x, view_y, view_group : ndarray of int, shape (V,)
        Index of each view's target in ``x_names``, camera in ``y_names``, pose group.
    A : ndarray, shape (V, 4, 4)
        Each view's pose-stream transform.
    start : ndarray of int, shape (V + 1,)
        The corners of view ``v`` are ``start[v]:start[v + 1]`` of the corner arrays.
    points : ndarray, shape (N, 3)
        Corners in the target frame, nominal [m] (``target_points(1.0)``).
    pixels : ndarray, shape (N, 2)
        Detected corners [px], distorted.
    """

    x_names: tuple[str, ...]
    y_names: tuple[str, ...]
    view_x: np.ndarray
    view_y: np.ndarray
    view_group: np.ndarray
    A: np.ndarray
    start: np.ndarray
    points: np.ndarray
    pixels: np.ndarray

    @property
    def n_views(self) -> int:
        return int(self.view_x.size)

    @property
    def n_corners(self) -> int:
        return int(self.points.shape[0])

    @property
    def n_groups(self) -> int:
        return int(self.view_group.max()) + 1 if self.view_group.size else 0

    @property
    def corner_view(self) -> np.ndarray:
        """Index of each corner's view, shape (N,)."""
        return np.repeat(np.arange(self.n_views), np.diff(self.start))

    def subset(self, keep: np.ndarray) -> CornerViews:
        """The views where ``keep`` (V,) is True, pose groups renumbered in order."""
        keep = np.asarray(keep, bool)
        counts = np.diff(self.start)
        corner_keep = np.repeat(keep, counts)
        _, groups = np.unique(self.view_group[keep], return_inverse=True)
        return CornerViews(
            x_names=self.x_names, y_names=self.y_names, view_x=self.view_x[keep],
            view_y=self.view_y[keep], view_group=groups.astype(np.intp).reshape(-1),
            A=self.A[keep], start=np.concatenate([[0], np.cumsum(counts[keep])]).astype(np.intp),
            points=self.points[corner_keep], pixels=self.pixels[corner_keep])

    def frames_seen(self) -> set[str]:
        """The frames that have at least one view."""
        return ({self.x_names[i] for i in np.unique(self.view_x)}
                | {self.y_names[i] for i in np.unique(self.view_y)})


def corner_views(observations: Sequence, x_names: Sequence[str], y_names: Sequence[str]
                 ) -> CornerViews:
    """Flatten ``observations`` (module docstring) whose frames are among ``x_names`` (targets)
    and ``y_names`` (cameras); others are left out. Views are kept in the order given.

    Raises
    ------
    ValueError
        Naming the observation, for corners and target points of different lengths, non-finite
        values or fewer than 3 corners.
    """
    x_names, y_names = tuple(x_names), tuple(y_names)
    xi = {n: i for i, n in enumerate(x_names)}
    yi = {n: i for i, n in enumerate(y_names)}
    vx, vy, As, pts, pix, counts, keys = [], [], [], [], [], [], []
    for i, ob in enumerate(observations):
        if ob.x not in xi or ob.y not in yi:
            continue
        c = np.asarray(ob.corners_px, float)
        p = np.asarray(ob.target_points(1.0), float)
        A = np.asarray(ob.A, float)
        who = f"observations[{i}] ({ob.x}, {ob.y})"
        if c.ndim != 2 or c.shape[1] != 2 or p.shape != (c.shape[0], 3) or c.shape[0] < 3:
            raise ValueError(f"{who}: expected (K, 2) corners and (K, 3) target points with "
                             f"K >= 3, got {c.shape} and {p.shape}")
        if not (np.isfinite(c).all() and np.isfinite(p).all()) or A.shape != (4, 4) \
                or not np.isfinite(A).all():
            raise ValueError(f"{who}: corners, target points and A must be finite")
        vx.append(xi[ob.x])
        vy.append(yi[ob.y])
        As.append(A)
        pts.append(p)
        pix.append(c)
        counts.append(c.shape[0])
        keys.append(np.ascontiguousarray(A).tobytes())
    group_of: dict[bytes, int] = {}
    groups = [group_of.setdefault(k, len(group_of)) for k in keys]
    return CornerViews(
        x_names=x_names, y_names=y_names,
        view_x=np.asarray(vx, dtype=np.intp), view_y=np.asarray(vy, dtype=np.intp),
        view_group=np.asarray(groups, dtype=np.intp),
        A=np.asarray(As, float).reshape(-1, 4, 4),
        start=np.concatenate([[0], np.cumsum(counts)]).astype(np.intp),
        points=np.concatenate(pts) if pts else np.zeros((0, 3)),
        pixels=np.concatenate(pix) if pix else np.zeros((0, 2)))

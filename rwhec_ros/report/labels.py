"""Labels that do not overlap: a greedy placement in display units, shared by the report's 3D
frame views and scatter plots."""

from __future__ import annotations

import numpy as np

__all__ = ["place_labels", "label_points"]

_DIRECTIONS = [(1, 1), (1, -1), (-1, 1), (-1, -1), (1, 0), (-1, 0), (0, 1), (0, -1)]


def _free(box, placed) -> bool:
    return all(box[2] <= b[0] or box[0] >= b[2] or box[3] <= b[1] or box[1] >= b[3]
               for b in placed)


def place_labels(points: np.ndarray, sizes: np.ndarray, *, step: float = 10.0,
                 rings: int = 8, obstacles=(), bounds=None) -> np.ndarray:
    """Offsets (n, 2) [display units] for labels anchored at ``points`` (n, 2) with box
    ``sizes`` (n, 2) so that no two boxes overlap (greedy: each label tries positions on rings
    of growing radius, 8 directions each, and takes the first free one).

    ``obstacles``: boxes ``(x0, y0, x1, y1)`` no label may cover (e.g. the data points);
    ``bounds``: a box every label must stay inside (e.g. the axes), when it can.
    """
    placed: list[tuple[float, float, float, float]] = []
    blocked = [tuple(b) for b in obstacles]
    out = np.zeros_like(points, dtype=float)
    for i, (p, s) in enumerate(zip(points, sizes, strict=True)):
        best = None
        for r in range(1, rings + 1):
            for dx, dy in _DIRECTIONS:
                off = np.array([dx, dy], float) * step * r
                x0 = p[0] + off[0] - (s[0] if dx < 0 else 0 if dx > 0 else s[0] / 2)
                y0 = p[1] + off[1] - (s[1] if dy < 0 else 0 if dy > 0 else s[1] / 2)
                box = (x0, y0, x0 + s[0], y0 + s[1])
                if bounds is not None and not (box[0] >= bounds[0] and box[1] >= bounds[1]
                                               and box[2] <= bounds[2] and box[3] <= bounds[3]):
                    continue
                if _free(box, placed) and _free(box, blocked):
                    best = (off, box)
                    break
            if best is not None:
                break
        if best is None:  # crowded: the last ring's first direction
            off = np.array([1.0, 1.0]) * step * rings
            best = (off, (p[0] + off[0], p[1] + off[1], p[0] + off[0] + s[0],
                          p[1] + off[1] + s[1]))
        out[i] = best[0]
        placed.append(best[1])
    return out


def label_points(ax, x: np.ndarray, y: np.ndarray, names: list[str], *, fontsize: float = 7,
                 others: tuple[np.ndarray, np.ndarray] | None = None) -> None:
    """Name the points ``(x, y)`` (data coordinates) of a 2D axes without overlaps: labels
    avoid each other, the named points and ``others`` (more points, unnamed), stay inside the
    axes, and a thin line joins a label to its point. Call after the axes limits are set."""
    fig = ax.figure
    scale = fig.dpi / 72.0  # display units per point
    pts = ax.transData.transform(np.column_stack([x, y])) if len(x) else np.zeros((0, 2))
    sizes = np.array([(fontsize * 0.62 * len(n) * scale + 4, fontsize * 1.35 * scale)
                      for n in names]).reshape(-1, 2)
    dots = pts if others is None else np.vstack(
        [pts, ax.transData.transform(np.column_stack(others))])
    r = 3.5 * scale
    obstacles = [(px - r, py - r, px + r, py + r) for px, py in dots]
    bbox = ax.get_window_extent()
    offsets = place_labels(pts, sizes, step=7 * scale, rings=10, obstacles=obstacles,
                           bounds=(bbox.x0, bbox.y0, bbox.x1, bbox.y1))
    for name, xi, yi, off in zip(names, x, y, offsets, strict=True):
        ax.annotate(name, (xi, yi), xytext=off / scale, textcoords="offset points",
                    fontsize=fontsize, ha="left" if off[0] > 0 else
                    ("right" if off[0] < 0 else "center"),
                    va="bottom" if off[1] > 0 else ("top" if off[1] < 0 else "center"),
                    arrowprops={"arrowstyle": "-", "color": "0.55", "linewidth": 0.5})

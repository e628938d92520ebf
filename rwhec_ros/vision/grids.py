"""Marker-free calibration boards as targets: chessboards and circle grids (layouts only).

A board is one rigid target with one frame (one ``X_j`` of ``A_i X_j = Y_k B_i``). These boards
carry no coded markers: OpenCV finds the whole regular grid (``cv2.findChessboardCornersSB``,
``cv2.findCirclesGrid``; :mod:`rwhec_ros.vision.grid_detection`) and the board's own layout must
tell which end is which. This module holds the layouts: where every grid point lies in the board
frame, what is printed where (for :mod:`rwhec_ros.vision.render`), and the check that refuses a
layout whose grid maps onto itself under a turn (its point order could flip between views).

Board frame (as for the boards of :mod:`rwhec_ros.vision.boards`)
-----------------------------------------------------------------
Origin at the **centre of the grid points**, ``x`` to the right and ``y`` up on the board as
printed upright, ``z = x cross y`` out of the printed face toward a viewer. Grid points are
labelled ``(a, b)``: column ``a`` from the left, row ``b`` from the top of the upright board; the
point list (:meth:`object_points`) is row by row from the top left, ``k = b * cols + a``
(OpenCV's order for an upright board).

Chessboard (``cols x rows`` inner corners, squares of ``square_size``)
----------------------------------------------------------------------
``(cols + 1) x (rows + 1)`` squares; upright, the top-left square is black (OpenCV's
``gen_pattern.py``). Corner ``(a, b)`` sits at ``((a - (cols-1)/2) s, ((rows-1)/2 - b) s)``.
With one odd and one even square count the top-left square is black upright and white turned,
which fixes the order. Turned by 180 degrees the board looks the same when ``cols + rows`` is
even (both square counts even or both odd, e.g. the ROS ``camera_calibration`` tutorial's 8 x 6
inner corners): such a board is **turn-symmetric** (:attr:`ChessboardSpec.turn_symmetric`). The
detector labels it one fixed way per image and the pose stream tells, across views, which
views are turned (:mod:`rwhec_ros.sync.board_turns`). A square grid (``cols == rows``) is
refused: it may also look the same turned by 90 degrees.

Circle grids (``cols`` circles per row, ``rows`` rows, dark circles on white)
-----------------------------------------------------------------------------
* symmetric (``circles``): point ``(a, b)`` at ``((a - (cols-1)/2) p, ((rows-1)/2 - b) p)``,
  ``p = spacing``. Such a grid maps onto itself turned by 180 degrees (and by 90 when square)
  unless it has a **larger origin circle** (``origin_circle``: industrial_calibration's
  "modified circle grid"), which is the bottom-left point ``(0, rows - 1)`` of the upright board.
  Without one it is turn-symmetric like a chessboard with both square counts even or both odd
  (the pose stream tells which views are turned); a square one is refused;
* asymmetric (``asymmetric_circles``, OpenCV's layout): row ``b`` shifted by half a period when
  ``b`` is odd, point ``(a, b)`` at ``((2a + b mod 2 - (cols - 1/2)) p, ((rows-1)/2 - b) p)``
  with ``p = spacing`` OpenCV's "square size" (neighbours in a row are ``2p`` apart, rows ``p``
  apart). With an even number of rows it maps onto itself turned by 180 degrees: refused; with
  an odd number the layout fixes the order.

``diameter`` (optional) is the printed circle diameter; the detector measures it in the image
when it is not given (it serves the correction of the circle-centre projection bias). Rendering
uses ``0.4 p`` when unset (OpenCV's ``gen_pattern.py`` default) and ``1.75`` times the diameter
for an origin circle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .boards import _positive, _positive_int

__all__ = ["ChessboardSpec", "CircleGridSpec", "GridSpec", "ORIGIN_CIRCLE_SCALE"]

#: Printed diameter of an origin circle as a multiple of the other circles' (rendering only; the
#: detector only needs it to be clearly larger).
ORIGIN_CIRCLE_SCALE = 1.75


def _count(owner: str, field: str, value, least: int) -> int:
    v = _positive_int(owner, field, value)
    if v < least:
        raise ValueError(f"{owner}: {field} must be >= {least}, got {v}")
    return v


def _grid_labels(cols: int, rows: int) -> tuple[np.ndarray, np.ndarray]:
    """``(a, b)`` of the points in row-by-row order."""
    b, a = np.divmod(np.arange(cols * rows), cols)
    return a, b


class _Grid:
    """What a grid without coded markers has: ``cols`` x ``rows`` points found by OpenCV's
    grid detectors (a chessboard's inner corners, a circle grid's centres)."""

    cols: int
    rows: int

    @property
    def marker_ids(self) -> tuple[int, ...]:
        """No coded markers."""
        return ()

    @property
    def pattern_size(self) -> tuple[int, int]:
        """OpenCV's ``patternSize`` ``(cols, rows)``."""
        return self.cols, self.rows

    @property
    def n_corners(self) -> int:
        """Points of the grid (the points of a pose)."""
        return self.cols * self.rows


@dataclass(frozen=True)
class ChessboardSpec(_Grid):
    """A plain chessboard (module docstring for the layout and the frame).

    Attributes
    ----------
    cols, rows : int
        Inner corners along ``x`` and ``y`` (OpenCV's ``patternSize``), each >= 2, not equal;
        with ``cols + rows`` even the board is :attr:`turn_symmetric`.
    square_size : float
        Edge of a square [m] (nominal if the scale is unknown).
    """

    cols: int
    rows: int
    square_size: float

    kind = "chessboard"
    dictionary = ""  # no coded markers

    def __post_init__(self) -> None:
        owner = "chessboard"
        object.__setattr__(self, "cols", _count(owner, "cols", self.cols, 2))
        object.__setattr__(self, "rows", _count(owner, "rows", self.rows, 2))
        object.__setattr__(self, "square_size",
                           _positive(owner, "square_size", self.square_size))
        if self.cols == self.rows:
            raise ValueError(
                f"{owner}: cols {self.cols} and rows {self.rows} inner corners make a square "
                f"grid, which can look the same turned by 90 degrees, so its corner order "
                f"could turn between views; use a board with different numbers of squares "
                f"along its two sides (e.g. 9 x 6 inner corners)")

    @property
    def turn_symmetric(self) -> bool:
        """True when the board looks the same turned by 180 degrees (``cols + rows`` even):
        which views are turned is told from the pose stream (module docstring)."""
        return (self.cols + self.rows) % 2 == 0

    @property
    def pitch(self) -> float:
        """Distance of neighbouring grid points [m]."""
        return self.square_size

    @property
    def width(self) -> float:
        """Width of the squares ``W`` [m]."""
        return (self.cols + 1) * self.square_size

    @property
    def height(self) -> float:
        """Height of the squares ``H`` [m]."""
        return (self.rows + 1) * self.square_size

    def object_points(self) -> np.ndarray:
        """Inner corners (n_corners, 3) in the board frame, row by row from the top left."""
        a, b = _grid_labels(self.cols, self.rows)
        s = self.square_size
        return np.stack([(a - 0.5 * (self.cols - 1)) * s, (0.5 * (self.rows - 1) - b) * s,
                         np.zeros(a.shape)], axis=1)

    def quiet_zone(self) -> float:
        """White margin drawn around the squares by default [m] (one square)."""
        return self.square_size

    def outline(self, margin: float) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the printed area with a white ``margin`` [m]."""
        return (-0.5 * self.width - margin, 0.5 * self.width + margin,
                -0.5 * self.height - margin, 0.5 * self.height + margin)

    def texture(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """What is printed at board points ``(x, y)`` [m]: 0 black, 1 white. Same shape as
        ``x``; white outside the squares."""
        s = self.square_size
        col = np.floor((np.asarray(x, dtype=float) + 0.5 * self.width) / s).astype(np.intp)
        row = np.floor((0.5 * self.height - np.asarray(y, dtype=float)) / s).astype(np.intp)
        inside = (col >= 0) & (col <= self.cols) & (row >= 0) & (row <= self.rows)
        out = np.ones(col.shape, dtype=np.uint8)
        out[inside & ((col + row) % 2 == 0)] = 0  # top-left square (0, 0) black
        return out


@dataclass(frozen=True)
class CircleGridSpec(_Grid):
    """A grid of dark circles (module docstring for the layouts and the frame).

    Attributes
    ----------
    cols, rows : int
        Circles per row and rows (OpenCV's ``patternSize``), each >= 2 (asymmetric: ``rows``
        odd, >= 3).
    spacing : float
        Symmetric: distance of neighbouring circle centres [m]; asymmetric: OpenCV's square size
        (half the centre distance within a row, the distance between rows).
    asymmetric : bool
        OpenCV's asymmetric grid (``asymmetric_circles``).
    origin_circle : bool
        Symmetric grids: the bottom-left circle of the upright board is larger (the "modified
        circle grid" of industrial_calibration), which fixes the order; without it the grid is
        :attr:`turn_symmetric` (``cols != rows`` required).
    diameter : float or None
        Printed diameter of the (ordinary) circles [m], smaller than the distance of
        neighbours; None: measured in each image by the detector.
    """

    cols: int
    rows: int
    spacing: float
    asymmetric: bool = False
    origin_circle: bool = False
    diameter: float | None = None

    dictionary = ""  # no coded markers

    def __post_init__(self) -> None:
        owner = self.kind
        object.__setattr__(self, "asymmetric", bool(self.asymmetric))
        object.__setattr__(self, "origin_circle", bool(self.origin_circle))
        object.__setattr__(self, "cols", _count(owner, "cols", self.cols, 2))
        object.__setattr__(self, "rows", _count(owner, "rows", self.rows,
                                                3 if self.asymmetric else 2))
        object.__setattr__(self, "spacing", _positive(owner, "spacing", self.spacing))
        if self.asymmetric:
            if self.origin_circle:
                raise ValueError(f"{owner}: origin_circle is for symmetric grids (type circles); "
                                 f"an asymmetric grid fixes its order by its layout")
            if self.rows % 2 == 0:
                raise ValueError(
                    f"{owner}: rows {self.rows} is even: such an asymmetric grid looks the same "
                    f"turned by 180 degrees, so its point order can flip between views; use an "
                    f"odd number of rows (OpenCV's pattern is 4 x 11)")
        elif not self.origin_circle and self.cols == self.rows:
            raise ValueError(
                f"{owner}: origin_circle is false and cols == rows {self.cols}: a square "
                f"symmetric circle grid looks the same turned by 90 degrees, so its point order "
                f"can turn between views; use asymmetric_circles, a grid with a larger origin "
                f"circle (origin_circle: true), or one with different numbers of circles along "
                f"its two sides (turned by 180 degrees then, which the pose stream tells)")
        if self.diameter is not None:
            d = _positive(owner, "diameter", self.diameter)
            if d >= self.neighbour_distance:
                raise ValueError(f"{owner}: diameter {d!r} must be smaller than the distance of "
                                 f"neighbouring circles {self.neighbour_distance!r}")
            object.__setattr__(self, "diameter", d)

    @property
    def turn_symmetric(self) -> bool:
        """A symmetric grid without an origin circle (``cols != rows``): it looks the same turned
        by 180 degrees; the pose stream tells which views are turned
        (:mod:`rwhec_ros.sync.board_turns`)."""
        return not self.asymmetric and not self.origin_circle

    @property
    def kind(self) -> str:
        """``"asymmetric_circles"`` or ``"circles"``."""
        return "asymmetric_circles" if self.asymmetric else "circles"

    @property
    def pitch(self) -> float:
        """Distance between rows [m] (and between neighbours in a row of a symmetric grid)."""
        return self.spacing

    @property
    def neighbour_distance(self) -> float:
        """Shortest distance of two circle centres [m]."""
        return self.spacing * (np.sqrt(2.0) if self.asymmetric else 1.0)

    @property
    def printed_diameter(self) -> float:
        """Diameter of the ordinary circles as rendered [m]."""
        return self.diameter if self.diameter is not None else 0.4 * self.spacing

    @property
    def width(self) -> float:
        """Extent of the circle centres along ``x`` [m]."""
        return (2 * self.cols - 1 if self.asymmetric else self.cols - 1) * self.spacing

    @property
    def height(self) -> float:
        """Extent of the circle centres along ``y`` [m]."""
        return (self.rows - 1) * self.spacing

    def object_points(self) -> np.ndarray:
        """Circle centres (n_corners, 3) in the board frame, row by row from the top left."""
        a, b = _grid_labels(self.cols, self.rows)
        p = self.spacing
        if self.asymmetric:
            x = (2 * a + b % 2 - (self.cols - 0.5)) * p
        else:
            x = (a - 0.5 * (self.cols - 1)) * p
        return np.stack([x, (0.5 * (self.rows - 1) - b) * p, np.zeros(a.shape)], axis=1)

    def origin_index(self) -> int | None:
        """Index of the origin circle in :meth:`object_points` (None without one)."""
        return (self.rows - 1) * self.cols if self.origin_circle else None

    def quiet_zone(self) -> float:
        """White margin around the circle centres drawn by default [m] (one spacing, and at
        least the origin circle)."""
        big = 0.5 * ORIGIN_CIRCLE_SCALE * self.printed_diameter if self.origin_circle else 0.0
        return max(self.spacing, big + 0.5 * self.spacing)

    def outline(self, margin: float) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the printed area: the centres' rectangle and a
        white ``margin`` [m] (which must hold the circles: at least :meth:`quiet_zone`)."""
        return (-0.5 * self.width - margin, 0.5 * self.width + margin,
                -0.5 * self.height - margin, 0.5 * self.height + margin)

    def texture(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """What is printed at board points ``(x, y)`` [m]: 0 black (a circle), 1 white."""
        p = self.spacing
        X = np.asarray(x, dtype=float)
        Y = np.asarray(y, dtype=float)
        out = np.ones(X.shape, dtype=np.uint8)
        r = 0.5 * self.printed_diameter
        b = np.rint(0.5 * (self.rows - 1) - Y / p).astype(np.intp)
        if self.asymmetric:
            a = np.rint(0.5 * (X / p + self.cols - 0.5 - b % 2)).astype(np.intp)
            cx = (2 * a + b % 2 - (self.cols - 0.5)) * p
        else:
            a = np.rint(X / p + 0.5 * (self.cols - 1)).astype(np.intp)
            cx = (a - 0.5 * (self.cols - 1)) * p
        cy = (0.5 * (self.rows - 1) - b) * p
        on = (a >= 0) & (a < self.cols) & (b >= 0) & (b < self.rows)
        d2 = (X - cx) ** 2 + (Y - cy) ** 2
        out[on & (d2 <= r * r)] = 0
        if self.origin_circle:
            o = self.object_points()[self.origin_index()]
            R = 0.5 * ORIGIN_CIRCLE_SCALE * self.printed_diameter
            out[(X - o[0]) ** 2 + (Y - o[1]) ** 2 <= R * R] = 0
        return out


#: Either marker-free board layout.
GridSpec = ChessboardSpec | CircleGridSpec

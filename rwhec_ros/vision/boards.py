"""Calibration boards as targets: a Kalibr-style AprilGrid and an OpenCV ChArUco board.

A board is one rigid target with one frame (one ``X_j`` of ``A_i X_j = Y_k B_i``); its pose
``T_cam_board`` comes from PnP over every detected corner (:mod:`rwhec_ros.vision.board_detection`).
This module holds the layouts only: where every marker corner and every chessboard corner lies
in the board frame, which cv2.aruco dictionary the markers come from, and what is printed where
(for :mod:`rwhec_ros.vision.render`).

Board frame (both kinds)
------------------------
The single-tag convention of :mod:`rwhec_ros.vision.detection` carried over to the printed board:
origin at the **centre of the pattern** (of the rectangle spanned by the tags' black squares, or
by the chessboard squares), ``x`` to the right and ``y`` up on the board as printed (upright:
AprilGrid tag ``first_id`` bottom-left, ChArUco marker 0 top-left), ``z = x cross y`` out of the
printed face toward a viewer. A 1 x 1 AprilGrid with one-bit borders is one tag, with its frame at
the tag centre. Conversions to the frames other tools report:

* Kalibr's AprilGrid target frame (origin at the outer bottom-left corner of tag 0, ``x`` right,
  ``y`` up, ``z`` out): ``p_kalibr = p_board + (W/2, H/2, 0)``;
* OpenCV's board frame (``cv2.aruco.Board`` object points: origin at the top-left corner of the
  pattern, ``x`` right, ``y`` down, ``z`` into the board): ``p_cv = (x + W/2, H/2 - y, -z)``,

with ``W x H`` the pattern size (:attr:`AprilGridSpec.width`, :attr:`AprilGridSpec.height`).

AprilGrid (Kalibr's ``aprilgrid`` target, ``kalibr_create_target_pdf --type apriltag``)
-------------------------------------------------------------------------------------------
``rows x cols`` tags of black-square edge ``tag_size`` with gaps ``tag_spacing * tag_size``
(Kalibr's ``tagSpacing`` is this ratio), ids ``first_id + row * cols + col`` with row 0 at the
bottom and column 0 at the left (Kalibr's order), every tag upright as in the AprilTag images, a
black border of ``border_bits`` cells (Kalibr prints 2; plain AprilTags have 1), and Kalibr's small
black squares (edge = the gap) at the gap crossings. OpenCV 4.x's AprilTag dictionaries are the
official tag images turned by 180 degrees (fixed in OpenCV 5, opencv/opencv#28823); the corner
order of each grid tag is derived from the installed OpenCV (:func:`official_orientation_turned`),
so a printed Kalibr grid gives the same board frame with either.

ChArUco (``cv2.aruco.CharucoBoard``)
------------------------------------
``squares_x x squares_y`` chessboard squares of edge ``square_size``, ArUco markers of edge
``marker_size`` centred in the white squares with ids ``first_id ...`` in OpenCV's order (row by
row from the top left), OpenCV >= 4.6's pattern unless ``legacy_pattern``. The pose uses the
chessboard (saddle) corners, ids ``0 .. (squares_x - 1)(squares_y - 1) - 1`` row by row from the
top left, found by ``cv2.aruco.CharucoDetector``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import cv2
import numpy as np

from .families import (
    dictionary_key,
    dictionary_size,
    get_dictionary,
    official_marker_bitmap,
    official_orientation_turned,
)

__all__ = [
    "AprilGridSpec",
    "CharucoSpec",
    "BoardSpec",
]

def _positive_int(owner: str, field: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or int(value) < 1:
        raise ValueError(f"{owner}: {field} must be a positive integer, got {value!r}")
    return int(value)


def _positive(owner: str, field: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = float("nan")
    if not (np.isfinite(v) and v > 0):
        raise ValueError(f"{owner}: {field} must be a positive number, got {value!r}")
    return v


def _first_id(owner: str, value, count: int, n_markers: int, dictionary: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or int(value) < 0:
        raise ValueError(f"{owner}: first_id must be a non-negative integer, got {value!r}")
    if int(value) + n_markers > count:
        raise ValueError(
            f"{owner}: first_id {int(value)} + {n_markers} markers exceeds the {count} markers "
            f"of {dictionary}"
        )
    return int(value)


@dataclass(frozen=True)
class AprilGridSpec:
    """A Kalibr-style AprilGrid (module docstring for the layout and the frame).

    Attributes
    ----------
    rows, cols : int
        Tags per column and per row (Kalibr's ``tagRows``, ``tagCols``).
    tag_size : float
        Edge of a tag's black square [m] (Kalibr's ``tagSize``; nominal if the scale is
        unknown).
    tag_spacing : float
        Gap between neighbouring tags as a fraction of ``tag_size`` (Kalibr's ``tagSpacing``),
        in ``[0, 1]``; at least ``1 / cells`` so that each tag keeps a white quiet zone.
    first_id : int
        Id of the bottom-left tag.
    family : str
        AprilTag family (or any cv2.aruco dictionary, :func:`dictionary_key`).
    border_bits : int
        Black border width in cells: 2 for grids printed by Kalibr (default), 1 for tags printed
        from the AprilTag images.
    corner_squares : bool
        The printed grid has Kalibr's black squares at the gap crossings (rendering only).
    """

    rows: int
    cols: int
    tag_size: float
    tag_spacing: float = 0.3
    first_id: int = 0
    family: str = "tag36h11"
    border_bits: int = 2
    corner_squares: bool = True

    kind = "aprilgrid"

    def __post_init__(self) -> None:
        owner = "aprilgrid"
        object.__setattr__(self, "rows", _positive_int(owner, "rows", self.rows))
        object.__setattr__(self, "cols", _positive_int(owner, "cols", self.cols))
        object.__setattr__(self, "tag_size", _positive(owner, "tag_size", self.tag_size))
        try:
            family = dictionary_key(self.family)
        except ValueError as exc:
            raise ValueError(f"{owner}: family: {exc}") from None
        object.__setattr__(self, "family", family)
        border = self.border_bits
        if isinstance(border, bool) or not isinstance(border, (int, np.integer)) or not (
            1 <= int(border) <= 3
        ):
            raise ValueError(f"{owner}: border_bits must be 1, 2 or 3, got {border!r}")
        object.__setattr__(self, "border_bits", int(border))
        spacing = float(self.tag_spacing) if np.isscalar(self.tag_spacing) else np.nan
        if not (np.isfinite(spacing) and 1.0 / self.cells <= spacing <= 1.0):
            raise ValueError(
                f"{owner}: tag_spacing must be in [1/{self.cells}, 1] (a fraction of tag_size, "
                f"at least one cell of quiet zone), got {self.tag_spacing!r}"
            )
        object.__setattr__(self, "tag_spacing", spacing)
        object.__setattr__(self, "first_id", _first_id(
            owner, self.first_id, dictionary_size(family), self.rows * self.cols, family))

    # ------------------------------------------------------------------ layout
    @property
    def dictionary(self) -> str:
        """Dictionary of the markers (canonical name)."""
        return self.family

    @property
    def cells(self) -> int:
        """Cells across a tag's black square (data cells + 2 ``border_bits``)."""
        return int(get_dictionary(self.family).markerSize) + 2 * int(self.border_bits)

    @property
    def gap(self) -> float:
        """Gap between tags [m]."""
        return self.tag_spacing * self.tag_size

    @property
    def width(self) -> float:
        """Pattern width ``W`` [m] (outer edges of the tags, without the corner squares)."""
        return self.cols * self.tag_size + (self.cols - 1) * self.gap

    @property
    def height(self) -> float:
        """Pattern height ``H`` [m]."""
        return self.rows * self.tag_size + (self.rows - 1) * self.gap

    @property
    def marker_ids(self) -> tuple[int, ...]:
        return tuple(range(self.first_id, self.first_id + self.rows * self.cols))

    @property
    def n_corners(self) -> int:
        """Corners usable for the pose when every tag is seen (4 per tag)."""
        return 4 * self.rows * self.cols

    def tag_centre(self, marker_id: int) -> np.ndarray:
        """Centre (3,) of a tag in the board frame."""
        k = int(marker_id) - self.first_id
        if not 0 <= k < self.rows * self.cols:
            raise ValueError(f"marker_id {marker_id} is not on this grid {self.marker_ids[0]}.."
                             f"{self.marker_ids[-1]}")
        row, col = divmod(k, self.cols)
        pitch = self.tag_size + self.gap
        return np.array([
            -0.5 * self.width + 0.5 * self.tag_size + col * pitch,
            -0.5 * self.height + 0.5 * self.tag_size + row * pitch,
            0.0,
        ])

    def marker_object_points(self, marker_id: int) -> np.ndarray:
        """Corners (4, 3) of a tag's black square in the board frame, in the order
        ``cv2.aruco`` reports the corners of that marker (clockwise from the marker's own top
        left as OpenCV draws it)."""
        h = 0.5 * self.tag_size
        upright = np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])
        if official_orientation_turned(self.family):
            upright = np.roll(upright, -2, axis=0)
        return self.tag_centre(marker_id) + upright

    def outline(self, margin: float) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the printed area with a white ``margin`` [m]
        around the pattern (and around the corner squares, if printed)."""
        extra = margin + (self.gap if self.corner_squares else 0.0)
        return (-0.5 * self.width - extra, 0.5 * self.width + extra,
                -0.5 * self.height - extra, 0.5 * self.height + extra)

    def texture(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """What is printed at board points ``(x, y)`` [m]: 0 black, 1 white (inside the
        pattern; the caller decides where the board ends). Same shape as ``x``."""
        s, g = self.tag_size, self.gap
        pitch = s + g
        # Shift so that the period [gap | tag] starts at the outer gap left of / below tag 0.
        u = np.asarray(x, dtype=float) + 0.5 * self.width + g
        v = np.asarray(y, dtype=float) + 0.5 * self.height + g
        i = np.floor(u / pitch)
        j = np.floor(v / pitch)
        fu = u - i * pitch - g  # >= 0 inside a tag column, < 0 in a gap column
        fv = v - j * pitch - g
        col = i.astype(np.intp)
        row = j.astype(np.intp)
        in_tag = (fu >= 0) & (fv >= 0) & (col >= 0) & (col < self.cols) & (row >= 0) & (
            row < self.rows)
        out = np.ones(u.shape, dtype=np.uint8)
        if self.corner_squares:
            square = (fu < 0) & (fv < 0) & (col >= 0) & (col <= self.cols) & (row >= 0) & (
                row <= self.rows)
            out[square] = 0
        if np.any(in_tag):
            n = self.cells
            cell = s / n
            cx = np.clip(np.floor(fu[in_tag] / cell).astype(np.intp), 0, n - 1)
            cy = np.clip(n - 1 - np.floor(fv[in_tag] / cell).astype(np.intp), 0, n - 1)
            bitmaps = self._bitmaps()
            k = row[in_tag] * self.cols + col[in_tag]
            out[in_tag] = bitmaps[k, cy, cx] > 127
        return out

    def _bitmaps(self) -> np.ndarray:
        return _grid_bitmaps(self.family, self.first_id, self.rows * self.cols, self.border_bits)


@functools.lru_cache(maxsize=16)
def _grid_bitmaps(family: str, first_id: int, count: int, border_bits: int) -> np.ndarray:
    return np.stack([official_marker_bitmap(family, first_id + k, border_bits)
                     for k in range(count)])


@dataclass(frozen=True)
class CharucoSpec:
    """A ChArUco board as ``cv2.aruco.CharucoBoard`` defines it (module docstring).

    Attributes
    ----------
    squares_x, squares_y : int
        Chessboard squares along ``x`` (columns) and ``y`` (rows), each >= 2.
    square_size : float
        Edge of a chessboard square [m].
    marker_size : float
        Edge of a marker's black square [m], smaller than ``square_size``.
    dictionary : str
        ArUco dictionary (``"DICT_5X5_100"``, ``"5x5_100"``) or AprilTag family.
    first_id : int
        Id of marker 0 (the top-left one); ids ``first_id, first_id + 1, ...`` row by row.
    legacy_pattern : bool
        Boards made by OpenCV < 4.6 with an even number of rows (OpenCV's ``setLegacyPattern``).
    """

    squares_x: int
    squares_y: int
    square_size: float
    marker_size: float
    dictionary: str = "DICT_5X5_100"
    first_id: int = 0
    legacy_pattern: bool = False

    kind = "charuco"

    def __post_init__(self) -> None:
        owner = "charuco"
        for name in ("squares_x", "squares_y"):
            value = _positive_int(owner, name, getattr(self, name))
            if value < 2:
                raise ValueError(f"{owner}: {name} must be >= 2, got {value}")
            object.__setattr__(self, name, value)
        object.__setattr__(self, "square_size",
                           _positive(owner, "square_size", self.square_size))
        marker = _positive(owner, "marker_size", self.marker_size)
        if marker >= self.square_size:
            raise ValueError(f"{owner}: marker_size {marker!r} must be smaller than square_size "
                             f"{self.square_size!r}")
        object.__setattr__(self, "marker_size", marker)
        try:
            key = dictionary_key(self.dictionary)
        except ValueError as exc:
            raise ValueError(f"{owner}: dictionary: {exc}") from None
        object.__setattr__(self, "dictionary", key)
        object.__setattr__(self, "legacy_pattern", bool(self.legacy_pattern))
        n_markers = (self.squares_x * self.squares_y) // 2
        object.__setattr__(self, "first_id", _first_id(
            owner, self.first_id, dictionary_size(key), n_markers, key))

    # ------------------------------------------------------------------ layout
    @property
    def width(self) -> float:
        """Pattern width ``W`` [m]."""
        return self.squares_x * self.square_size

    @property
    def height(self) -> float:
        """Pattern height ``H`` [m]."""
        return self.squares_y * self.square_size

    @property
    def marker_ids(self) -> tuple[int, ...]:
        return tuple(int(i) for i in self._layout()[0])

    @property
    def n_corners(self) -> int:
        """Chessboard corners of the board."""
        return (self.squares_x - 1) * (self.squares_y - 1)

    def cv2_board(self) -> cv2.aruco.CharucoBoard:
        """A new ``cv2.aruco.CharucoBoard`` of this layout (OpenCV's frame, see the module)."""
        board = cv2.aruco.CharucoBoard(
            (self.squares_x, self.squares_y), self.square_size, self.marker_size,
            get_dictionary(self.dictionary),
            np.array(self._ids_array(), dtype=np.int32),
        )
        board.setLegacyPattern(self.legacy_pattern)
        return board

    def corner_object_points(self) -> np.ndarray:
        """Chessboard corners (n_corners, 3) in the board frame, indexed by ChArUco corner id."""
        return self._layout()[2]

    def marker_object_points(self, marker_id: int) -> np.ndarray:
        """Corners (4, 3) of a marker in the board frame, in ``cv2.aruco``'s corner order."""
        ids, corners, _ = self._layout()
        hit = np.flatnonzero(ids == int(marker_id))
        if hit.size == 0:
            raise ValueError(f"marker_id {marker_id} is not on this ChArUco board")
        return corners[hit[0]]

    def outline(self, margin: float) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the printed area with a white ``margin`` [m]."""
        return (-0.5 * self.width - margin, 0.5 * self.width + margin,
                -0.5 * self.height - margin, 0.5 * self.height + margin)

    def texture(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """What is printed at board points ``(x, y)`` [m]: 0 black, 1 white (inside the
        pattern; the caller decides where the board ends). Same shape as ``x``."""
        sq = self.square_size
        u = np.asarray(x, dtype=float) + 0.5 * self.width  # OpenCV frame: x right, y down
        v = 0.5 * self.height - np.asarray(y, dtype=float)
        col = np.floor(u / sq).astype(np.intp)
        row = np.floor(v / sq).astype(np.intp)
        inside = (col >= 0) & (col < self.squares_x) & (row >= 0) & (row < self.squares_y)
        out = np.ones(u.shape, dtype=np.uint8)
        slot = np.full(u.shape, -1, dtype=np.intp)
        table = self._square_markers()
        slot[inside] = table[row[inside], col[inside]]
        out[inside & (slot < 0)] = 0  # squares without a marker are the black ones
        has = slot >= 0
        if np.any(has):
            d = get_dictionary(self.dictionary)
            n = int(d.markerSize) + 2
            cell = self.marker_size / n
            k = slot[has]
            # Top-left corner of each marker square in the OpenCV frame.
            c0 = col[has] * sq + 0.5 * (sq - self.marker_size)
            r0 = row[has] * sq + 0.5 * (sq - self.marker_size)
            cx = np.floor((u[has] - c0) / cell).astype(np.intp)
            cy = np.floor((v[has] - r0) / cell).astype(np.intp)
            in_marker = (cx >= 0) & (cx < n) & (cy >= 0) & (cy < n)
            values = np.ones(k.shape, dtype=np.uint8)
            bitmaps = _cv2_bitmaps(self.dictionary, self._ids_array())
            values[in_marker] = bitmaps[k[in_marker], cy[in_marker], cx[in_marker]] > 127
            out[has] = values
        return out

    # ------------------------------------------------------------------ internals
    def _ids_array(self) -> tuple[int, ...]:
        return tuple(range(self.first_id,
                           self.first_id + (self.squares_x * self.squares_y) // 2))

    def _layout(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return _charuco_layout(self.squares_x, self.squares_y, self.square_size,
                               self.marker_size, self.dictionary, self.first_id,
                               self.legacy_pattern)

    def _square_markers(self) -> np.ndarray:
        """(squares_y, squares_x) table: index into the marker list of the marker in each
        square (OpenCV rows from the top), -1 for black squares."""
        _, corners_board, _ = self._layout()
        table = np.full((self.squares_y, self.squares_x), -1, dtype=np.intp)
        for k, quad in enumerate(corners_board):
            cx, cy = quad[:, :2].mean(axis=0)
            col = int(np.floor((cx + 0.5 * self.width) / self.square_size))
            row = int(np.floor((0.5 * self.height - cy) / self.square_size))
            table[row, col] = k
        return table


def _cv_to_board(points: np.ndarray, width: float, height: float) -> np.ndarray:
    """OpenCV board frame (top-left origin, y down, z in) -> board frame (centre, y up, z out)."""
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    return np.stack([p[:, 0] - 0.5 * width, 0.5 * height - p[:, 1], 0.0 - p[:, 2]], axis=1) + 0.0


@functools.lru_cache(maxsize=16)
def _charuco_layout(sx: int, sy: int, square: float, marker: float, dictionary: str,
                    first_id: int, legacy: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(marker ids (n,), marker corners (n, 4, 3), chessboard corners (m, 3)), board frame."""
    ids = np.arange(first_id, first_id + (sx * sy) // 2, dtype=np.int32)
    board = cv2.aruco.CharucoBoard((sx, sy), square, marker, get_dictionary(dictionary), ids)
    board.setLegacyPattern(legacy)
    W, H = sx * square, sy * square
    marker_ids = np.asarray(board.getIds(), dtype=int).reshape(-1)
    corners = np.stack([_cv_to_board(q, W, H) for q in board.getObjPoints()])
    chess = _cv_to_board(np.asarray(board.getChessboardCorners()), W, H)
    for a in (marker_ids, corners, chess):
        a.setflags(write=False)
    return marker_ids, corners, chess


@functools.lru_cache(maxsize=16)
def _cv2_bitmaps(dictionary: str, ids: tuple[int, ...]) -> np.ndarray:
    d = get_dictionary(dictionary)
    n = int(d.markerSize) + 2
    return np.stack([cv2.aruco.generateImageMarker(d, int(i), n, borderBits=1) for i in ids])


#: Either board layout.
BoardSpec = AprilGridSpec | CharucoSpec

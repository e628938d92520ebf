"""Synthetic images of AprilTags and boards seen by a calibrated camera (tests, benchmarks, demo).

Tag frame (the one :mod:`rwhec_ros.vision.detection` estimates, OpenCV's ``SOLVEPNP_IPPE_SQUARE``
/ ``cv2.aruco`` convention): origin at the centre of the black square, ``x`` to the right and ``y``
up on the printed tag, ``z = x cross y`` out of the tag face toward a viewer. The black square
spans ``[-size/2, size/2]^2`` in ``(x, y)``; the white quiet zone surrounds it.

Rendering is an exact inverse lookup: every (sub-)sample of the output image is undistorted to
its ray, intersected with the tag plane and given the colour of the cell it hits (point sampling
of the ideal piecewise-constant scene); ``supersample**2`` samples per pixel on a rank-1 lattice
(:func:`sample_offsets`; optionally shifted differently in every pixel, :func:`pixel_shifts`) are
averaged (box filter), which anti-aliases the edges. The lookup is restricted to the bounding box
of the tag's projected outline.

Boards (:class:`RenderedBoard`: an AprilGrid or a ChArUco board of :mod:`rwhec_ros.vision.boards`,
a chessboard or a circle grid of :mod:`rwhec_ros.vision.grids`) are drawn the same way in their
board frame (centre of the pattern, ``x`` right, ``y`` up, ``z`` out of the face), with the
board's own :meth:`texture` and a white margin around the pattern.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from .boards import AprilGridSpec, CharucoSpec
from .families import marker_bitmap, marker_cells
from .grids import ChessboardSpec, CircleGridSpec
from .intrinsics import CameraIntrinsics

__all__ = [
    "RenderedTag",
    "RenderedBoard",
    "render_tags",
    "look_at",
    "tag_outline",
    "sample_offsets",
    "pixel_shifts",
]


@dataclass(frozen=True, eq=False)
class RenderedTag:
    """A tag to render.

    Attributes
    ----------
    tag_id : int
        Marker id in the family.
    T_cam_tag : ndarray, shape (4, 4)
        Pose of the tag frame in the camera frame (maps tag coordinates to camera coordinates).
    size : float
        Edge length of the black square in metres (AprilTag convention).
    """

    tag_id: int
    T_cam_tag: np.ndarray
    size: float

    def __post_init__(self) -> None:
        T = np.array(self.T_cam_tag, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ValueError(
                f"T_cam_tag of tag {self.tag_id} must be a finite (4, 4) array, got shape {T.shape}"
            )
        if not (np.isfinite(self.size) and self.size > 0):
            raise ValueError(f"size of tag {self.tag_id} must be positive, got {self.size!r}")
        T.setflags(write=False)
        object.__setattr__(self, "T_cam_tag", T)


_BOARDS = (AprilGridSpec, CharucoSpec, ChessboardSpec, CircleGridSpec)


@dataclass(frozen=True, eq=False)
class RenderedBoard:
    """A board to render.

    Attributes
    ----------
    board : AprilGridSpec, CharucoSpec, ChessboardSpec or CircleGridSpec
        Layout (:mod:`rwhec_ros.vision.boards`, :mod:`rwhec_ros.vision.grids`).
    T_cam_board : ndarray, shape (4, 4)
        Pose of the board frame in the camera frame.
    margin : float or None
        White margin around the pattern [m] (beyond Kalibr's corner squares for a grid); None:
        one gap of the grid (at least one tag cell), half a square of a ChArUco board, the
        ``quiet_zone()`` of a chessboard or circle grid.
    """

    board: AprilGridSpec | CharucoSpec | ChessboardSpec | CircleGridSpec
    T_cam_board: np.ndarray
    margin: float | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.board, _BOARDS):
            raise ValueError(f"board must be one of {[b.__name__ for b in _BOARDS]}, got "
                             f"{type(self.board).__name__}")
        T = np.array(self.T_cam_board, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ValueError(f"T_cam_board must be a finite (4, 4) array, got shape {T.shape}")
        T.setflags(write=False)
        object.__setattr__(self, "T_cam_board", T)
        if self.margin is not None and not (np.isfinite(self.margin) and self.margin >= 0):
            raise ValueError(f"margin must be >= 0 or None, got {self.margin!r}")

    def extent(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the printed board (pattern and margin) [m]."""
        margin = self.margin
        if margin is None:
            b = self.board
            if isinstance(b, AprilGridSpec):
                margin = max(b.gap, b.tag_size / b.cells)
            elif isinstance(b, CharucoSpec):
                margin = 0.5 * b.square_size
            else:
                margin = b.quiet_zone()
        return self.board.outline(float(margin))


def look_at(
    camera_position: np.ndarray,
    target_point: np.ndarray,
    up: np.ndarray = (0.0, 0.0, 1.0),
) -> np.ndarray:
    """Pose ``T_world_cam`` of an optical camera frame at ``camera_position`` aimed at a point.

    The camera ``z`` axis points at ``target_point``, ``x`` to the right and ``y`` down in the
    image, with the world direction ``up`` appearing up in the image.

    Returns
    -------
    ndarray, shape (4, 4)

    Raises
    ------
    ValueError
        If the two points coincide or ``up`` is parallel to the viewing direction.
    """
    p = np.asarray(camera_position, dtype=float).reshape(3)
    q = np.asarray(target_point, dtype=float).reshape(3)
    u = np.asarray(up, dtype=float).reshape(3)
    forward = q - p
    dist = np.linalg.norm(forward)
    if not dist > 1e-12:
        raise ValueError(f"target_point must differ from camera_position, got {p.tolist()}")
    z = forward / dist
    x = np.cross(z, u)
    nx = np.linalg.norm(x)
    if not nx > 1e-9 * max(np.linalg.norm(u), 1e-300):
        raise ValueError(f"up must not be parallel to the viewing direction, got {u.tolist()}")
    x /= nx
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, p
    return T


def tag_outline(size: float, extent_cells: float, cells: int, per_edge: int = 16) -> np.ndarray:
    """Points along the square ``[-h, h]^2`` (tag frame, ``z = 0``), ``h = size extent/(2 cells)``.

    Returns shape (4 * per_edge, 3).
    """
    h = 0.5 * size * extent_cells / cells
    s = np.linspace(-h, h, per_edge, endpoint=False)
    edges = [
        np.c_[s, np.full_like(s, h)],
        np.c_[np.full_like(s, h), -s],
        np.c_[-s, np.full_like(s, -h)],
        np.c_[np.full_like(s, -h), s],
    ]
    xy = np.concatenate(edges)
    return np.c_[xy, np.zeros(len(xy))]


def _bounding_box(
    intrinsics: CameraIntrinsics, T_cam_tag: np.ndarray, outline: np.ndarray
) -> tuple[int, int, int, int] | None:
    """Pixel box ``(u0, v0, u1, v1)`` (exclusive end) holding the tag, or None if off-image."""
    W, H = intrinsics.width, intrinsics.height
    pts_cam = outline @ T_cam_tag[:3, :3].T + T_cam_tag[:3, 3]
    if np.any(pts_cam[:, 2] <= 1e-6 * np.linalg.norm(pts_cam, axis=1)):
        return 0, 0, W, H  # partly behind the camera: search the whole image
    if intrinsics.is_fisheye:
        # cv2.fisheye is only valid up to 90 degrees from the axis; stay conservative there.
        angle = np.arctan2(np.linalg.norm(pts_cam[:, :2], axis=1), pts_cam[:, 2])
        if np.any(angle > np.deg2rad(80.0)):
            return 0, 0, W, H
    uv = intrinsics.project_points(pts_cam)
    if not np.all(np.isfinite(uv)):
        return 0, 0, W, H
    margin = 2
    u0 = max(int(np.floor(uv[:, 0].min())) - margin, 0)
    v0 = max(int(np.floor(uv[:, 1].min())) - margin, 0)
    u1 = min(int(np.ceil(uv[:, 0].max())) + margin + 1, W)
    v1 = min(int(np.ceil(uv[:, 1].max())) + margin + 1, H)
    if u1 <= u0 or v1 <= v0:
        return None
    return u0, v0, u1, v1


def sample_offsets(supersample: int) -> np.ndarray:
    """Sub-pixel sample offsets (n, 2), ``n = supersample**2``, in ``(-0.5, 0.5)^2``.

    A rank-1 lattice: sample ``k`` sits at ``x = (k + 1/2)/n``, ``y = ((k (s + 1)) mod n + 1/2)/n``
    (minus 1/2). Every sample has its own ``x`` and its own ``y``, so the coverage of a nearly
    axis-aligned edge is resolved in steps of ``1/n`` pixel instead of ``1/s`` for a regular
    ``s x s`` grid. Edges parallel to the lattice's short vectors are resolved coarsely
    (:func:`pixel_shifts`).
    """
    s = int(supersample)
    n = s * s
    k = np.arange(n)
    return np.stack([(k + 0.5) / n - 0.5, ((k * (s + 1)) % n + 0.5) / n - 0.5], axis=1)


def pixel_shifts(uu: np.ndarray, vv: np.ndarray) -> np.ndarray:
    """Per-pixel shifts (..., 2) in ``[0, 1)^2`` of the sample pattern (a Cranley-Patterson
    rotation, ``render_tags(..., shift_pattern=True)``): a fixed hash (splitmix64) of the integer
    pixel coordinates, so rendering stays deterministic. Any fixed lattice puts its samples on a
    few lines parallel to its short vectors, so an edge parallel to them is resolved in a few
    coverage levels, the same all along the edge: a systematic shift of the edge (``s = 2`` at 45
    degrees, ``s = 3`` at slope 1/2, ``s = 4`` at slope 1/3: demo tags turned that way got
    corners 0.2-0.7 px off, poses 1.5-3 degrees off). Shifted differently in every pixel, the
    quantisation becomes noise (about ``1 / (n sqrt(12))`` of the contrast per edge pixel) that
    averages out along an edge, whatever its direction."""
    x = (np.asarray(uu).astype(np.uint64) * np.uint64(0x9E3779B97F4A7C15)) ^ (
        np.asarray(vv).astype(np.uint64) * np.uint64(0xC2B2AE3D27D4EB4F))
    out = []
    for salt in (np.uint64(0x632BE59BD9B4E019), np.uint64(0x85EBCA77C2B2AE63)):
        z = x + salt
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
        out.append((z >> np.uint64(11)).astype(np.float64) / float(1 << 53))
    return np.stack(out, axis=-1)


def _rays(
    intrinsics: CameraIntrinsics, box: tuple[int, int, int, int], offsets: np.ndarray,
    shift: bool = False,
) -> np.ndarray:
    """Normalized rays (h, w, n, 2) of the sub-samples of the pixels in ``box`` (the pattern
    ``offsets`` shifted in each pixel by :func:`pixel_shifts`, modulo the pixel, with
    ``shift``)."""
    u0, v0, u1, v1 = box
    vv, uu = np.mgrid[v0:v1, u0:u1]
    off = np.broadcast_to(offsets[None, None, :, :], (v1 - v0, u1 - u0) + offsets.shape)
    if shift:
        off = np.mod(off + 0.5 + pixel_shifts(uu, vv)[:, :, None, :], 1.0) - 0.5
    pix = np.stack([uu, vv], axis=-1).astype(float)[:, :, None, :] + off
    xy = intrinsics.normalize_points(pix.reshape(-1, 2))
    return xy.reshape(pix.shape)


def render_tags(
    intrinsics: CameraIntrinsics,
    tags: Sequence[RenderedTag | RenderedBoard],
    family: str = "tag36h11",
    *,
    image: np.ndarray | float | None = None,
    blur_sigma: float = 0.0,
    noise_std: float = 0.0,
    rng: np.random.Generator | None = None,
    supersample: int = 4,
    black_level: float = 30.0,
    white_level: float = 225.0,
    quiet_zone_cells: int = 1,
    shift_pattern: bool = False,
) -> np.ndarray:
    """Render AprilTags and boards into a grayscale image of the camera ``intrinsics``.

    Parameters
    ----------
    intrinsics : CameraIntrinsics
        Camera (any supported distortion model).
    tags : sequence of RenderedTag or RenderedBoard
        Tags and boards with their poses; drawn far to near (painter's order: occlusion is
        exact per sample, except that a nearer item's boundary pixels mix with the farther
        content already averaged over the pixel). Items whose centre is behind the camera, or
        whose face points away from it, are skipped; the part of an item behind the camera is
        not drawn.
    family : str
        AprilTag family of all single tags (boards carry their own dictionary).
    image : ndarray (H, W) or float, optional
        Background: an image of the camera's size (any real dtype, 0..255) or a uniform level;
        default uniform 128.
    blur_sigma : float
        Standard deviation (pixels) of a Gaussian blur applied after rendering (0: none).
    noise_std : float
        Standard deviation of additive Gaussian noise (grey levels) applied after the blur;
        requires ``rng``.
    rng : numpy.random.Generator, optional
        The only source of randomness.
    supersample : int
        Samples per pixel along each axis (>= 1); ``supersample**2`` point samples are averaged.
    black_level, white_level : float
        Grey levels of the black and white tag cells (and board areas).
    quiet_zone_cells : int
        Width of the white border around the black square of a single tag, in cells.
    shift_pattern : bool
        Shift the sample pattern differently in every pixel (:func:`pixel_shifts`): no edge
        direction is resolved coarsely, at the price of a little noise along every edge (the
        demo's images; default False, the fixed lattice of the benchmarks).

    Returns
    -------
    ndarray, shape (H, W), uint8
    """
    W, H = intrinsics.width, intrinsics.height
    if int(supersample) != supersample or supersample < 1:
        raise ValueError(f"supersample must be a positive integer, got {supersample!r}")
    offsets = sample_offsets(int(supersample))
    if not (np.isfinite(blur_sigma) and blur_sigma >= 0):
        raise ValueError(f"blur_sigma must be >= 0, got {blur_sigma!r}")
    if not (np.isfinite(noise_std) and noise_std >= 0):
        raise ValueError(f"noise_std must be >= 0, got {noise_std!r}")
    if noise_std > 0 and rng is None:
        raise ValueError("rng must be given when noise_std > 0")
    if image is None:
        canvas = np.full((H, W), 128.0)
    elif np.ndim(image) == 0:
        canvas = np.full((H, W), float(image))
    else:
        canvas = np.array(image, dtype=float)
        if canvas.shape != (H, W):
            raise ValueError(f"image must have shape {(H, W)}, got {canvas.shape}")

    cells = marker_cells(family)
    extent = cells + 2 * int(quiet_zone_cells)
    for item in sorted(tags, key=lambda it: -float(np.linalg.norm(_pose(it)[:3, 3]))):
        T = _pose(item)
        t = T[:3, 3]
        if t[2] <= 0 or float(T[:3, 2] @ t) >= 0:
            continue  # centre behind the camera, or back face toward the camera
        if isinstance(item, RenderedBoard):
            x0, x1, y0, y1 = item.extent()
            outline = _rectangle_outline(x0, x1, y0, y1)
            lookup = _board_lookup(item, black_level, white_level)
        else:
            outline = tag_outline(item.size, extent, cells)
            lookup = _tag_lookup(item, family, quiet_zone_cells, black_level, white_level)
        _draw_plane(canvas, intrinsics, T, outline, offsets, lookup, shift_pattern)

    if blur_sigma > 0:
        canvas = cv2.GaussianBlur(canvas, (0, 0), sigmaX=float(blur_sigma))
    if noise_std > 0:
        canvas = canvas + rng.normal(0.0, float(noise_std), size=canvas.shape)
    return np.clip(np.rint(canvas), 0, 255).astype(np.uint8)


def _pose(item: RenderedTag | RenderedBoard) -> np.ndarray:
    return item.T_cam_board if isinstance(item, RenderedBoard) else item.T_cam_tag


def _rectangle_outline(
    x0: float, x1: float, y0: float, y1: float, per_edge: int = 16
) -> np.ndarray:
    """Points (4 per_edge, 3) along the rectangle ``[x0, x1] x [y0, y1]`` of a plane ``z = 0``."""
    sx = np.linspace(x0, x1, per_edge + 1)
    sy = np.linspace(y0, y1, per_edge + 1)
    xy = np.concatenate([
        np.c_[sx, np.full_like(sx, y0)],
        np.c_[sx, np.full_like(sx, y1)],
        np.c_[np.full_like(sy, x0), sy],
        np.c_[np.full_like(sy, x1), sy],
    ])
    return np.c_[xy, np.zeros(len(xy))]


def _tag_lookup(tag: RenderedTag, family: str, quiet_zone_cells: int, black: float,
                white: float):
    """``(a, b) -> (levels, inside)`` of one tag with its quiet zone (tag frame, metres)."""
    levels = np.where(marker_bitmap(family, tag.tag_id, quiet_zone_cells) > 127, white, black)
    extent = levels.shape[0]
    cell = tag.size / (extent - 2 * int(quiet_zone_cells))
    half = 0.5 * extent * cell

    def lookup(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        col = np.floor((a + half) / cell)
        row = np.floor((half - b) / cell)
        inside = (col >= 0) & (col < extent) & (row >= 0) & (row < extent)
        ci = np.where(inside, col, 0).astype(np.intp)
        ri = np.where(inside, row, 0).astype(np.intp)
        return levels[ri, ci], inside

    return lookup


def _board_lookup(item: RenderedBoard, black: float, white: float):
    """``(a, b) -> (levels, inside)`` of a board with its white margin (board frame, metres)."""
    x0, x1, y0, y1 = item.extent()

    def lookup(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        inside = (a >= x0) & (a < x1) & (b >= y0) & (b < y1)
        values = np.full(a.shape, white)
        if np.any(inside):
            values[inside] = np.where(item.board.texture(a[inside], b[inside]) > 0, white, black)
        return values, inside

    return lookup


def _draw_plane(canvas: np.ndarray, intrinsics: CameraIntrinsics, T: np.ndarray,
                outline: np.ndarray, offsets: np.ndarray, lookup, shift: bool = False) -> None:
    """Paint a planar item (pose ``T`` = T_cam_item, texture ``lookup``) into ``canvas``."""
    box = _bounding_box(intrinsics, T, outline)
    if box is None:
        return
    u0, v0, u1, v1 = box
    xy = _rays(intrinsics, box, offsets, shift)
    # Ray (x, y, 1) meets the plane {R [a, b, 0] + t}: [a, b, 1] ~ H^-1 [x, y, 1],
    # H = [r1 r2 t]; the third component is positive in front of the camera.
    Hinv = np.linalg.inv(np.c_[T[:3, 0], T[:3, 1], T[:3, 3]])
    rays = np.concatenate([xy, np.ones(xy.shape[:-1] + (1,))], axis=-1)
    abw = rays @ Hinv.T
    w = abw[..., 2]
    front = (w > 0) & np.all(np.isfinite(xy), axis=-1)
    w_safe = np.where(front, w, 1.0)
    a = np.where(front, abw[..., 0] / w_safe, np.inf)
    b = np.where(front, abw[..., 1] / w_safe, np.inf)
    levels, inside = lookup(a, b)
    inside &= front
    samples = np.where(inside, levels, canvas[v0:v1, u0:u1, None])
    canvas[v0:v1, u0:u1] = samples.mean(axis=-1)

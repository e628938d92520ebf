"""Sub-pixel tag corners from straight-line fits to the four edges of the black square.

``cv2.cornerSubPix`` (aruco's ``SUBPIX`` refinement) is built for saddle points; on the convex
corners of a square it is biased by 0.1-0.3 px toward the dark side (measured on rendered images,
see ``benchmarks/perception.md``), and aruco's ``APRILTAG`` refinement inherits the AprilTag
library's pixel-corner convention (a +0.5 px offset in OpenCV's pixel-centre convention). This
module instead locates the edges themselves:

1. sample points along each edge (away from the corners) and read an intensity profile along the
   edge normal, from inside (black border) to outside (white quiet zone), by bilinear
   interpolation (``cv2.remap``);
2. the edge position on each profile is the *area* estimate
   ``e = integral (1 - f(d)) dd - h`` with ``f = (I - I_dark) / (I_white - I_dark)`` over
   ``d in [-h, h]``: exact for an area-sampled straight step (up to the bilinear interpolation)
   and unchanged by blur with any centred, normalised point-spread function narrower than the
   window; levels ``I_dark``/``I_white`` are read at the profile ends;
3. the edge points are undistorted (:meth:`CameraIntrinsics.undistort_points`) and a line is
   fitted to each edge in the ideal pinhole image, where edges are straight (least median of
   squares to find the inliers, then total least squares on them);
4. adjacent lines are intersected; the corners are re-projected into the distorted image and the
   procedure repeated from there while they still move (this follows edges curved by strong
   distortion).
"""

from __future__ import annotations

import cv2
import numpy as np

from .intrinsics import CameraIntrinsics

__all__ = ["refine_corners_edges"]


def _fit_line(points: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Total-least-squares line ``n . p = c`` through points (n, 2); None if degenerate."""
    if points.shape[0] < 3:
        return None
    centre = points.mean(axis=0)
    _, sv, Vt = np.linalg.svd(points - centre, full_matrices=False)
    if sv[0] <= 0:
        return None
    normal = Vt[1]
    return normal, float(normal @ centre)


def _fit_line_robust(
    points: np.ndarray, min_residual_px: float = 0.05, max_candidates: int = 12
) -> tuple[np.ndarray, float] | None:
    """Line fit that ignores a minority of bad edge points (occlusions, dirt, glints).

    Least median of squares over the lines through up to ``max_candidates`` evenly spread point
    pairs ``(i, i + n/2)`` (half an edge apart: well conditioned; deterministic; a contiguous
    run of bad points spoils only some pairs), then a total-least-squares refit to the points
    within 3 robust sigmas (``1.4826`` times that median; residuals below ``min_residual_px`` are
    always kept).
    """
    n = points.shape[0]
    if n < 6:
        return _fit_line(points)
    half = n // 2
    first = np.unique(np.linspace(0, half - 1, min(half, max_candidates)).astype(int))
    a, b = points[first], points[first + half]
    d = b - a
    length = np.linalg.norm(d, axis=1)
    good = length > 1e-9
    if not np.any(good):
        return _fit_line(points)
    normals = np.stack([-d[good, 1], d[good, 0]], axis=1) / length[good, None]
    offsets = np.sum(normals * a[good], axis=1)
    residual = np.abs(points @ normals.T - offsets)  # (n, candidates)
    med = np.median(residual, axis=0)
    best = int(np.argmin(med))
    limit = max(3.0 * 1.4826 * float(med[best]), min_residual_px)
    keep = residual[:, best] <= limit
    if np.count_nonzero(keep) < max(3, half):
        return _fit_line(points)
    return _fit_line(points[keep])


def _intersect(l1: tuple[np.ndarray, float], l2: tuple[np.ndarray, float]) -> np.ndarray | None:
    A = np.array([l1[0], l2[0]])
    det = np.linalg.det(A)
    if abs(det) < 1e-9:
        return None
    return np.linalg.solve(A, np.array([l1[1], l2[1]]))


def _distort(intrinsics: CameraIntrinsics, ideal: np.ndarray) -> np.ndarray:
    """Ideal pinhole pixels (N, 2) -> distorted pixels (N, 2)."""
    if not intrinsics.has_distortion:
        return np.asarray(ideal, dtype=float)
    K = intrinsics.K
    y = (ideal[:, 1] - K[1, 2]) / K[1, 1]
    x = (ideal[:, 0] - K[0, 2] - K[0, 1] * y) / K[0, 0]
    return intrinsics.project_points(np.stack([x, y, np.ones_like(x)], axis=1))


def refine_corners_edges(
    gray: np.ndarray,
    corners: np.ndarray,
    intrinsics: CameraIntrinsics,
    cells: int,
    *,
    max_half_width_px: float = 3.0,
    min_half_width_px: float = 1.0,
    step_px: float = 0.25,
    min_contrast: float = 10.0,
    iterations: int = 3,
    converged_px: float = 0.1,
) -> tuple[np.ndarray, np.ndarray] | None:
    """Refine the four corners of a tag's black square by edge-line fitting.

    Parameters
    ----------
    gray : ndarray, shape (H, W), uint8
        Image.
    corners : ndarray, shape (4, 2)
        Initial corners in distorted pixels (order of ``cv2.aruco``: clockwise in the image),
        within about a pixel of the truth.
    intrinsics : CameraIntrinsics
        Camera model (edges are straight only after undistortion).
    cells : int
        Cells across the black square (8 for tag36h11): the profiles stay within one cell of
        the edge, i.e. inside the black border and the white quiet zone.
    max_half_width_px, min_half_width_px : float
        Half-length of the normal profiles is ``min(max_half_width_px, 0.45 cell)``; below
        ``min_half_width_px`` (tiny tags) the refinement is not attempted.
    step_px : float
        Sampling step along the profiles.
    min_contrast : float
        Minimum white-dark difference (grey levels) of a usable profile.
    iterations : int
        Maximum number of sample / fit rounds (>= 1).
    converged_px : float
        Stop when no corner moved more than this in a round: the area estimate does not depend
        on where the profile is centred, so another round only matters when the sample points
        were far off the edge (a poor seed, or edges curved by distortion).

    Returns
    -------
    (ideal_corners, distorted_corners) : tuple of ndarray (4, 2), or None
        Corners in ideal (undistorted, same ``K``) pixels and in distorted pixels; None when the
        tag is too small or an edge has too few usable profiles (keep the input corners then).
    """
    quad = np.asarray(corners, dtype=float).reshape(4, 2)
    sides = np.linalg.norm(np.roll(quad, -1, axis=0) - quad, axis=1)
    cell_px = float(np.min(sides)) / float(cells)
    h = min(max_half_width_px, 0.45 * cell_px)
    if h < min_half_width_px or not np.all(np.isfinite(quad)):
        return None
    offsets = np.arange(-h, h + 1e-9, step_px)
    n_off = offsets.size
    ends = max(1, int(round(0.5 / step_px)))
    H, W = gray.shape
    # Work on a float crop around the tag (the profiles reach at most h + 3 px beyond the quad).
    pad = int(np.ceil(h + 3.0 + 0.5 * cell_px))
    x0 = max(int(np.floor(quad[:, 0].min())) - pad, 0)
    y0 = max(int(np.floor(quad[:, 1].min())) - pad, 0)
    x1 = min(int(np.ceil(quad[:, 0].max())) + pad + 1, W)
    y1 = min(int(np.ceil(quad[:, 1].max())) + pad + 1, H)
    if x1 - x0 < 2 or y1 - y0 < 2:
        return None
    crop = np.asarray(gray[y0:y1, x0:x1], dtype=np.float32)
    origin = np.array([x0, y0], dtype=float)
    n_per_edge = int(np.clip(np.max(sides) / 2.0, 8, 64))
    fractions = np.linspace(0.12, 0.88, n_per_edge)
    ideal_corners = intrinsics.undistort_points(quad)
    for _ in range(max(1, int(iterations))):
        a = ideal_corners
        b = np.roll(ideal_corners, -1, axis=0)
        ideal_pts = (a[:, None, :] + fractions[None, :, None] * (b - a)[:, None, :]).reshape(-1, 2)
        step_dir = np.repeat(b - a, n_per_edge, axis=0)
        # Sample points and local edge directions in the distorted image.
        both = _distort(intrinsics, np.concatenate([ideal_pts, ideal_pts + 1e-3 * step_dir]))
        pts, ahead = both[: len(ideal_pts)], both[len(ideal_pts) :]
        tangent = ahead - pts
        tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
        # Clockwise quad in image coordinates (y down): the outward normal is (t_y, -t_x).
        normal = np.stack([tangent[:, 1], -tangent[:, 0]], axis=1)
        samples = pts[:, None, :] + offsets[None, :, None] * normal[:, None, :] - origin
        profiles = cv2.remap(
            crop,
            np.ascontiguousarray(samples[..., 0], dtype=np.float32),
            np.ascontiguousarray(samples[..., 1], dtype=np.float32),
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=-1.0,
        ).astype(float)
        in_image = (
            (samples[..., 0] >= 0)
            & (samples[..., 0] <= crop.shape[1] - 1)
            & (samples[..., 1] >= 0)
            & (samples[..., 1] <= crop.shape[0] - 1)
        ).all(axis=1)
        dark = profiles[:, :ends].mean(axis=1)
        white = profiles[:, n_off - ends :].mean(axis=1)
        contrast = white - dark
        ok = in_image & (contrast >= min_contrast)
        f = np.clip((profiles - dark[:, None]) / np.where(ok, contrast, 1.0)[:, None], 0.0, 1.0)
        g = 1.0 - f
        e = step_px * (g[:, 1:] + g[:, :-1]).sum(axis=1) / 2.0 - h
        ok &= np.abs(e) < h - 0.5 * step_px
        edge_pts = intrinsics.undistort_points(pts + e[:, None] * normal)
        edge_of = np.repeat(np.arange(4), n_per_edge)
        lines = []
        for i in range(4):
            sel = ok & (edge_of == i)
            line = _fit_line_robust(edge_pts[sel]) if np.count_nonzero(sel) >= 3 else None
            if line is None:
                return None
            lines.append(line)
        new = []
        for i in range(4):
            c = _intersect(lines[(i - 1) % 4], lines[i])
            if c is None:
                return None
            new.append(c)
        new_ideal = np.array(new)
        moved = float(np.max(np.linalg.norm(new_ideal - ideal_corners, axis=1)))
        if not np.isfinite(moved) or moved > max(3.0, 0.5 * cell_px):
            return None
        ideal_corners = new_ideal
        if moved < converged_px:
            break
    return ideal_corners, _distort(intrinsics, ideal_corners)

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


def _fit_lines(
    points: np.ndarray, weights: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Total-least-squares lines ``n . p = c`` through weighted point sets, all edges at once.

    Parameters
    ----------
    points : ndarray, shape (E, N, 2)
    weights : ndarray, shape (E, N)
        1 for the points of each set, 0 for padding.

    Returns
    -------
    normals : ndarray, shape (E, 2)
        Unit normals (eigenvector of the smallest eigenvalue of the scatter matrix).
    offsets : ndarray, shape (E,)
    ok : ndarray of bool, shape (E,)
        At least 3 points and a non-degenerate spread.
    """
    count = weights.sum(axis=1)
    centre = np.einsum("en,enk->ek", weights, points) / np.maximum(count, 1.0)[:, None]
    d = (points - centre[:, None, :]) * np.sqrt(weights)[..., None]
    scatter = np.einsum("eni,enj->eij", d, d)
    values, vectors = np.linalg.eigh(scatter)
    normals = vectors[:, :, 0]
    ok = (count >= 3) & (values[:, 1] > 0)
    return normals, np.einsum("ek,ek->e", normals, centre), ok


def _fit_lines_robust(
    points: np.ndarray,
    valid: np.ndarray,
    min_residual_px: float = 0.05,
    max_candidates: int = 12,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Line fits that ignore a minority of bad edge points (occlusions, dirt, glints).

    Per edge: least median of squares over the lines through up to ``max_candidates`` evenly
    spread pairs ``(i, i + n/2)`` of its ``n`` valid points (half an edge apart: well
    conditioned; deterministic; a contiguous run of bad points spoils only some pairs), then a
    total-least-squares refit to the points within 3 robust sigmas (``1.4826`` times that median;
    residuals below ``min_residual_px`` are always kept). Edges with fewer than 6 valid points,
    no usable pair or too few inliers (< ``max(3, n/2)``) get the plain fit of all valid points.
    All edges are processed together (the work per tag is dominated by call overhead).

    Parameters
    ----------
    points : ndarray, shape (E, N, 2)
        Edge points; only those with ``valid`` count, in their order along the edge.
    valid : ndarray of bool, shape (E, N)

    Returns
    -------
    normals (E, 2), offsets (E,), ok (E,) : as :func:`_fit_lines`.
    """
    n_edges, n_max = valid.shape
    rows = np.arange(n_edges)
    rows2 = rows[:, None]
    # Valid points first, in their order (stable sort), padding after them.
    pts = points[rows2, np.argsort(~valid, axis=1, kind="stable")]
    n = valid.sum(axis=1)
    is_point = np.arange(n_max) < n[:, None]
    # Candidate pairs: np.linspace(0, half - 1, k).astype(int) with k = min(half, max_candidates).
    half = n // 2
    k = np.minimum(half, max_candidates)
    j = np.arange(max_candidates)
    step = (half - 1) / np.maximum(k - 1, 1)
    first = np.where(j == k[:, None] - 1, half[:, None] - 1, (j * step[:, None]).astype(int))
    first = np.clip(first, 0, np.maximum(half - 1, 0)[:, None])  # (unused candidates j >= k)
    a = pts[rows2, first]
    d = pts[rows2, np.minimum(first + half[:, None], n_max - 1)] - a
    length = np.hypot(d[..., 0], d[..., 1])
    good = (j < k[:, None]) & (length > 1e-9)
    normals = d[..., ::-1] * (-1.0, 1.0) / np.where(good, length, 1.0)[..., None]
    offsets = np.einsum("eck,eck->ec", normals, a)
    residual = np.abs(np.einsum("enk,eck->enc", pts, normals) - offsets[:, None, :])
    # Median over each edge's valid points: padding sorts last as +inf.
    ranked = np.sort(np.where(is_point[..., None], residual, np.inf), axis=1)
    lo = np.maximum((n - 1) // 2, 0)
    med = 0.5 * (ranked[rows, lo] + ranked[rows, np.minimum(n // 2, n_max - 1)])
    med = np.where(good, med, np.inf)
    best = np.argmin(med, axis=1)
    limit = np.maximum(3.0 * 1.4826 * med[rows, best], min_residual_px)
    keep = is_point & (residual[rows, :, best] <= limit[:, None])
    robust = (n >= 6) & good.any(axis=1) & (keep.sum(axis=1) >= np.maximum(3, half))
    weights = np.where(robust[:, None], keep, is_point).astype(float)
    return _fit_lines(pts, weights)


def _intersect(
    n1: np.ndarray, c1: np.ndarray, n2: np.ndarray, c2: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Intersections (E, 2) of lines ``n1 . p = c1`` and ``n2 . p = c2`` (normals (E, 2)), and
    whether each is well defined (lines not parallel)."""
    det = n1[:, 0] * n2[:, 1] - n1[:, 1] * n2[:, 0]
    ok = np.abs(det) >= 1e-9
    det = np.where(ok, det, 1.0)
    x = (c1 * n2[:, 1] - c2 * n1[:, 1]) / det
    y = (n1[:, 0] * c2 - n2[:, 0] * c1) / det
    return np.column_stack([x, y]), ok


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
    following = [1, 2, 3, 0]
    for _ in range(max(1, int(iterations))):
        a = ideal_corners
        b = ideal_corners[following]
        ideal_pts = (a[:, None, :] + fractions[None, :, None] * (b - a)[:, None, :]).reshape(-1, 2)
        step_dir = np.repeat(b - a, n_per_edge, axis=0)
        # Sample points and local edge directions in the distorted image.
        both = _distort(intrinsics, np.concatenate([ideal_pts, ideal_pts + 1e-3 * step_dir]))
        pts, ahead = both[: len(ideal_pts)], both[len(ideal_pts) :]
        tangent = ahead - pts
        tangent /= np.hypot(tangent[:, 0], tangent[:, 1])[:, None]
        # Clockwise quad in image coordinates (y down): the outward normal is (t_y, -t_x).
        normal = tangent[:, ::-1] * (1.0, -1.0)
        samples = pts[:, None, :] + offsets[None, :, None] * normal[:, None, :] - origin
        profiles = cv2.remap(
            crop,
            np.ascontiguousarray(samples[..., 0], dtype=np.float32),
            np.ascontiguousarray(samples[..., 1], dtype=np.float32),
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=-1.0,
        ).astype(float)
        # A profile is a straight segment: inside the crop iff both of its ends are.
        ends_xy = samples[:, [0, -1], :]
        inside = (ends_xy >= 0.0) & (ends_xy <= (crop.shape[1] - 1, crop.shape[0] - 1))
        in_image = inside.all(axis=(1, 2))
        dark = profiles[:, :ends].mean(axis=1)
        white = profiles[:, n_off - ends :].mean(axis=1)
        contrast = white - dark
        ok = in_image & (contrast >= min_contrast)
        f = np.clip((profiles - dark[:, None]) / np.where(ok, contrast, 1.0)[:, None], 0.0, 1.0)
        g = 1.0 - f
        e = step_px * (g[:, 1:] + g[:, :-1]).sum(axis=1) / 2.0 - h
        ok &= np.abs(e) < h - 0.5 * step_px
        edge_pts = intrinsics.undistort_points(pts + e[:, None] * normal)
        normals, line_c, fitted = _fit_lines_robust(
            edge_pts.reshape(4, n_per_edge, 2), ok.reshape(4, n_per_edge)
        )
        if not np.all(fitted):
            return None
        # Corner i is where the line of edge i - 1 meets that of edge i.
        prev = [3, 0, 1, 2]
        new_ideal, crossed = _intersect(normals[prev], line_c[prev], normals, line_c)
        if not np.all(crossed):
            return None
        shift = new_ideal - ideal_corners
        moved = float(np.max(np.hypot(shift[:, 0], shift[:, 1])))
        if not np.isfinite(moved) or moved > max(3.0, 0.5 * cell_px):
            return None
        ideal_corners = new_ideal
        if moved < converged_px:
            break
    return ideal_corners, _distort(intrinsics, ideal_corners)

"""Tag candidate search on a decimated image, corners refined at full resolution.

``cv2.aruco``'s candidate search (adaptive thresholds at three window sizes, contours, polygon
fits, decoding) costs time proportional to the pixel count, although the quads it finds only
need to be good to about a pixel: the corners are refined afterwards. With a decimation factor
``d > 1`` (:attr:`DetectorConfig.decimate <rwhec_ros.vision.detection.DetectorConfig>`):

1. the image is shrunk by ``d`` in both directions (``cv2.resize`` with ``INTER_AREA``: the mean
   of each ``d x d`` block, which also averages the noise down);
2. ``cv2.aruco`` finds and decodes the tags in the small image, with its ``SUBPIX`` refinement
   there;
3. the corners are mapped back to full-resolution pixels (pixel *centres* correspond:
   ``u = (u_small + 0.5) s_x - 0.5`` with ``s_x`` the width ratio, likewise ``v``) and refined
   at full resolution with ``cv2.cornerSubPix`` using aruco's own window rule
   (:func:`refine_corners_subpix`), so the detector continues from the same kind of corners as
   without decimation (for ``corner_refinement="edge"`` the edge-line fit of
   :mod:`rwhec_ros.vision.edges` then runs at full resolution, as always).

Decimation raises the smallest decodable tag by the factor ``d`` (decoding needs about two
pixels per cell in the searched image; measured in ``benchmarks/perception.md``), which is why
``"auto"`` decimates only large images. Candidates whose side in the searched image is below one
pixel per cell cannot be decoded and are not examined (:func:`min_perimeter_rate`); without that
floor the noise of a small image yields hundreds of tiny quads that cost more to reject than the
decimation saves.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = [
    "AUTO_DECIMATE_MIN_SIDE_PX",
    "check_decimate",
    "decimation_factor",
    "decimate_image",
    "corners_to_full_resolution",
    "min_perimeter_rate",
    "refine_corners_subpix",
]

#: ``decimate="auto"``: the largest integer factor that keeps the shrunk image's longer side at
#: least this long (so 1280x1024 -> 2, 640x480 -> 1, 2448x2048 -> 3).
AUTO_DECIMATE_MIN_SIDE_PX = 600


def check_decimate(decimate: int | str) -> int | str:
    """Validate a ``decimate`` option: ``"auto"`` or an integer ``>= 1``; returns it normalised.

    Raises
    ------
    ValueError
        Naming the field and the value.
    """
    if isinstance(decimate, str):
        if decimate.strip().lower() == "auto":
            return "auto"
        raise ValueError(f"decimate must be 'auto' or an integer >= 1, got {decimate!r}")
    if isinstance(decimate, bool) or not isinstance(decimate, (int, np.integer, float)):
        raise ValueError(f"decimate must be 'auto' or an integer >= 1, got {decimate!r}")
    if not np.isfinite(decimate) or int(decimate) != decimate or int(decimate) < 1:
        raise ValueError(f"decimate must be 'auto' or an integer >= 1, got {decimate!r}")
    return int(decimate)


def decimation_factor(decimate: int | str, width: int, height: int) -> int:
    """The integer factor for an image of ``width x height`` pixels.

    ``"auto"`` gives ``max(1, max(width, height) // AUTO_DECIMATE_MIN_SIDE_PX)``; an integer is
    returned unchanged, but never so large that the shrunk image is smaller than 16 pixels on its
    shorter side (nothing could be decoded there).
    """
    decimate = check_decimate(decimate)
    if decimate == "auto":
        factor = max(1, max(int(width), int(height)) // AUTO_DECIMATE_MIN_SIDE_PX)
    else:
        factor = int(decimate)
    return max(1, min(factor, min(int(width), int(height)) // 16))


def decimate_image(gray: np.ndarray, factor: int) -> np.ndarray:
    """``gray`` (H, W) shrunk to ``(H // factor, W // factor)`` by area averaging (``INTER_AREA``).

    The last ``W % factor`` columns / ``H % factor`` rows are spread over the others (the scale is
    the exact size ratio, see :func:`corners_to_full_resolution`). ``factor == 1`` returns
    ``gray`` itself.
    """
    if factor == 1:
        return gray
    h, w = gray.shape[:2]
    return cv2.resize(gray, (w // factor, h // factor), interpolation=cv2.INTER_AREA)


def corners_to_full_resolution(
    corners: np.ndarray, small_shape: tuple[int, int], full_shape: tuple[int, int]
) -> np.ndarray:
    """Map pixel coordinates (..., 2) of the shrunk image to the full image.

    Pixel centres correspond under ``cv2.resize``: ``u = (u_s + 0.5) W / w - 0.5`` and
    ``v = (v_s + 0.5) H / h - 0.5`` with ``(h, w) = small_shape``, ``(H, W) = full_shape``.
    """
    scale = np.array([full_shape[1] / small_shape[1], full_shape[0] / small_shape[0]], dtype=float)
    return (np.asarray(corners, dtype=float) + 0.5) * scale - 0.5


def min_perimeter_rate(cells: int, width: int, height: int, floor: float = 0.01) -> float:
    """``minMarkerPerimeterRate`` for a searched image of ``width x height``: quads of at least one
    pixel per cell (perimeter ``4 cells``), or the ``floor`` rate if that is larger."""
    return max(float(floor), 4.0 * int(cells) / max(int(width), int(height)))


def refine_corners_subpix(
    gray: np.ndarray,
    corners: np.ndarray,
    cells: int,
    params: cv2.aruco.DetectorParameters,
) -> np.ndarray:
    """``cv2.cornerSubPix`` on the four corners (4, 2) of one tag at full resolution.

    The same window rule and termination as aruco's ``CORNER_REFINE_SUBPIX`` (OpenCV 4.7+):
    half-window ``min(cornerRefinementWinSize, max(1, round(relativeCornerRefinmentWinSize *
    module)))`` with ``module`` the mean side of the quad divided by ``cells`` (aruco's
    ``markerSize + 2 markerBorderBits``), ``cornerRefinementMaxIterations`` iterations or steps
    below ``cornerRefinementMinAccuracy`` pixels.

    Parameters
    ----------
    gray : ndarray, shape (H, W), uint8
    corners : ndarray, shape (4, 2)
        Corners in full-resolution pixels (e.g. from :func:`corners_to_full_resolution`).
    cells : int
        Cells across the black square (:func:`rwhec_ros.vision.families.marker_cells`).
    params : cv2.aruco.DetectorParameters
        Window and termination settings.

    Returns
    -------
    ndarray, shape (4, 2), float
    """
    quad = np.ascontiguousarray(np.asarray(corners, dtype=np.float32).reshape(4, 1, 2))
    module = float(np.mean(np.linalg.norm(quad[:, 0] - np.roll(quad[:, 0], -1, axis=0), axis=1)))
    module /= float(cells)
    win = max(1, int(round(float(params.relativeCornerRefinmentWinSize) * module)))
    win = min(win, int(params.cornerRefinementWinSize))
    criteria = (
        cv2.TERM_CRITERIA_MAX_ITER | cv2.TERM_CRITERIA_EPS,
        int(params.cornerRefinementMaxIterations),
        float(params.cornerRefinementMinAccuracy),
    )
    cv2.cornerSubPix(gray, quad, (win, win), (-1, -1), criteria)
    return quad.reshape(4, 2).astype(float)

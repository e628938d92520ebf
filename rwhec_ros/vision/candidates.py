"""Tag candidate search with ``cv2.aruco``, optionally on a decimated image.

:class:`CandidateSearch` is the first stage of :class:`rwhec_ros.vision.detection.TagDetector`:
tag ids and their four corners, before corner refinement, pose and gates.

Decimation
----------

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
   :mod:`rwhec_ros.vision.edges` then runs at full resolution, as always);
4. a tag with fewer than :data:`REDETECT_BELOW_PX_PER_CELL` pixels per cell in the searched image
   is instead searched again at full resolution in a window around it
   (:func:`redetect_in_window`): its mapped corners can be several pixels off (the corner window
   of ``cornerSubPix`` is then smaller than that error, measured up to 4 px), which the edge fit
   cannot always recover and which can still pass the reprojection gate with a wrong pose.

Decimation raises the smallest decodable tag by the factor ``d`` (decoding is reliable from
about 2.3 pixels per cell in the searched image, i.e. sides of about ``18 d`` pixels for
tag36h11; measured in ``benchmarks/perception.md``), which is why ``"auto"`` decimates only large
images. Candidates whose side in the searched image is below one
pixel per cell cannot be decoded and are not examined (:func:`min_perimeter_rate`); without that
floor the noise of a small image yields hundreds of tiny quads that cost more to reject than the
decimation saves.
"""

from __future__ import annotations

import cv2
import numpy as np

from .families import aruco_dictionary

__all__ = [
    "CandidateSearch",
    "AUTO_DECIMATE_MIN_SIDE_PX",
    "check_decimate",
    "decimation_factor",
    "decimate_image",
    "corners_to_full_resolution",
    "min_perimeter_rate",
    "refine_corners_subpix",
    "REDETECT_BELOW_PX_PER_CELL",
    "redetect_in_window",
]

#: ``decimate="auto"``: the largest integer factor that keeps the shrunk image's longer side at
#: least this long (so 1280x1024 -> 2, 640x480 -> 1, 2448x2048 -> 3).
AUTO_DECIMATE_MIN_SIDE_PX = 600

#: Tags with fewer pixels per cell than this in the searched image are searched again at full
#: resolution around their position (step 4 of the module docstring). Mapped corners were within
#: 0.4 px of the truth down to about 3 px per cell and up to 4 px off below that
#: (``benchmarks/perception.md``); 4 keeps a margin.
REDETECT_BELOW_PX_PER_CELL = 4.0


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


def redetect_in_window(
    detector: cv2.aruco.ArucoDetector,
    params: cv2.aruco.DetectorParameters,
    gray: np.ndarray,
    corners: np.ndarray,
    tag_id: int,
    cells: int,
) -> np.ndarray | None:
    """Find tag ``tag_id`` again at full resolution in a window around its approximate corners.

    The window is the quad's bounding box grown by two cells (the quiet zone and more), half the
    largest adaptive-threshold window and aruco's border margin, so that the search inside it
    sees the tag as the full-image search would.

    Parameters
    ----------
    detector : cv2.aruco.ArucoDetector
        Used for the window search; its parameters are replaced by ``params`` with
        ``minMarkerPerimeterRate`` scaled to the window (one pixel per cell).
    params : cv2.aruco.DetectorParameters
        The full-resolution parameters (refinement, thresholds).
    gray : ndarray, shape (H, W), uint8
        Full-resolution image.
    corners : ndarray, shape (4, 2)
        Approximate corners (full-resolution pixels).
    tag_id : int
        The id decoded in the decimated image.
    cells : int
        Cells across the black square.

    Returns
    -------
    ndarray, shape (4, 2), or None
        The corners found in the window (full-image pixels), or None when the window search
        does not find ``tag_id`` within one side of the approximate centre.
    """
    quad = np.asarray(corners, dtype=float).reshape(4, 2)
    side = float(np.mean(np.linalg.norm(quad - np.roll(quad, -1, axis=0), axis=1)))
    margin = 2.0 * side / cells + 0.5 * params.adaptiveThreshWinSizeMax
    margin += params.minDistanceToBorder + 2.0
    height, width = gray.shape
    x0 = max(int(np.floor(quad[:, 0].min() - margin)), 0)
    y0 = max(int(np.floor(quad[:, 1].min() - margin)), 0)
    x1 = min(int(np.ceil(quad[:, 0].max() + margin)) + 1, width)
    y1 = min(int(np.ceil(quad[:, 1].max() + margin)) + 1, height)
    if x1 - x0 < 8 or y1 - y0 < 8:
        return None
    window = np.ascontiguousarray(gray[y0:y1, x0:x1])
    local = _copy_parameters(params)
    local.minMarkerPerimeterRate = min_perimeter_rate(cells, x1 - x0, y1 - y0)
    detector.setDetectorParameters(local)
    found, ids, _ = detector.detectMarkers(window)
    if ids is None:
        return None
    centre = quad.mean(axis=0) - (x0, y0)
    best, best_distance = None, side
    for candidate, candidate_id in zip(found, np.asarray(ids).reshape(-1), strict=True):
        c = np.asarray(candidate, dtype=float).reshape(4, 2)
        distance = float(np.linalg.norm(c.mean(axis=0) - centre))
        if int(candidate_id) == int(tag_id) and distance < best_distance:
            best, best_distance = c, distance
    return None if best is None else best + (x0, y0)


class CandidateSearch:
    """``cv2.aruco`` detection of one family, at full resolution or decimated.

    Holds one ``cv2.aruco.ArucoDetector`` per searched image size (their smallest examined quad
    has one pixel per cell, :func:`min_perimeter_rate`, unless the parameters were given one
    explicitly) and one for window searches; not thread-safe (one per thread, like
    :class:`~rwhec_ros.vision.detection.TagDetector`).

    Parameters
    ----------
    family : str
        AprilTag family or ArUco dictionary.
    params : cv2.aruco.DetectorParameters
        Full-resolution parameters (refinement, thresholds, overrides).
    fixed_min_perimeter : bool
        ``params.minMarkerPerimeterRate`` was set by the user: keep it for every searched size.
    """

    def __init__(
        self, family: str, params: cv2.aruco.DetectorParameters, fixed_min_perimeter: bool = False
    ) -> None:
        self._dictionary = aruco_dictionary(family)
        self._cells = int(self._dictionary.markerSize) + 2
        self._params = params
        self._fixed_min_perimeter = bool(fixed_min_perimeter)
        self._detectors: dict[tuple[int, int], cv2.aruco.ArucoDetector] = {}
        self._window_detector: cv2.aruco.ArucoDetector | None = None

    def find(self, gray: np.ndarray, factor: int = 1) -> tuple[list[int], list[np.ndarray]]:
        """Tag ids and corners (4, 2) in full-resolution pixels (steps 1-4 of the module
        docstring for ``factor > 1``; aruco's own refinement at full resolution otherwise).

        Parameters
        ----------
        gray : ndarray, shape (H, W), uint8, C-contiguous
        factor : int
            Decimation factor (:func:`decimation_factor`).
        """
        searched = decimate_image(gray, factor)
        corners, ids, _ = self._aruco(searched.shape).detectMarkers(searched)
        if ids is None or len(ids) == 0:
            return [], []
        ids_list = [int(i) for i in np.asarray(ids).reshape(-1)]
        quads = [np.asarray(c, dtype=float).reshape(4, 2) for c in corners]
        if factor == 1:
            return ids_list, quads
        kept_ids, kept = [], []
        for tag_id, quad in zip(ids_list, quads, strict=True):
            full = corners_to_full_resolution(quad, searched.shape, gray.shape)
            side = np.min(np.linalg.norm(quad - np.roll(quad, -1, axis=0), axis=1))
            if side >= REDETECT_BELOW_PX_PER_CELL * self._cells:
                found = refine_corners_subpix(gray, full, self._cells, self._params)
            else:
                if self._window_detector is None:
                    self._window_detector = cv2.aruco.ArucoDetector(self._dictionary, self._params)
                found = redetect_in_window(
                    self._window_detector, self._params, gray, full, tag_id, self._cells
                )
            if found is not None:  # else a full-resolution search would not find it either
                kept_ids.append(tag_id)
                kept.append(found)
        return kept_ids, kept

    def _aruco(self, shape: tuple[int, ...]) -> cv2.aruco.ArucoDetector:
        """The detector for a searched image of ``shape`` (H, W), created once per shape."""
        key = (int(shape[0]), int(shape[1]))
        detector = self._detectors.get(key)
        if detector is None:
            params = _copy_parameters(self._params)
            if not self._fixed_min_perimeter:
                params.minMarkerPerimeterRate = min_perimeter_rate(
                    self._cells, key[1], key[0], self._params.minMarkerPerimeterRate
                )
            detector = cv2.aruco.ArucoDetector(self._dictionary, params)
            self._detectors[key] = detector
        return detector


def _copy_parameters(params: cv2.aruco.DetectorParameters) -> cv2.aruco.DetectorParameters:
    """A copy of ``cv2.aruco.DetectorParameters`` (the binding has no copy constructor)."""
    copy = cv2.aruco.DetectorParameters()
    for name in dir(params):
        if not name.startswith("_") and not callable(getattr(params, name)):
            setattr(copy, name, getattr(params, name))
    return copy

"""Find a chessboard or a circle grid in an image and label its points, without silent flips or
shifts (layouts: :mod:`rwhec_ros.vision.grids`).

Per board (:meth:`GridFinder.find`):

1. **search** -- chessboards: ``cv2.findChessboardCornersSB`` (OpenCV's sector-based detector,
   ``CALIB_CB_NORMALIZE_IMAGE | CALIB_CB_EXHAUSTIVE``) with the configured size; its corners are
   used as found (``chessboard_refinement: sb``, the more accurate on the real chessboard set,
   ``benchmarks/real_data.md``) or polished by ``cv2.cornerSubPix`` with a window of 0.4 times
   the shortest corner spacing (``subpix``, the more accurate on renders at an angle). Where it
   finds no whole board, it searches again without ``CALIB_CB_NORMALIZE_IMAGE`` (the equalised
   histogram hid the whole board in 3 of 20 real 1280x960 views of leo038/hand_eye_calibrate,
   which OpenCV's default flags find with all 88 corners). When the whole board is still not
   found, the same detector with ``CALIB_CB_LARGER`` and a 3 x 3 minimum looks for a part of it
   (a large board on a real arm is often seen only in part); a part whose
   square colours do not show the chessboard pattern clearly counts as nothing found. Circle grids:
   ``cv2.findCirclesGrid`` (symmetric or asymmetric) with a blob detector that accepts circles
   of any size from 8 px area to a twentieth of the image.
2. **labels** -- OpenCV's point order may start at any corner of the grid and run either way.
   Every turn and mirror of the found grid that fits on the board is tried at every offset:
   kept are those seen from the printed side (the image of the board's ``x`` and ``y`` axes
   must keep their orientation, ``z`` toward the camera) whose pattern matches -- a chessboard's
   square colours (sampled at the square centres), the larger origin circle at the bottom-left
   corner (blob size over the local spacing), the asymmetric grid's layout (homography fit).
   One candidate left: labelled (always so for a whole board of a layout whose pattern fixes
   the order). A whole turn-symmetric board (a chessboard with both square counts even or both
   odd, a symmetric circle grid without an origin circle) leaves two, the board and the board
   turned by 180 degrees: without a predicted pose the one whose ``x`` axis runs more to the
   image's right is taken (``how = "turn_symmetric"``), and the pose stream tells across views
   which views are turned (:mod:`rwhec_ros.sync.board_turns`).
   None: ``ambiguous_orientation``. Several (a part of a plain
   chessboard: the colours halve the shifts, but a part turned by 180 degrees and shifted
   matches them too): a predicted ``T_cam_board`` picks the one whose points lie nearest its
   projection when that is clearly nearer than the next (within a third of a square, the next
   at least twice as far); otherwise ``partial_view``: never a view shifted by a square.
3. **circle centres** (circle grids) -- a circle seen at an angle is an ellipse whose centre is
   not the image of the circle's centre. After a first pose the offset of each circle (the
   centroid of its projected disk minus the projection of its centre, from 32 boundary points
   through the camera model) is subtracted from the detected centre, and the pose solved again
   (:func:`centre_bias`); the diameter is the configured one or, unset, measured from the blobs
   (their diameter over the local spacing in the image).

The labelled points go to :func:`rwhec_ros.vision.board_detection.board_observation` (pose,
outliers, flip check, gates, precision) like those of the marker boards.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .detector_config import CHESSBOARD_REFINEMENTS, DetectorConfig, RejectReason
from .grids import ChessboardSpec, CircleGridSpec
from .intrinsics import CameraIntrinsics
from .planar_pose import solve_planar_pose
from .targets import TargetRejection, TargetSpec

__all__ = ["GridFinder", "GridPoints", "centre_bias", "CHESSBOARD_REFINEMENTS", "SB_FLAGS",
           "SB_RETRY_FLAGS"]

#: ``findChessboardCornersSB`` flags of the search.
SB_FLAGS = cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE
#: Flags of the second search for the whole board, where the first found none (no histogram
#: equalisation: OpenCV's own default finds such boards).
SB_RETRY_FLAGS = cv2.CALIB_CB_EXHAUSTIVE
#: Seed of OpenCV's RNG before each sector-based search (:meth:`GridFinder._chessboard`).
SB_RNG_SEED = 0
_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 50, 1e-3)
#: Least |colour score| (fraction of the black-white contrast sampled) for a chessboard order.
_MIN_COLOUR_SCORE = 0.3
#: Least ratio of the origin circle's size to the next corner circle's.
_MIN_ORIGIN_RATIO = 1.25


@dataclass(eq=False)
class GridPoints:
    """A labelled grid: ``image_points`` (N, 2) distorted pixels, ``object_points`` (N, 3)
    board frame, ``ideal`` (N, 2) undistorted pixels; ``partial`` when only part of the board
    was found; ``how`` the way the labels were fixed (``"pattern"``, ``"prediction"`` or
    ``"turn_symmetric"``: one of a turn-symmetric board's two labellings, the pose stream tells
    which views are turned, :mod:`rwhec_ros.sync.board_turns`)."""

    image_points: np.ndarray
    object_points: np.ndarray
    ideal: np.ndarray
    partial: bool = False
    how: str = "pattern"


def _dihedral(g: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The 8 turns and mirrors of a (h, w, ...) grid, with the index maps (h', w') into the
    flattened original."""
    idx = np.arange(g.shape[0] * g.shape[1]).reshape(g.shape[:2])
    out = []
    for mirror in (False, True):
        a, i = (g[:, ::-1], idx[:, ::-1]) if mirror else (g, idx)
        for k in range(4):
            out.append((np.rot90(a, k), np.rot90(i, k)))
    return out


def _handed(ideal: np.ndarray) -> bool:
    """The grid (h, w, 2) of undistorted points is seen from the printed side: along ``a``
    (axis 1, board ``x``) and ``b`` (axis 0, board ``-y``) the image turns as the board's
    upright view (module docstring of :mod:`rwhec_ros.vision.grids`)."""
    e_a = np.mean(ideal[:, -1] - ideal[:, 0], axis=0)
    e_b = np.mean(ideal[-1, :] - ideal[0, :], axis=0)
    return float(e_a[0] * e_b[1] - e_a[1] * e_b[0]) > 0


def _sample(gray: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Bilinear grey levels at ``points`` (n, 2) (mean over a 3 x 3 pixel neighbourhood)."""
    img = cv2.blur(gray, (3, 3)).astype(np.float32)
    p = np.asarray(points, dtype=np.float32).reshape(-1, 1, 2)
    out = cv2.remap(img, p[..., 0], p[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return out.reshape(-1).astype(float)


def _colour_score(gray: np.ndarray, g: np.ndarray) -> float:
    """How well a labelled corner grid (h, w, 2), distorted pixels, matches "square between
    corners (a, b) and (a+1, b+1) black iff a + b even": +1 perfect, -1 the other parity."""
    centres = 0.25 * (g[:-1, :-1] + g[1:, :-1] + g[:-1, 1:] + g[1:, 1:])
    values = _sample(gray, centres.reshape(-1, 2)).reshape(centres.shape[:2])
    b, a = np.indices(values.shape)
    black = (a + b) % 2 == 0
    if not black.any() or black.all():
        return 0.0
    contrast = float(np.percentile(values, 90) - np.percentile(values, 10))
    if contrast <= 0:
        return 0.0
    return float(values[~black].mean() - values[black].mean()) / contrast


def centre_bias(centres_m: np.ndarray, radii_m: np.ndarray, T_cam_board: np.ndarray,
                intrinsics: CameraIntrinsics, n_boundary: int = 32) -> np.ndarray:
    """Offsets (N, 2) [px] of the image centroids of circles (board-frame centres (N, 3),
    radii (N,)) from the images of their centres, seen at ``T_cam_board`` through the camera
    model (distortion included): the centroid of the polygon of ``n_boundary`` projected
    boundary points, minus the projected centre."""
    c = np.asarray(centres_m, dtype=float).reshape(-1, 3)
    r = np.asarray(radii_m, dtype=float).reshape(-1)
    th = np.linspace(0.0, 2.0 * np.pi, n_boundary, endpoint=False)
    ring = np.stack([np.cos(th), np.sin(th), np.zeros_like(th)], axis=1)
    pts = c[:, None, :] + r[:, None, None] * ring[None]
    uv = intrinsics.project_points(pts.reshape(-1, 3), T_cam_board).reshape(len(c), -1, 2)
    x, y = uv[..., 0], uv[..., 1]
    xn, yn = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1)
    cross = x * yn - xn * y
    area = 0.5 * cross.sum(axis=1)
    cx = ((x + xn) * cross).sum(axis=1) / (6.0 * area)
    cy = ((y + yn) * cross).sum(axis=1) / (6.0 * area)
    return np.stack([cx, cy], axis=1) - intrinsics.project_points(c, T_cam_board)


class GridFinder:
    """Finds one chessboard or circle-grid target (module docstring). Holds a blob detector:
    not thread-safe, one per thread (like :class:`~.target_detector.TargetDetector`).

    Parameters
    ----------
    target : TargetSpec
        Its ``board`` a :class:`~.grids.ChessboardSpec` or :class:`~.grids.CircleGridSpec`.
    config : DetectorConfig
        ``chessboard_refinement``.
    """

    def __init__(self, target: TargetSpec, config: DetectorConfig) -> None:
        if not isinstance(target.board, (ChessboardSpec, CircleGridSpec)):
            raise ValueError(f"target {target.name!r} is not a chessboard or circle grid")
        self.target = target
        self.spec = target.board
        self.config = config
        self._blobs = None
        self._keypoints = ()
        self._origin_ratio = 1.0

    # ------------------------------------------------------------------ public
    def find(self, gray: np.ndarray, intrinsics: CameraIntrinsics,
             predicted: np.ndarray | None = None
             ) -> tuple[GridPoints | None, list[TargetRejection], np.ndarray | None]:
        """Search, label (module docstring).

        Returns
        -------
        points : GridPoints or None
            The labelled points, None when nothing usable was found.
        rejections : list of TargetRejection
            Why a grid that was found gave no points (``partial_view``,
            ``ambiguous_orientation``).
        outline : ndarray (4, 2) or None
            The four outer points of the grid found (distorted pixels), also when rejected:
            where to draw it.
        """
        if isinstance(self.spec, ChessboardSpec):
            grid, partial = self._chessboard(gray)
        else:
            grid, partial = self._circles(gray), False
        if grid is None:
            return None, [], None
        outline = np.array([grid[0, 0], grid[0, -1], grid[-1, -1], grid[-1, 0]], dtype=float)
        ideal = intrinsics.undistort_points(grid.reshape(-1, 2)).reshape(grid.shape)
        placements = self._placements(gray, grid, ideal)
        name = self.target.name
        if not placements and partial:
            return None, [], None  # a grid-like texture, not a part of this board
        if not placements:
            return None, [TargetRejection(name, RejectReason.AMBIGUOUS_ORIENTATION.value,
                                          self._no_order_detail(grid))], outline
        how = "pattern"
        if len(placements) == 2 and not partial and self.spec.turn_symmetric and predicted is None:
            # a turn-symmetric board: the two labellings are the board and the board turned;
            # one fixed choice per image, the pose stream tells the turned views apart
            placements, how = [self._upright(placements, ideal)], "turn_symmetric"
        if len(placements) > 1:
            chosen = None if predicted is None else self._by_prediction(
                placements, grid, intrinsics, predicted)
            if chosen is None:
                h, w = grid.shape[:2]
                why = ("no predicted pose" if predicted is None
                       else "the predicted pose does not single one out")
                return None, [TargetRejection(
                    name, RejectReason.PARTIAL_VIEW.value,
                    f"a {w} x {h} part of the {self.spec.cols} x {self.spec.rows} grid fits at "
                    f"{len(placements)} places ({why}); a plain chessboard seen in part has no "
                    f"absolute corner index")], outline
            placements, how = [chosen], "prediction"
        flat = placements[0].reshape(-1)
        found = flat >= 0
        img = grid.reshape(-1, 2)[flat[found]]
        ideal_pts = ideal.reshape(-1, 2)[flat[found]]
        obj = self.spec.object_points()[found]
        points = GridPoints(img, obj, ideal_pts, partial, how)
        if isinstance(self.spec, CircleGridSpec):
            points = self._unbiased(points, intrinsics)
        return points, [], outline

    def circle_radii(self, points: GridPoints) -> np.ndarray:
        """Radii [m] of the circles of ``points`` (a labelled circle grid): the configured
        diameter, or the blobs' diameters over the local spacing in the image (median of the
        ordinary circles); an origin circle's scaled by its measured size ratio."""
        spec = self.spec
        n = len(points.object_points)
        is_origin = np.zeros(n, dtype=bool)
        if spec.origin_circle:
            origin = spec.object_points()[spec.origin_index()]
            is_origin = np.all(np.isclose(points.object_points, origin), axis=1)
        if spec.diameter is not None:
            r = np.full(n, 0.5 * spec.diameter)
        else:
            ratio = self._blob_sizes(points.image_points) / self._local_pitch_px(points)
            ok = ~is_origin & np.isfinite(ratio)
            r = np.full(n, 0.5 * (float(np.median(ratio[ok])) if ok.any() else 0.4) * spec.pitch)
        r[is_origin] *= self._origin_ratio
        return r

    def _unbiased(self, points: GridPoints, intrinsics: CameraIntrinsics) -> GridPoints:
        """Circle centres with the projection bias of their first pose subtracted (module
        docstring, step 3); unchanged when no first pose is found."""
        try:
            first = solve_planar_pose(points.object_points, points.image_points, points.ideal,
                                      intrinsics, min_ratio=1.0)
        except (cv2.error, np.linalg.LinAlgError, ValueError):
            return points
        if first.T is None:
            return points
        bias = centre_bias(points.object_points, self.circle_radii(points), first.T, intrinsics)
        if not np.all(np.isfinite(bias)):
            return points
        img = points.image_points - bias
        return GridPoints(img, points.object_points, intrinsics.undistort_points(img),
                          points.partial, points.how)

    # ------------------------------------------------------------------ search
    def _chessboard(self, gray: np.ndarray) -> tuple[np.ndarray | None, bool]:
        spec = self.spec
        # the sector-based detector draws from OpenCV's per-thread RNG: seeded, an image gives
        # the same answer whatever ran before it (a replayed bag gives the same pairs and
        # counters; on a noise image the part search found a 3 x 3 "part" for 2 seeds of 60)
        cv2.setRNGSeed(SB_RNG_SEED)
        ok, corners = cv2.findChessboardCornersSB(gray, spec.pattern_size, flags=SB_FLAGS)
        if not ok:  # the histogram equalisation can hide a whole board (module docstring)
            cv2.setRNGSeed(SB_RNG_SEED)
            ok, corners = cv2.findChessboardCornersSB(gray, spec.pattern_size,
                                                      flags=SB_RETRY_FLAGS)
        partial = False
        shape = (spec.rows, spec.cols)
        if not ok:
            cv2.setRNGSeed(SB_RNG_SEED)
            ok, corners, meta = cv2.findChessboardCornersSBWithMeta(
                gray, (3, 3), SB_FLAGS | cv2.CALIB_CB_LARGER)
            if not ok or meta is None:
                return None, False
            shape, partial = tuple(int(v) for v in np.asarray(meta).shape[:2]), True
        grid = np.asarray(corners, dtype=np.float64).reshape(*shape, 2)
        if self.config.chessboard_refinement == "subpix":
            grid = self._subpix(gray, grid)
        return grid, partial

    @staticmethod
    def _subpix(gray: np.ndarray, grid: np.ndarray) -> np.ndarray:
        steps = np.concatenate([np.linalg.norm(np.diff(grid, axis=0), axis=2).ravel(),
                                np.linalg.norm(np.diff(grid, axis=1), axis=2).ravel()])
        half = int(np.clip(round(0.4 * float(np.percentile(steps, 10))), 2, 15))
        pts = np.ascontiguousarray(grid.reshape(-1, 1, 2), dtype=np.float32)
        try:
            out = cv2.cornerSubPix(gray, pts, (half, half), (-1, -1), _SUBPIX_CRITERIA)
        except cv2.error:
            return grid
        out = np.asarray(out, dtype=np.float64).reshape(grid.shape)
        return out if np.all(np.isfinite(out)) else grid

    def _blob_detector(self, shape: tuple[int, int]) -> cv2.SimpleBlobDetector:
        if self._blobs is None or self._blobs[0] != shape:
            p = cv2.SimpleBlobDetector_Params()
            p.filterByArea = True
            p.minArea = 8.0
            p.maxArea = float(shape[0] * shape[1]) / 20.0
            p.filterByColor = True
            p.blobColor = 0
            self._blobs = (shape, cv2.SimpleBlobDetector_create(p))
        return self._blobs[1]

    def _circles(self, gray: np.ndarray) -> np.ndarray | None:
        spec = self.spec
        flags = cv2.CALIB_CB_ASYMMETRIC_GRID if spec.asymmetric else cv2.CALIB_CB_SYMMETRIC_GRID
        detector = self._blob_detector(gray.shape)
        try:
            ok, centres = cv2.findCirclesGrid(gray, spec.pattern_size, flags=flags,
                                              blobDetector=detector)
        except cv2.error:
            return None
        if not ok or centres is None:
            return None
        self._keypoints = detector.detect(gray)
        return np.asarray(centres, dtype=np.float64).reshape(spec.rows, spec.cols, 2)

    def _blob_sizes(self, points: np.ndarray) -> np.ndarray:
        """Diameter [px] of the blob nearest each point (nan when none within 3 px)."""
        kps = self._keypoints
        if not kps:
            return np.full(len(points), np.nan)
        where = np.array([k.pt for k in kps], dtype=float)
        size = np.array([k.size for k in kps], dtype=float)
        d = np.linalg.norm(points[:, None, :] - where[None], axis=2)
        near = np.argmin(d, axis=1)
        return np.where(d[np.arange(len(points)), near] < 3.0, size[near], np.nan)

    def _local_pitch_px(self, points: GridPoints) -> np.ndarray:
        """Per point, the image distance [px] of one pitch of the board near it (from the
        nearest other point, over their board distance in pitches)."""
        obj = points.object_points[:, :2] / self.spec.pitch
        img = points.image_points
        d_obj = np.linalg.norm(obj[:, None] - obj[None], axis=2)
        np.fill_diagonal(d_obj, np.inf)
        near = np.argmin(d_obj, axis=1)
        return (np.linalg.norm(img - img[near], axis=1)
                / d_obj[np.arange(len(obj)), near])

    # ------------------------------------------------------------------ labels
    def _placements(self, gray: np.ndarray, grid: np.ndarray,
                    ideal: np.ndarray) -> list[np.ndarray]:
        """Every labelling that fits (module docstring, step 2), each a (rows, cols) array of
        indices into the found points, -1 where a board point was not found."""
        spec = self.spec
        rows, cols = spec.rows, spec.cols
        out = []
        chess = isinstance(spec, ChessboardSpec)
        for (g, idx), (gi, _) in zip(_dihedral(grid), _dihedral(ideal), strict=True):
            h, w = g.shape[:2]
            if h > rows or w > cols or not _handed(gi):
                continue
            parity = None
            if chess:
                score = _colour_score(gray, g)
                if abs(score) < _MIN_COLOUR_SCORE:
                    continue
                parity = 0 if score > 0 else 1
            elif not self._circle_pattern_fits(g, gi):
                continue
            for dy in range(rows - h + 1):
                for dx in range(cols - w + 1):
                    if parity is not None and (dx + dy) % 2 != parity:
                        continue
                    order = np.full((rows, cols), -1)
                    order[dy:dy + h, dx:dx + w] = idx
                    out.append(order)
        return out

    def _circle_pattern_fits(self, g: np.ndarray, gi: np.ndarray) -> bool:
        """A full circle grid (rows, cols) so labelled matches the layout: the asymmetric
        layout fits a homography, the origin circle is the largest corner blob."""
        spec = self.spec
        if g.shape[:2] != (spec.rows, spec.cols):
            return False
        if spec.turn_symmetric:
            return True  # the board and the board turned: both fit (find() takes one)
        if spec.asymmetric:
            obj = spec.object_points()[:, :2]
            H, _ = cv2.findHomography(obj, gi.reshape(-1, 2), 0)
            if H is None:
                return False
            proj = cv2.perspectiveTransform(obj.reshape(-1, 1, 2), H).reshape(-1, 2)
            err = np.sqrt(np.mean(np.sum((proj - gi.reshape(-1, 2)) ** 2, axis=1)))
            pitch = np.median(np.linalg.norm(np.diff(gi, axis=0), axis=2))
            return bool(err < 0.1 * pitch)
        # the four corner circles, origin candidate first, each with its two grid neighbours:
        # blob size over the local spacing, so that perspective does not favour the nearest
        ends = [((-1, 0), (-2, 0), (-1, 1)), ((0, 0), (1, 0), (0, 1)),
                ((0, -1), (1, -1), (0, -2)), ((-1, -1), (-2, -1), (-1, -2))]
        corners = np.array([g[c] for c, _, _ in ends])
        pitch = np.array([0.5 * (np.linalg.norm(g[c] - g[u]) + np.linalg.norm(g[c] - g[v]))
                          for c, u, v in ends])
        sizes = self._blob_sizes(corners) / pitch
        if not np.all(np.isfinite(sizes)):
            return False
        if sizes[0] < _MIN_ORIGIN_RATIO * float(np.max(sizes[1:])):
            return False
        self._origin_ratio = float(sizes[0] / np.median(sizes[1:]))
        return True

    @staticmethod
    def _upright(placements: list[np.ndarray], ideal: np.ndarray) -> np.ndarray:
        """Of a turn-symmetric board's two labellings, the one whose ``x`` axis runs more to
        the image's right (ties: the first)."""
        pts = ideal.reshape(-1, 2)
        rightward = [float(pts[order[0, -1], 0] - pts[order[0, 0], 0]) for order in placements]
        return placements[int(np.argmax(rightward))]

    def _no_order_detail(self, grid: np.ndarray) -> str:
        spec = self.spec
        h, w = grid.shape[:2]
        if isinstance(spec, ChessboardSpec):
            if max(h, w) > max(spec.rows, spec.cols) or h * w > spec.n_corners:
                return (f"found a {w} x {h} corner grid, larger than the configured cols "
                        f"{spec.cols} x rows {spec.rows}")
            return "the square colours do not fix the corner order (too little contrast)"
        if spec.asymmetric:
            return "the points do not fit the asymmetric layout in any order"
        return "no grid corner holds a clearly larger origin circle"

    def _by_prediction(self, placements: list[np.ndarray], grid: np.ndarray,
                       intrinsics: CameraIntrinsics, predicted: np.ndarray) -> np.ndarray | None:
        """The placement whose points lie clearly nearest the projection of the board at the
        predicted pose (module docstring, step 2), or None."""
        proj = intrinsics.project_points(self.spec.object_points(), predicted)
        pts = grid.reshape(-1, 2)
        errors = []
        for order in placements:
            flat = order.reshape(-1)
            found = flat >= 0
            errors.append(float(np.sqrt(np.mean(np.sum(
                (pts[flat[found]] - proj[found]) ** 2, axis=1)))))
        rank = np.argsort(errors)
        step = float(np.median(np.linalg.norm(np.diff(grid, axis=1), axis=2)))
        best = errors[rank[0]]
        second = errors[rank[1]] if len(rank) > 1 else np.inf
        if best < step / 3.0 and second >= 2.0 * best:
            return placements[rank[0]]
        return None

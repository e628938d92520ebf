"""The record of one edge's synchronised measurement pairs, :class:`DatasetEdge`.

It is what the pair accumulator (:meth:`rwhec_ros.sync.PairAccumulator.edges`) returns and what a
data set (:class:`rwhec_ros.data.dataset.Dataset`) stores: image stamps, the pairs ``(A_i, B_i)``
with ``A_i X = Y B_i`` (paper eq. (7)) and their precisions ``sigma`` [m], ``kappa`` (eq. (32)),
and optionally the detected corners of each pair (for the reprojection error per camera): a
tag's four, or a board's with their board-frame points.
It lives in ``sync``, which ``data`` builds on, so that imports run one way: ``data`` uses
``sync``, never the reverse.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.problem import DEFAULT_ROTATION_TOL, check_transforms

__all__ = ["DatasetEdge", "check_name", "check_corners"]


def check_name(value: object, what: str) -> str:
    """``value`` if it is a non-empty string, else ``ValueError`` naming ``what``."""
    if not isinstance(value, str) or not value:
        raise ValueError(f"{what}: expected a non-empty string, got {value!r}")
    return value


def check_corners(corners_px, corner_points_m, n: int, name: str) -> dict:
    """``{"corners_px": ..., "corner_points_m": ...}`` of :class:`DatasetEdge` checked and
    converted (float arrays, None when no pair has corners); ``ValueError`` naming ``name``, the
    key and the pair.

    Tag corners (``corner_points_m`` None): shape (n, 4, 2), four finite corners or all NaN per
    pair. Board corners: (n, M, 2) and (n, M, 3) with M >= 4, a point finite in both or NaN in
    both, and per pair none or at least 4 points.
    """
    out = {"corners_px": None, "corner_points_m": None}
    if corners_px is None:
        if corner_points_m is not None:
            raise ValueError(f"{name} corner_points_m: given without corners_px")
        return out
    c = np.asarray(corners_px, dtype=float)
    if corner_points_m is None:
        if c.shape != (n, 4, 2):
            raise ValueError(f"{name} corners_px: expected shape ({n}, 4, 2) (tag corners; "
                             f"boards give corner_points_m too), got {c.shape}")
        rows = np.isfinite(c).reshape(n, 8)
        partial = rows.any(axis=1) & ~rows.all(axis=1)
        if partial.any() or np.isinf(c).any():
            i = int(np.argmax(partial | np.isinf(c).reshape(n, 8).any(axis=1)))
            raise ValueError(f"{name} corners_px[{i}]: expected 4 finite corners or all NaN "
                             f"(no corners), got {c[i].tolist()!r}")
        out["corners_px"] = c if rows.any() else None
        return out
    p = np.asarray(corner_points_m, dtype=float)
    if c.ndim != 3 or c.shape[0] != n or c.shape[1] < 4 or c.shape[2] != 2:
        raise ValueError(f"{name} corners_px: expected shape ({n}, M, 2) with M >= 4, got "
                         f"{c.shape}")
    if p.shape != c.shape[:2] + (3,):
        raise ValueError(f"{name} corner_points_m: expected shape {c.shape[:2] + (3,)} (as "
                         f"corners_px), got {p.shape}")
    if np.isinf(c).any() or np.isinf(p).any():
        i = int(np.argmax(np.isinf(c).any(axis=(1, 2)) | np.isinf(p).any(axis=(1, 2))))
        raise ValueError(f"{name} corners_px[{i}] / corner_points_m[{i}]: infinite value")
    seen = np.isfinite(c).all(axis=2)
    bad = (seen != np.isfinite(c).any(axis=2)) | (seen != np.isfinite(p).all(axis=2)) | (
        seen != np.isfinite(p).any(axis=2))
    if bad.any():
        i, j = (int(v) for v in np.argwhere(bad)[0])
        raise ValueError(f"{name} corners_px[{i}][{j}] / corner_points_m[{i}][{j}]: a point "
                         f"must be finite in both or NaN in both, got {c[i, j].tolist()!r} and "
                         f"{p[i, j].tolist()!r}")
    count = seen.sum(axis=1)
    few = (count > 0) & (count < 4)
    if few.any():
        i = int(np.argmax(few))
        raise ValueError(f"{name} corners_px[{i}]: expected at least 4 points or none, got "
                         f"{int(count[i])}")
    if count.any():
        out["corners_px"], out["corner_points_m"] = c, p
    return out


@dataclass(frozen=True, eq=False)
class DatasetEdge:
    """The pairs of one edge; arrays are validated and converted on construction.

    Attributes
    ----------
    x, y : str
        X-frame (tag) and Y-frame (camera) names.
    stamps_ns : ndarray, shape (N,), int64
        Image stamps [ns] (``0..N-1`` when unknown, see
        :meth:`rwhec_ros.data.dataset.Dataset.from_problem`).
    A, B : ndarray, shape (N, 4, 4), float64
        ``T_<camera carrier>_<tag carrier>`` and ``T_cam_tag``, ``A_i X = Y B_i``.
    sigma, kappa : ndarray, shape (N,), float64
        Translation standard deviation [m] and Langevin concentration of each ``B``.
    rotation_tol : float
        Tolerance of the rotation checks (:func:`~rwhec_ros.core.problem.check_transforms`);
        the pair accumulator passes its own, files are read with the default.
    corners_px : ndarray, shape (N, M, 2), or None
        The detected corners of each pair in distorted pixels; NaN for points a pair does not
        have; None when no pair has them (data sets written before they were kept, paper CSV
        data). Single tags (``corner_points_m`` None): ``M = 4``, the tag's corners in the
        order of :data:`~rwhec_ros.vision.detection.TAG_CORNERS_UNIT`, four or none per pair.
        Boards: the corners the board's pose was computed from, as many as were seen (at
        least 4), padded with NaN to the edge's largest count ``M``.
    corner_points_m : ndarray, shape (N, M, 3), or None
        Boards only: the same corners in the target (board) frame [m, nominal for an unknown
        scale], NaN exactly where ``corners_px`` is; they differ from pair to pair because a
        board may be partly seen. None for single tags (their corners follow from the tag
        size, :attr:`rwhec_ros.data.dataset.Dataset.tag_sizes_m`).
    """

    x: str
    y: str
    stamps_ns: np.ndarray
    A: np.ndarray
    B: np.ndarray
    sigma: np.ndarray
    kappa: np.ndarray
    rotation_tol: float = field(default=DEFAULT_ROTATION_TOL, repr=False)
    corners_px: np.ndarray | None = field(default=None, repr=False)
    corner_points_m: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        name = f"edge ({self.x}, {self.y})"
        check_name(self.x, f"{name} x")
        check_name(self.y, f"{name} y")
        stamps = np.asarray(self.stamps_ns)
        if stamps.ndim != 1 or stamps.shape[0] < 1:
            raise ValueError(
                f"{name} stamps_ns: expected shape (N,) with N >= 1, got {stamps.shape}"
            )
        if stamps.dtype.kind not in "iu":
            raise ValueError(f"{name} stamps_ns: expected integers, got dtype {stamps.dtype}")
        if stamps.dtype.kind == "u" and (stamps > np.iinfo(np.int64).max).any():
            raise ValueError(f"{name} stamps_ns: value above the int64 range: {stamps.max()!r}")
        if (stamps < 0).any():
            i = int(np.argmax(stamps < 0))
            raise ValueError(f"{name} stamps_ns[{i}]: must be >= 0, got {int(stamps[i])}")
        n = stamps.shape[0]
        A = check_transforms(self.A, what=f"{name} A", rotation_tol=self.rotation_tol)
        B = check_transforms(self.B, what=f"{name} B", rotation_tol=self.rotation_tol)
        for what, T in (("A", A), ("B", B)):
            if T.shape[0] != n:
                raise ValueError(f"{name} {what}: expected {n} transforms, got {T.shape[0]}")
        arrays = {"stamps_ns": stamps.astype(np.int64), "A": A, "B": B}
        for what in ("sigma", "kappa"):
            v = np.asarray(getattr(self, what), dtype=float)
            if v.shape != (n,):
                raise ValueError(f"{name} {what}: expected shape ({n},), got {v.shape}")
            bad = ~np.isfinite(v) | (v <= 0)
            if bad.any():
                i = int(np.argmax(bad))
                raise ValueError(f"{name} {what}[{i}]: must be finite and > 0, got {float(v[i])!r}")
            arrays[what] = v
        arrays.update(check_corners(self.corners_px, self.corner_points_m, n, name))
        for key, value in arrays.items():
            object.__setattr__(self, key, value)

    @property
    def n(self) -> int:
        return int(self.stamps_ns.shape[0])


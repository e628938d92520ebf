"""The record of one edge's synchronised measurement pairs, :class:`DatasetEdge`.

It is what the pair accumulator (:meth:`rwhec_ros.sync.PairAccumulator.edges`) returns and what a
data set (:class:`rwhec_ros.data.dataset.Dataset`) stores: image stamps, the pairs ``(A_i, B_i)``
with ``A_i X = Y B_i`` (paper eq. (7)) and their precisions ``sigma`` [m], ``kappa`` (eq. (32)),
and optionally the detected tag corners of each pair (for the reprojection error per camera).
It lives in ``sync``, which ``data`` builds on, so that imports run one way: ``data`` uses
``sync``, never the reverse.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.problem import DEFAULT_ROTATION_TOL, check_transforms

__all__ = ["DatasetEdge", "check_name"]


def check_name(value: object, what: str) -> str:
    """``value`` if it is a non-empty string, else ``ValueError`` naming ``what``."""
    if not isinstance(value, str) or not value:
        raise ValueError(f"{what}: expected a non-empty string, got {value!r}")
    return value


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
    corners_px : ndarray, shape (N, 4, 2), or None
        The detected corners of each pair's tag in distorted pixels (order of
        :data:`~rwhec_ros.vision.detection.TAG_CORNERS_UNIT`); NaN rows for pairs without
        corners; None when no pair has them (data sets written before they were kept, paper
        CSV data).
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
        if self.corners_px is not None:
            c = np.asarray(self.corners_px, dtype=float)
            if c.shape != (n, 4, 2):
                raise ValueError(f"{name} corners_px: expected shape ({n}, 4, 2), got {c.shape}")
            rows = np.isfinite(c).reshape(n, 8)
            partial = rows.any(axis=1) & ~rows.all(axis=1)
            if partial.any() or np.isinf(c).any():
                i = int(np.argmax(partial | np.isinf(c).reshape(n, 8).any(axis=1)))
                raise ValueError(f"{name} corners_px[{i}]: expected 4 finite corners or all NaN "
                                 f"(no corners), got {c[i].tolist()!r}")
            arrays["corners_px"] = c if rows.any() else None
        for key, value in arrays.items():
            object.__setattr__(self, key, value)

    @property
    def n(self) -> int:
        return int(self.stamps_ns.shape[0])


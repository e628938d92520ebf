"""The numbers of a report: per-pair residuals of ``A_i X_j = Y_k B_i``, per-edge fit, order."""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.lie import rotation_distance
from ..core.problem import Problem
from ..core.result import CalibrationResult, Certificate
from ..core.verdict import FitStatistics, VerdictOptions, goodness_of_fit

__all__ = [
    "EdgeResiduals",
    "edge_residuals",
    "estimates_from_document",
    "fit_of_document",
    "natural_key",
]


def natural_key(name: str) -> tuple:
    """Sort key putting ``tag_2`` before ``tag_11`` (numbers compared as numbers)."""
    return tuple(int(p) if p.isdigit() else p for p in re.split(r"(\d+)", str(name)))


@dataclass(frozen=True)
class EdgeResiduals:
    """Per-pair residuals of ``A_i X = Y B_i`` on one edge.

    Attributes
    ----------
    x, y : str
        Tag (X) and camera (Y) frame names.
    translation_m : ndarray, shape (N,)
        ``|t(A_i X) - t(Y B_i)|`` [m] with the metric ``B`` translation ``t_B / alpha``.
    rotation_rad : ndarray, shape (N,)
        Geodesic angle between ``R_A R_X`` and ``R_Y R_B`` [rad].
    """

    x: str
    y: str
    translation_m: np.ndarray
    rotation_rad: np.ndarray

    @property
    def name(self) -> str:
        return f"({self.x}, {self.y})"

    @property
    def n(self) -> int:
        return int(self.translation_m.shape[0])


def edge_residuals(
    problem: Problem, X: np.ndarray, Y: np.ndarray, scale: float = 1.0
) -> list[EdgeResiduals]:
    """Residuals of every pair of ``problem`` at the estimate (cf. eq. (7) and (22)), edges in
    natural order (``tag_2`` before ``tag_11``, then the camera).

    Parameters
    ----------
    problem : Problem
    X : ndarray, shape (M, 4, 4)
        ``T_<tag carrier>_tag`` in ``problem.x_names`` order (metric).
    Y : ndarray, shape (P, 4, 4)
        ``T_<camera carrier>_cam`` in ``problem.y_names`` order (metric).
    scale : float
        ``alpha``: measured ``B`` translations are ``alpha`` times metric ones (1 for known
        scale).
    """
    X = np.asarray(X, dtype=float)
    Y = np.asarray(Y, dtype=float)
    if X.shape != (problem.M, 4, 4) or Y.shape != (problem.P, 4, 4):
        raise ValueError(f"X, Y: expected shapes ({problem.M}, 4, 4) and ({problem.P}, 4, 4), "
                         f"got {X.shape} and {Y.shape}")
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"scale: must be finite and > 0, got {scale!r}")
    xi = {n: i for i, n in enumerate(problem.x_names)}
    yi = {n: i for i, n in enumerate(problem.y_names)}
    out = []
    for e in sorted(problem.edges, key=lambda e: (natural_key(e.x), natural_key(e.y))):
        Xj, Yk = X[xi[e.x]], Y[yi[e.y]]
        RA, tA = e.A[:, :3, :3], e.A[:, :3, 3]
        RB, tB = e.B[:, :3, :3], e.B[:, :3, 3] / scale
        t_ax = RA @ Xj[:3, 3] + tA
        t_yb = tB @ Yk[:3, :3].T + Yk[:3, 3]
        out.append(EdgeResiduals(
            e.x, e.y,
            np.linalg.norm(t_ax - t_yb, axis=1),
            rotation_distance(RA @ Xj[:3, :3], Yk[:3, :3] @ RB),
        ))
    return out


def estimates_from_document(
    doc: Mapping[str, Any], problem: Problem
) -> tuple[np.ndarray, np.ndarray, float]:
    """``(X (M,4,4), Y (P,4,4), scale)`` of a result mapping, in ``problem``'s frame order.

    Raises ``ValueError`` naming a frame of the problem that the result does not hold.
    """
    frames = {f["name"]: np.asarray(f["matrix"], dtype=float) for f in doc["frames"]}
    missing = [n for n in problem.x_names + problem.y_names if n not in frames]
    if missing:
        raise ValueError(f"frames: the result has no estimate for {missing} of the data")
    X = np.array([frames[n] for n in problem.x_names])
    Y = np.array([frames[n] for n in problem.y_names])
    return X, Y, float(doc.get("scale", 1.0))


def fit_of_document(doc: Mapping[str, Any], problem: Problem) -> FitStatistics:
    """The goodness of fit (:func:`rwhec_ros.core.verdict.goodness_of_fit`) of a result mapping
    on ``problem``, with the verdict's options of the result when it has them."""
    X, Y, scale = estimates_from_document(doc, problem)
    result = CalibrationResult(problem.x_names, problem.y_names, X, Y, scale,
                               Certificate.local_only(0.0), str(doc.get("mode", "")))
    stored = ((doc.get("verdict_details") or {}).get("options")) or {}
    known = VerdictOptions.__dataclass_fields__
    opts = VerdictOptions(**{k: v for k, v in stored.items() if k in known})
    return goodness_of_fit(problem, result, opts)

"""Held-out validation: k-fold cross-validation over the measurement pairs.

In-sample residuals always look good: the estimate was fitted to them. Cross-validation asks how
well the calibration predicts pairs it has *not* seen. The pairs of every edge are split at
random (a passed :class:`numpy.random.Generator`) into ``k`` folds of (nearly) equal size --
stratified per edge, so that every fold holds out about ``1/k`` of every edge and no frame loses
all its data; each fold is solved with :func:`~rwhec_ros.core.solve.solve` (mode ``fast``) on
the other pairs, and its held-out pairs are scored against that fold's estimate.

Residuals per pair (eq. (33)): the translation residual ``|R_A t_X + t_A - t_Y - R_Y t_B / alpha|``
[mm] (where the calibrated chain puts the tag minus where the camera saw it, in the camera
carrier) and the rotation residual, the angle between ``R_A R_X`` and ``R_Y R_B`` [deg]. Per edge
the RMS and the median are reported held-out next to in-sample (the residuals of the solution on
all pairs). Held-out RMS near ``sqrt(N / (N - p))`` times the in-sample one is what noise alone
gives; much larger means the estimate does not generalise (outliers, unmodelled effects such as
time offsets or a flexing rig, too few motions).

Edges with fewer than ``min_pairs`` pairs stay in every fold's training set (holding out one of
three pairs can make a frame undetermined); they are reported in-sample only, with a note.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..problem import Edge, Problem
from ..solve import SolveOptions, solve
from .information import check_result_frames, pair_residuals

__all__ = ["ResidualStats", "EdgeValidation", "CrossValidation", "fold_assignment",
           "cross_validate"]


@dataclass
class ResidualStats:
    """RMS and median of ``n`` translation [mm] and rotation [deg] residuals."""

    n: int
    rms_translation_mm: float
    median_translation_mm: float
    rms_rotation_deg: float
    median_rotation_deg: float

    @staticmethod
    def of(residual_t: np.ndarray, angle: np.ndarray) -> ResidualStats:
        """From translation residuals (N, 3) [m] and angles (N,) [rad]."""
        d = 1e3 * np.linalg.norm(np.asarray(residual_t, float).reshape(-1, 3), axis=1)
        a = np.degrees(np.asarray(angle, float).reshape(-1))
        if d.size == 0:
            nan = float("nan")
            return ResidualStats(0, nan, nan, nan, nan)
        return ResidualStats(int(d.size), float(np.sqrt(np.mean(d**2))), float(np.median(d)),
                             float(np.sqrt(np.mean(a**2))), float(np.median(a)))

    def to_dict(self) -> dict:
        return {"n": int(self.n), "rms_translation_mm": float(self.rms_translation_mm),
                "median_translation_mm": float(self.median_translation_mm),
                "rms_rotation_deg": float(self.rms_rotation_deg),
                "median_rotation_deg": float(self.median_rotation_deg)}


@dataclass
class EdgeValidation:
    """Held-out and in-sample residuals of one edge (``held_out`` is ``None`` when the edge was
    never held out, see ``note``)."""

    x: str
    y: str
    n_pairs: int
    in_sample: ResidualStats
    held_out: ResidualStats | None
    note: str = ""

    @property
    def ratio(self) -> float:
        """Held-out over in-sample RMS translation residual (NaN without held-out pairs)."""
        if self.held_out is None or not self.in_sample.rms_translation_mm > 0:
            return float("nan")
        return self.held_out.rms_translation_mm / self.in_sample.rms_translation_mm

    def to_dict(self) -> dict:
        return {"x": self.x, "y": self.y, "n_pairs": int(self.n_pairs),
                "in_sample": self.in_sample.to_dict(),
                "held_out": None if self.held_out is None else self.held_out.to_dict(),
                "note": self.note}


@dataclass
class CrossValidation:
    """Result of :func:`cross_validate`.

    Attributes
    ----------
    folds : int
    edges : list of EdgeValidation
        In problem order.
    in_sample, held_out : ResidualStats
        Over the pairs that were held out (each once), in-sample and held out; edges never
        held out count in neither (see their :class:`EdgeValidation`).
    fold_status : list of str
        The certificate status of each fold's solve.
    notes : list of str
    timing_s : float
    """

    folds: int
    edges: list[EdgeValidation]
    in_sample: ResidualStats
    held_out: ResidualStats
    fold_status: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    timing_s: float = 0.0

    def to_dict(self) -> dict:
        return {"folds": int(self.folds), "in_sample": self.in_sample.to_dict(),
                "held_out": self.held_out.to_dict(),
                "edges": [e.to_dict() for e in self.edges],
                "fold_status": list(self.fold_status), "notes": list(self.notes)}


def fold_assignment(problem: Problem, folds: int, rng: np.random.Generator, *,
                    min_pairs: int = 6) -> list[np.ndarray]:
    """Per edge, the fold (0..folds-1) of each pair, or -1 for edges with fewer than
    ``max(min_pairs, folds)`` pairs (never held out). Stratified: each fold gets ``n // folds``
    or one more of every edge's pairs, in a random order from ``rng``."""
    if int(folds) != folds or folds < 2:
        raise ValueError(f"folds: must be an integer >= 2, got {folds!r}")
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng: expected numpy.random.Generator, got {type(rng).__name__}")
    out = []
    for e in problem.edges:
        if e.n < max(int(min_pairs), int(folds)):
            out.append(np.full(e.n, -1))
            continue
        f = np.empty(e.n, int)
        f[rng.permutation(e.n)] = (np.arange(e.n) + int(rng.integers(folds))) % folds
        out.append(f)
    return out


def _subset(e: Edge, mask: np.ndarray) -> Edge:
    """The pairs ``mask`` of an already validated edge."""
    return Edge(e.x, e.y, e.A[mask], e.B[mask], e.sigma[mask], e.kappa[mask])


def _edge_residuals(problem: Problem, X: np.ndarray, Y: np.ndarray, alpha: float,
                    e_idx: int, mask: np.ndarray | None = None):
    e = problem.edges[e_idx]
    j, k = problem.edge_x[e_idx], problem.edge_y[e_idx]
    A, B = (e.A, e.B) if mask is None else (e.A[mask], e.B[mask])
    return pair_residuals(A, B, X[j], Y[k], alpha if problem.unknown_scale else 1.0)


def cross_validate(
    problem: Problem,
    rng: np.random.Generator,
    *,
    folds: int = 5,
    result=None,
    options: SolveOptions | None = None,
    min_pairs: int = 6,
) -> CrossValidation:
    """k-fold cross-validation over the pairs (module docstring).

    Parameters
    ----------
    problem : Problem
    rng : numpy.random.Generator
        Decides the folds (same seed, same folds).
    folds : int
        ``k`` (5).
    result : CalibrationResult, optional
        The solution on all pairs for the in-sample residuals (solved here if not given).
    options : SolveOptions, optional
        For every solve; default ``SolveOptions(mode="fast")``.
    min_pairs : int
        Edges with fewer pairs (or fewer than ``folds``) are never held out.
    """
    t0 = time.perf_counter()
    opts = options or SolveOptions(mode="fast")
    assign = fold_assignment(problem, folds, rng, min_pairs=min_pairs)
    if result is None:
        result = solve(problem, opts)
    else:
        check_result_frames(problem, result)
    held_t = [[] for _ in problem.edges]
    held_a = [[] for _ in problem.edges]
    status = []
    notes = []
    if all((a < 0).all() for a in assign):
        notes.append(f"no edge has {max(min_pairs, folds)} pairs: nothing was held out")
    else:
        for f in range(folds):
            train = [_subset(e, a != f) for e, a in zip(problem.edges, assign, strict=True)]
            sub = Problem(problem.x_names, problem.y_names, train,
                          unknown_scale=problem.unknown_scale)
            res = solve(sub, opts)
            status.append(res.certificate.status.value)
            for e_idx, a in enumerate(assign):
                test = a == f
                if test.any():
                    rt, ang = _edge_residuals(problem, res.X, res.Y, res.scale, e_idx, test)
                    held_t[e_idx].append(rt)
                    held_a[e_idx].append(ang)
    edges = []
    all_in_t, all_in_a = [np.zeros((0, 3))], [np.zeros(0)]
    for e_idx, e in enumerate(problem.edges):
        rt, ang = _edge_residuals(problem, result.X, result.Y, result.scale, e_idx)
        if held_t[e_idx]:
            all_in_t.append(rt)
            all_in_a.append(ang)
            held = ResidualStats.of(np.concatenate(held_t[e_idx]), np.concatenate(held_a[e_idx]))
            note = ""
        else:
            held = None
            note = (f"only {e.n} pairs (< {max(min_pairs, folds)}): kept for training in every "
                    "fold, not held out")
        edges.append(EdgeValidation(e.x, e.y, e.n, ResidualStats.of(rt, ang), held, note))
    flat_t = [t for ts in held_t for t in ts]
    flat_a = [a for As in held_a for a in As]
    held_all = ResidualStats.of(np.concatenate(flat_t) if flat_t else np.zeros((0, 3)),
                                np.concatenate(flat_a) if flat_a else np.zeros(0))
    return CrossValidation(folds=int(folds), edges=edges,
                           in_sample=ResidualStats.of(np.concatenate(all_in_t),
                                                      np.concatenate(all_in_a)),
                           held_out=held_all, fold_status=status, notes=notes,
                           timing_s=time.perf_counter() - t0)

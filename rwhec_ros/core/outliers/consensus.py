"""The two RANSAC stages on one edge: hypotheses, consensus sets and their local refinement.

Stage 1 (:func:`ransac_1x1y`) hypothesises ``(X, Y)`` from minimal samples of 3 pairs; stage 2
(:func:`ransac_given`) one frame from each pair by eq. (70) once the other frame is known. See
:mod:`.ransac` for the scheme around them.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from itertools import combinations

import numpy as np

from ..problem import Edge
from .models import axis_span, fit_1x1y, refit_given, score_hypotheses, x_from_y, y_from_x
from .options import RansacOptions

__all__ = ["MINIMAL_SAMPLE", "Consensus", "translation_thresholds", "ransac_1x1y",
           "ransac_given"]

#: Size of the minimal sample of the 1X1Y model (stage 1).
MINIMAL_SAMPLE = 3


@dataclass
class Consensus:
    X: np.ndarray
    Y: np.ndarray
    t_res: np.ndarray
    r_res: np.ndarray
    inliers: np.ndarray
    count: int
    score: float


def _consensus(
    t_res: np.ndarray, r_res: np.ndarray, t_thr: np.ndarray, r_thr: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inlier masks (H, N), counts (H,), MSAC scores (H,) of residuals (H, N)."""
    inl = (t_res <= t_thr) & (r_res <= r_thr)
    score = np.minimum((t_res / t_thr) ** 2, 1.0) + np.minimum((r_res / r_thr) ** 2, 1.0)
    return inl, inl.sum(axis=1), score.sum(axis=1)


def _better(count: int, score: float, best: Consensus | None) -> bool:
    return best is None or count > best.count or (count == best.count and score < best.score)


def _required_hypotheses(n_inliers: int, n: int, opts: RansacOptions, sample: int) -> int:
    """Adaptive RANSAC count ``log(1 - p) / log(1 - w^s)`` clamped to the option bounds."""
    w = n_inliers / n
    if w >= 1.0:
        need = opts.min_iterations
    elif w <= 0.0:
        need = opts.max_iterations
    else:
        denom = math.log1p(-(w**sample))
        need = opts.max_iterations if denom == 0.0 else math.ceil(
            math.log(1.0 - opts.confidence) / denom
        )
    return int(min(opts.max_iterations, max(opts.min_iterations, need)))


def _triple_batches(
    edge: Edge, opts: RansacOptions, rng: np.random.Generator
) -> Iterator[np.ndarray]:
    """Non-degenerate 3-pair samples (b, 3) in batches; stops when none can be found."""
    n = edge.n
    RA = edge.A[:, :3, :3]
    min_span = np.deg2rad(opts.min_axis_span_deg)
    if math.comb(n, 3) <= opts.max_iterations:
        triples = np.array(list(combinations(range(n), 3)), dtype=int)
        triples = triples[rng.permutation(triples.shape[0])]
        triples = triples[axis_span(RA[triples]) >= min_span]
        for s in range(0, triples.shape[0], opts.batch_size):
            yield triples[s : s + opts.batch_size]
        return
    max_draws = 20 * opts.max_iterations
    draws = 0
    while draws < max_draws:
        cand = rng.integers(0, n, size=(4 * opts.batch_size, 3))
        draws += cand.shape[0]
        distinct = (cand[:, 0] != cand[:, 1]) & (cand[:, 0] != cand[:, 2]) & (
            cand[:, 1] != cand[:, 2]
        )
        cand = cand[distinct]
        cand = cand[axis_span(RA[cand]) >= min_span][: opts.batch_size]
        if cand.shape[0]:
            draws = 0  # only a long run of degenerate draws ends the search
            yield cand


def translation_thresholds(edge: Edge, opts: RansacOptions, unknown_scale: bool) -> np.ndarray:
    thr = np.full(edge.n, opts.translation_threshold)
    if unknown_scale:
        thr = thr + opts.scale_tolerance * np.linalg.norm(edge.B[:, :3, 3], axis=1)
    return thr


def ransac_1x1y(
    edge: Edge, opts: RansacOptions, rng: np.random.Generator, t_thr: np.ndarray
) -> tuple[Consensus | None, int]:
    """Stage 1 on one edge; ``(None, 0)`` when no non-degenerate minimal sample exists."""
    r_thr = np.deg2rad(opts.rotation_threshold_deg)
    best: Consensus | None = None
    done = 0
    need = opts.max_iterations
    for batch in _triple_batches(edge, opts, rng):
        batch = batch[: max(need - done, 0)]
        if batch.shape[0] == 0:
            break
        X, Y = fit_1x1y(edge.A[batch], edge.B[batch])
        t_res, r_res = score_hypotheses(edge.A, edge.B, X, Y)
        inl, counts, scores = _consensus(t_res, r_res, t_thr, r_thr)
        done += batch.shape[0]
        h = int(np.lexsort((scores, -counts))[0])
        if _better(int(counts[h]), float(scores[h]), best):
            best = Consensus(X[h], Y[h], t_res[h], r_res[h], inl[h], int(counts[h]),
                              float(scores[h]))
            need = _required_hypotheses(best.count, edge.n, opts, MINIMAL_SAMPLE)
        if done >= need:
            break
    if best is None:
        return None, 0
    for _ in range(opts.local_refinements):
        idx = np.flatnonzero(best.inliers)
        if idx.size < MINIMAL_SAMPLE:
            break
        X, Y = fit_1x1y(edge.A[idx][None], edge.B[idx][None], edge.kappa[idx][None],
                         edge.sigma[idx][None])
        t_res, r_res = score_hypotheses(edge.A, edge.B, X, Y)
        inl, counts, scores = _consensus(t_res, r_res, t_thr, r_thr)
        stable = np.array_equal(inl[0], best.inliers)
        best = Consensus(X[0], Y[0], t_res[0], r_res[0], inl[0], int(counts[0]),
                          float(scores[0]))
        if stable:
            break
    return best, done


def ransac_given(
    edge: Edge, opts: RansacOptions, known: str, T_known: np.ndarray, t_thr: np.ndarray
) -> Consensus:
    """Stage 2 (paper, eq. (70)): one hypothesis per pair for the unknown frame of the edge."""
    r_thr = np.deg2rad(opts.rotation_threshold_deg)
    A, B = edge.A, edge.B
    hyp = x_from_y(A, B, T_known) if known == "Y" else y_from_x(A, B, T_known)
    rep = np.repeat(T_known[None], edge.n, axis=0)
    X, Y = (hyp, rep) if known == "Y" else (rep, hyp)
    t_res, r_res = score_hypotheses(A, B, X, Y)
    inl, counts, scores = _consensus(t_res, r_res, t_thr, r_thr)
    h = int(np.lexsort((scores, -counts))[0])
    best = Consensus(X[h], Y[h], t_res[h], r_res[h], inl[h], int(counts[h]), float(scores[h]))
    for _ in range(opts.local_refinements):
        idx = np.flatnonzero(best.inliers)
        if idx.size == 0:
            break
        T = refit_given(edge, idx, known, T_known)
        Xr, Yr = (T[None], T_known[None]) if known == "Y" else (T_known[None], T[None])
        t_res, r_res = score_hypotheses(A, B, Xr, Yr)
        inl, counts, scores = _consensus(t_res, r_res, t_thr, r_thr)
        stable = np.array_equal(inl[0], best.inliers)
        best = Consensus(Xr[0], Yr[0], t_res[0], r_res[0], inl[0], int(counts[0]),
                          float(scores[0]))
        if stable or best.count == 0:
            break
    return best



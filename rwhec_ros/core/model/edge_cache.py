"""Edge blocks of the cost reused from one problem to the next (the live re-solve's cache).

The cost matrix ``Q`` of eq. (42) is the sum, edge by edge, of 25x25 blocks that are themselves
sums over the edge's pairs (:func:`~rwhec_ros.core.model.cost.edge_blocks`). While data arrive, each
re-solve of the live solver (:mod:`rwhec_ros.session.live_solve`) sees the same edges with a few
more pairs each; :class:`EdgeBlockCache` keeps the per-edge sums of the previous problem and, for
an edge whose first pairs are exactly those of the previous problem, adds the sums of the new
pairs only. Which edges those are it learns in one of two ways:

* from *lineages* (the live solver's way): the accumulator names each edge's sequence of kept
  pairs by an object that stays the same while pairs are only appended
  (:attr:`~rwhec_ros.sync.accumulator.KeptPairs.lineage`); an edge with the lineage of last
  time and at least as many pairs reuses last time's sums, without looking at the pairs;
* without lineages, by comparing the pairs (same ``A``, ``B``, ``sigma``, ``kappa``, value by
  value) with a copy of the previous problem's.

Any other edge (new, fewer pairs, a pair replaced, the stated noise changed) is summed afresh.
Both ways give the same blocks for the same reuse, and those equal the freshly assembled blocks
up to the rounding of the sums (split in two runs instead of one);
``test/core/test_edge_cache.py`` checks it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..problem import Problem
from .cost import (
    _blocks_from_sums,
    _edge_indices,
    _edge_sums,
    _edge_sums_few,
    _finished_blocks,
)

__all__ = ["EdgeBlockCache", "FEW_PAIRS"]

#: New pairs up to this many (next to reused ones) are summed per pair and reduced per edge
#: (temporaries ~2.7 kB per pair); more, or nothing reused, one matrix product per edge
#: (:func:`~rwhec_ros.core.model.cost.edge_blocks`'s way: a first call gives exactly its blocks).
FEW_PAIRS = 2048


@dataclass
class _Previous:
    """The per-edge sums of the last call, the edges' lineages (``None`` when compared by
    value) and, for comparing by value, the pairs (own copy: one row ``[A (16), B (16),
    sigma, kappa]`` per pair, edge by edge; ``None`` with lineages)."""

    index: dict[tuple[str, str], int]
    starts: np.ndarray | None
    counts: list[int]
    rows: np.ndarray | None
    G: np.ndarray
    K: np.ndarray
    ksum: np.ndarray
    lineages: list | None = None


@dataclass
class _Plan:
    """What :meth:`EdgeBlockCache.blocks` sums and reuses: per edge its pair count and its
    edge index last time (``src``, meaningful for the reused edges); the edges with pairs to
    sum (``active``) and how many (``fresh``); the edges reusing last time's sums (``old``)
    and the pairs reused in all; the edges' lineages (``None`` when compared by value)."""

    counts: list[int]
    active: list[int]
    fresh: list[int]
    old: list[int]
    src: list[int]
    reused: int
    lineages: list | None


def _ranges(starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Concatenated ``arange(starts[e], starts[e] + lengths[e])`` over ``e``."""
    total = int(lengths.sum())
    offsets = np.arange(total) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    return np.repeat(starts, lengths) + offsets


class EdgeBlockCache:
    """Per-edge sums of the previous problem, reused for the pairs it shares with the next.

    Not thread-safe: one owner (the live solver's worker thread). Holds the last problem's
    per-edge sums (3 kB per edge) and, when called without lineages, a copy of its pairs (about
    300 bytes per pair) to compare with.

    Attributes
    ----------
    reused_pairs, summed_pairs : int
        Pairs of the last :meth:`blocks` call taken from the previous sums and summed afresh.
    """

    def __init__(self) -> None:
        self._prev: _Previous | None = None
        self.reused_pairs = 0
        self.summed_pairs = 0

    def clear(self) -> None:
        """Forget the previous problem."""
        self._prev = None

    def blocks(self, problem: Problem, lineages: dict | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(full, rot, idx)`` of ``problem`` as :func:`~rwhec_ros.core.model.cost.edge_blocks`
        returns them (to set ``problem.precomputed_blocks``), reusing the previous call's sums
        for every edge that only gained pairs at its end.

        ``lineages``: ``{(x, y): lineage}`` of the edges' pairs
        (:attr:`~rwhec_ros.sync.accumulator.KeptPairs.lineage`): an edge whose lineage is the
        one of the previous call (identity, not ``None``) and has at least as many pairs
        reuses that call's sums without a comparison; others are summed afresh. The previous
        call must have had lineages too (a call without them compares the pairs with those of
        a previous call without them)."""
        edges = problem.edges
        E = len(edges)
        if lineages is None:
            counts = [e.n for e in edges]
            starts = np.cumsum(counts, dtype=np.int64) - counts
            rows = self._rows(edges, int(sum(counts)))
            reuse, src = self._reusable(edges, rows, starts, counts)
            fresh = np.asarray(counts, dtype=np.int64) - reuse
            active = np.flatnonzero(fresh)
            new = rows[_ranges(starts[active] + reuse[active], fresh[active])]
            A, B = new[:, 0:16].reshape(-1, 4, 4), new[:, 16:32].reshape(-1, 4, 4)
            sigma, kappa = new[:, 32], new[:, 33]
            plan = _Plan(counts, active.tolist(), fresh[active].tolist(),
                         np.flatnonzero(reuse).tolist(), src.tolist(), int(reuse.sum()), None)
        else:
            plan, tails = self._same_lineage(edges, lineages)
            starts = rows = None  # (only a call without lineages compares pairs by position)
            A, B, sigma, kappa = _concatenated(tails)
        # nothing reused (the first call): exactly the fresh assembly's sums
        sums = _edge_sums_few if plan.old and A.shape[0] <= FEW_PAIRS else _edge_sums
        Gn, Kn, kn = sums(A, B, sigma, kappa, np.array(plan.fresh, dtype=np.int64))
        G = np.zeros((E, 16, 16))
        K = np.zeros((E, 9, 9))
        ksum = np.zeros(E)
        if plan.old:
            prev = self._prev
            old = np.array(plan.old, dtype=np.int64)
            src = np.array([plan.src[i] for i in plan.old], dtype=np.int64)
            G[old] = prev.G[src]
            K[old] = prev.K[src]
            ksum[old] = prev.ksum[src]
        active = np.array(plan.active, dtype=np.int64)
        G[active] += Gn
        K[active] += Kn
        ksum[active] += kn
        self._prev = _Previous({(e.x, e.y): i for i, e in enumerate(edges)}, starts,
                               plan.counts, rows, G, K, ksum, plan.lineages)
        self.reused_pairs = plan.reused
        self.summed_pairs = int(sum(plan.fresh))
        return _finished(problem, G, K, ksum)

    @staticmethod
    def _rows(edges, N: int) -> np.ndarray:
        """One copy of every pair, ``[A, B, sigma, kappa]`` (N, 34), edge by edge."""
        rows = np.empty((N, 34))
        if edges:
            rows[:, 0:16] = np.concatenate([e.A for e in edges]).reshape(N, 16)
            rows[:, 16:32] = np.concatenate([e.B for e in edges]).reshape(N, 16)
            rows[:, 32] = np.concatenate([e.sigma for e in edges])
            rows[:, 33] = np.concatenate([e.kappa for e in edges])
        return rows

    def _candidates(self, edges, counts: list[int]) -> tuple[list[int], list[int]]:
        """Per edge, the previous call's pair count of the same edge when it had at most as
        many pairs, else 0; and that edge's index last time."""
        E = len(edges)
        prev = self._prev
        reuse, src = [0] * E, [0] * E
        for i, e in enumerate(edges):
            j = prev.index.get((e.x, e.y))
            if j is None or prev.counts[j] > counts[i]:
                continue
            reuse[i], src[i] = prev.counts[j], j
        return reuse, src

    def _same_lineage(self, edges, lineages: dict) -> tuple[_Plan, list[tuple]]:
        """:meth:`_reusable` by lineage (no pair compared: :meth:`_candidates` and the same
        lineage, in one loop over the edges), as a :class:`_Plan` with the edges' lineages
        (``lineages.get((x, y))``); and the pairs to sum, ``(A, B, sigma, kappa)`` after the
        reused ones, of every edge with such pairs."""
        E = len(edges)
        prev = self._prev
        if prev is not None and prev.lineages is None:
            prev = None
        counts, lin, src = [0] * E, [None] * E, [0] * E
        active, fresh, old, tails = [], [], [], []
        reused = 0
        for i, e in enumerate(edges):
            n = counts[i] = e.n
            line = lin[i] = lineages.get((e.x, e.y))
            k = 0
            if prev is not None and line is not None:
                j = prev.index.get((e.x, e.y))
                if j is not None and prev.counts[j] <= n and line is prev.lineages[j]:
                    k, src[i] = prev.counts[j], j
                    if k:
                        old.append(i)
                        reused += k
            if n > k:
                active.append(i)
                fresh.append(n - k)
                tails.append((e.A[k:], e.B[k:], e.sigma[k:], e.kappa[k:]))
        return _Plan(counts, active, fresh, old, src, reused, lin), tails

    def _reusable(self, edges, rows: np.ndarray, starts: np.ndarray, counts: list[int]
                  ) -> tuple[np.ndarray, np.ndarray]:
        """Per edge, how many of its first pairs equal all the pairs of the same edge last time
        (0: none reusable) and that edge's index last time."""
        E = len(edges)
        prev = self._prev
        if prev is None or prev.rows is None:
            return np.zeros(E, dtype=np.int64), np.zeros(E, dtype=np.int64)
        reuse, src = self._candidates(edges, counts)
        reuse, src = np.array(reuse, dtype=np.int64), np.array(src, dtype=np.int64)
        if not reuse.any():
            return reuse, src
        same = (rows[_ranges(starts, reuse)] == prev.rows[_ranges(prev.starts[src], reuse)]
                ).all(axis=1)
        differs = np.bincount(np.repeat(np.arange(E), reuse), weights=~same, minlength=E)
        reuse[differs > 0] = 0
        return reuse, src


def _finished(problem: Problem, G: np.ndarray, K: np.ndarray, ksum: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``_finished_blocks(problem, *_blocks_from_sums(G, K, ksum))``, bit for bit, without its
    symmetrisation of ``full`` when that would change nothing: ``full`` is exactly symmetric
    when ``G`` is (``rot``'s parts are placed symmetrically, ``G``'s added at mirrored places),
    and ``0.5 (x + x) = x`` exactly."""
    if np.array_equal(G, np.swapaxes(G, 1, 2)):
        full, rot = _blocks_from_sums(G, K, ksum)
        return full, rot, _edge_indices(problem)
    return _finished_blocks(problem, *_blocks_from_sums(G, K, ksum))


def _concatenated(tails: list[tuple]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``A, B`` (N, 4, 4), ``sigma, kappa`` (N,): the ``(A, B, sigma, kappa)`` runs of pairs
    ``tails`` concatenated in order."""
    if not tails:
        return np.zeros((0, 4, 4)), np.zeros((0, 4, 4)), np.zeros(0), np.zeros(0)
    A, B, sigma, kappa = zip(*tails, strict=True)
    return np.concatenate(A), np.concatenate(B), np.concatenate(sigma), np.concatenate(kappa)

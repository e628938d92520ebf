"""The live re-solve's cache of the cost's edge blocks (:mod:`rwhec_ros.core.model.edge_cache`): the
cached blocks equal the freshly assembled ones whatever happened to the pairs since (pairs
added, a pair replaced, the noise changed, edges added or dropped), and a solve from cached
blocks equals a solve from scratch."""

import numpy as np
import pytest

from rwhec_ros.core.model.cost import _edge_sums, _edge_sums_few, build_cost_matrices, edge_blocks
from rwhec_ros.core.model.edge_cache import EdgeBlockCache
from rwhec_ros.core.problem import Edge, Problem
from rwhec_ros.core.solve import SolveOptions, solve
from rwhec_ros.simulation.synthetic import random_instance, random_transforms

# The cached sums add two runs of each edge's pairs where a fresh assembly sums them in one:
# they differ by the rounding of sums of ~100 terms of size <= max|block| (~1e-14 relative).
REL = 1e-12


def _instance(seed, n_per_edge=12, unknown_scale=False):
    rng = np.random.default_rng(seed)
    problem, _ = random_instance(rng, 3, 2, n_per_edge=n_per_edge, sigma=0.02, kappa=50.0,
                                 unknown_scale=unknown_scale)
    return problem


def _first(problem, counts, order=None):
    """The problem with only the first ``counts[e]`` pairs of every edge (edges in ``order``)."""
    edges = [Edge(e.x, e.y, e.A[:k], e.B[:k], e.sigma[:k], e.kappa[:k])
             for e, k in zip(problem.edges, counts, strict=True) if k]
    if order is not None:
        edges = [edges[i] for i in order]
    return problem.with_edges(edges)


def _fresh(problem):
    p = Problem(problem.x_names, problem.y_names, problem.edges,
                unknown_scale=problem.unknown_scale)
    return edge_blocks(p)


def _assert_blocks_equal(got, want):
    for g, w in zip(got, want, strict=True):
        assert g.shape == w.shape
        assert np.abs(g - w).max() <= REL * max(np.abs(w).max(), 1.0)
    np.testing.assert_array_equal(got[2], want[2])  # indices: exact


def test_first_call_is_the_fresh_assembly_exactly():
    problem = _instance(0)
    cache = EdgeBlockCache()
    got = cache.blocks(problem)
    for g, w in zip(got, _fresh(problem), strict=True):
        np.testing.assert_array_equal(g, w)
    assert cache.reused_pairs == 0 and cache.summed_pairs == problem.n_measurements


def test_pairs_added_to_some_edges_reuse_the_rest():
    problem = _instance(1)
    n = np.array([e.n for e in problem.edges])
    cache = EdgeBlockCache()
    before = n - np.array([4, 0, 1, 0, 7, 2])[: len(n)]
    cache.blocks(_first(problem, before))
    got = cache.blocks(problem)
    _assert_blocks_equal(got, _fresh(problem))
    assert cache.reused_pairs == before.sum()
    assert cache.summed_pairs == (n - before).sum()


def test_replaced_pair_noise_change_and_fewer_pairs_are_summed_again():
    problem = _instance(2)
    cache = EdgeBlockCache()
    cache.blocks(problem)
    # edge 0: one pair replaced (same count); edge 1: sigma changed; edge 2: fewer pairs
    e0, e1, e2 = problem.edges[:3]
    B = e0.B.copy()
    B[3] = random_transforms(np.random.default_rng(9), 1)[0]
    edges = [Edge(e0.x, e0.y, e0.A, B, e0.sigma, e0.kappa),
             Edge(e1.x, e1.y, e1.A, e1.B, 2.0 * e1.sigma, e1.kappa),
             Edge(e2.x, e2.y, e2.A[:5], e2.B[:5], e2.sigma[:5], e2.kappa[:5]),
             *problem.edges[3:]]
    changed = problem.with_edges(edges)
    got = cache.blocks(changed)
    _assert_blocks_equal(got, _fresh(changed))
    assert cache.summed_pairs == e0.n + e1.n + 5
    assert cache.reused_pairs == sum(e.n for e in problem.edges[3:])


def test_edges_added_dropped_and_reordered():
    problem = _instance(3)
    E = len(problem.edges)
    cache = EdgeBlockCache()
    cache.blocks(_first(problem, [6] * (E - 1) + [0]))  # the last edge is new next time
    counts = [8] * E
    counts[0] = 0  # the first edge disappears
    later = _first(problem, counts, order=list(reversed(range(E - 1))))
    _assert_blocks_equal(cache.blocks(later), _fresh(later))


@pytest.mark.parametrize("seed", [4, 5])
def test_few_pair_sums_equal_the_per_edge_products(seed):
    """The per-pair + reduceat sums of new pairs against the one-product-per-edge reference."""
    problem = _instance(seed, n_per_edge=7)
    st = problem.stacked()
    counts = np.array([e.n for e in problem.edges])
    for a, b in zip(_edge_sums_few(st["A"], st["B"], st["sigma"], st["kappa"], counts),
                    _edge_sums(st["A"], st["B"], st["sigma"], st["kappa"], counts), strict=True):
        assert np.abs(a - b).max() <= REL * np.abs(b).max()


@pytest.mark.parametrize("unknown_scale", [False, True])
def test_solve_from_cached_blocks_is_the_solve_from_scratch(unknown_scale):
    problem = _instance(6, n_per_edge=15, unknown_scale=unknown_scale)
    cache = EdgeBlockCache()
    cache.blocks(_first(problem, [10] * len(problem.edges)))
    cached = _first(problem, [15] * len(problem.edges))
    cached.precomputed_blocks = cache.blocks(cached)
    assert cache.reused_pairs > 0
    opts = SolveOptions(mode="fast", fallback_to_sdp=False)
    a, b = solve(cached, opts), solve(problem, opts)
    assert a.certificate.status == b.certificate.status
    # the same optimum of (to rounding) the same cost matrix
    np.testing.assert_allclose(a.X, b.X, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.Y, b.Y, rtol=0, atol=1e-9)
    assert a.certificate.primal_cost == pytest.approx(b.certificate.primal_cost, rel=1e-10)
    Qa, Qb = build_cost_matrices(cached)[0], build_cost_matrices(problem)[0]
    assert np.abs(Qa - Qb).max() <= REL * np.abs(Qb).max()


def test_precomputed_blocks_of_another_problem_are_refused():
    problem = _instance(7)
    other = _first(problem, [5] * (len(problem.edges) - 1) + [0])
    problem.precomputed_blocks = EdgeBlockCache().blocks(other)
    with pytest.raises(ValueError, match="precomputed_blocks"):
        edge_blocks(problem)


def _accumulated(problem, counts, acc=None):
    """A PairAccumulator (keyframe thresholds ~0: every pair kept) holding the first
    ``counts[e]`` pairs of every edge of ``problem`` (pairs already held are not offered
    again)."""
    from rwhec_ros.sync.accumulator import PairAccumulator

    if acc is None:
        acc = PairAccumulator(keyframe_rotation_rad=1e-12, keyframe_translation_m=1e-12,
                              max_pairs_per_edge=1000)
    held = acc.counts()
    for e, k in zip(problem.edges, counts, strict=True):
        for i in range(held.get((e.x, e.y), 0), k):
            assert acc.offer(e.x, e.y, i, e.A[i], e.B[i], float(e.sigma[i]), float(e.kappa[i]))
    return acc


def _snapshot_problem(problem, acc):
    from rwhec_ros.sync.accumulator import problem_from_edges

    snap = acc.kept_pairs()
    p, _ = problem_from_edges(snap, problem.x_names, problem.y_names, problem.unknown_scale,
                              1, validate=False)
    return p, {k: v.lineage for k, v in snap.items()}


@pytest.mark.parametrize("unknown_scale", [False, True])
def test_lineages_reuse_what_the_comparison_reuses_bit_for_bit(unknown_scale):
    """The live solver's way (lineages from the accumulator, no pair compared) against the
    comparison of every pair: the same reuse and the same blocks, bit for bit, through pairs
    appended, new precisions and a full edge replacing a pair; both equal the fresh assembly
    to rounding."""
    problem = _instance(8, n_per_edge=20, unknown_scale=unknown_scale)
    E = len(problem.edges)
    by_lineage, by_value = EdgeBlockCache(), EdgeBlockCache()
    acc = _accumulated(problem, [6] * E)
    steps = [lambda: _accumulated(problem, [9] * E, acc),  # every edge gained pairs
             lambda: _accumulated(problem, [9, 14] + [9] * (E - 2), acc),  # one edge
             lambda: acc.set_precisions(0.03, 80.0),  # every pair changed
             lambda: _accumulated(problem, [20] * E, acc)]
    reused = []
    for step in [lambda: None, *steps]:
        step()
        p, lineages = _snapshot_problem(problem, acc)
        got = by_lineage.blocks(p, lineages=lineages)
        want = by_value.blocks(p)
        for g, w in zip(got, want, strict=True):
            np.testing.assert_array_equal(g, w)
        assert (by_lineage.reused_pairs, by_lineage.summed_pairs) == (
            by_value.reused_pairs, by_value.summed_pairs)
        _assert_blocks_equal(got, _fresh(p))
        reused.append(by_lineage.reused_pairs)
    assert reused == [0, 6 * E, 9 * E, 0, 9 * (E - 1) + 14]


def test_an_edge_without_or_with_a_new_lineage_is_summed_afresh():
    problem = _instance(9, n_per_edge=10)
    E = len(problem.edges)
    cache = EdgeBlockCache()
    acc = _accumulated(problem, [4] * E)
    p, lineages = _snapshot_problem(problem, acc)
    cache.blocks(p, lineages=lineages)
    _accumulated(problem, [10] * E, acc)
    p, lineages = _snapshot_problem(problem, acc)
    first = (problem.edges[0].x, problem.edges[0].y)
    lineages[first] = None  # unknown: no promise, summed afresh
    lineages[(problem.edges[1].x, problem.edges[1].y)] = object()  # another sequence
    got = cache.blocks(p, lineages=lineages)
    assert cache.reused_pairs == 4 * (E - 2) and cache.summed_pairs == 10 * E - 4 * (E - 2)
    _assert_blocks_equal(got, _fresh(p))
    # a call without lineages after one with them (and the reverse) reuses nothing
    cache.blocks(p)
    assert cache.reused_pairs == 0
    cache.blocks(p, lineages=lineages)
    assert cache.reused_pairs == 0

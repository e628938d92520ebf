"""The promise of :attr:`KeptPairs.lineage` that the live re-solve's edge-block cache relies on:
two snapshots of an edge with the same lineage hold the same first pairs, bit for bit, and a
snapshot never changes after it was taken, whatever the accumulator does next (appends past
the first 64 slots, pairs arriving out of order, a full edge replacing pairs, new precisions,
a cleared accumulator)."""

import numpy as np
import pytest

from rwhec_ros.core.lie import make_transform
from rwhec_ros.simulation.synthetic import random_rotations
from rwhec_ros.sync.accumulator import PairAccumulator

FIELDS = ("stamps_ns", "A", "B", "sigma", "kappa")


def _pose(rng):
    return make_transform(random_rotations(rng, 1)[0], rng.uniform(-1.0, 1.0, 3))


def _frozen(snap):
    """Own copies of a snapshot's arrays, per edge."""
    return {k: [getattr(v, f).copy() for f in FIELDS] for k, v in snap.items()}


def _check(history):
    """Every snapshot as it was taken; same lineage -> the shorter is a prefix of the longer."""
    for snap, frozen in history:
        for k, v in snap.items():
            for f, want in zip(FIELDS, frozen[k], strict=True):
                assert np.array_equal(getattr(v, f), want), (k, f)
    by_lineage = {}
    for snap, _ in history:
        for k, v in snap.items():
            by_lineage.setdefault((k, id(v.lineage)), []).append(v)
    for group in by_lineage.values():
        group.sort(key=lambda v: v.n)
        for a, b in zip(group, group[1:], strict=False):
            for f in FIELDS:
                assert np.array_equal(getattr(a, f), getattr(b, f)[: a.n]), f


@pytest.mark.parametrize("seed", range(4))
def test_same_lineage_means_a_prefix_and_snapshots_never_change(seed):
    rng = np.random.default_rng(seed)
    # small full edges (replacements), keyframe thresholds ~0 (every distinct pose kept)
    acc = PairAccumulator(keyframe_rotation_rad=1e-9, keyframe_translation_m=1e-9,
                          max_pairs_per_edge=int(rng.choice([20, 70])))
    edges = [("tag_0", "cam_0"), ("tag_1", "cam_0"), ("tag_0", "cam_1")]
    stamp = {e: 1000 for e in edges}
    history = []
    lineages = {e: set() for e in edges}
    for step in range(260):
        e = edges[int(rng.integers(len(edges)))]
        r = rng.uniform()
        if r < 0.04:
            acc.set_precisions(float(rng.uniform(0.01, 0.1)), float(rng.uniform(50, 200)))
        else:
            back = r < 0.1  # a pair older than the newest of its edge
            s = stamp[e] - int(rng.integers(1, 500)) if back else stamp[e] + 1000
            stamp[e] = max(stamp[e], s)
            acc.offer(*e, s, _pose(rng), _pose(rng), 0.05, 100.0)
        if step % 3 == 0:
            snap = acc.kept_pairs()
            history.append((snap, _frozen(snap)))
            for k, v in snap.items():
                lineages[k].add(id(v.lineage))
    _check(history)
    counters = acc.counters()
    assert counters["replaced_redundant"] > 0  # the replacements were exercised
    assert all(len(ids) > 1 for ids in lineages.values())  # and lineages did change


def test_lineage_changes_exactly_when_the_sorted_pairs_stop_growing_at_their_end():
    rng = np.random.default_rng(7)
    acc = PairAccumulator(keyframe_rotation_rad=1e-9, keyframe_translation_m=1e-9,
                          max_pairs_per_edge=100)
    e = ("tag_0", "cam_0")

    def offer(stamp):
        assert acc.offer(*e, stamp, _pose(rng), _pose(rng), 0.05, 100.0)
        return acc.kept_pairs()[e]

    first = offer(10)
    grown = [offer(10 * i) for i in range(2, 80)]  # past the first 64 slots (arrays grow)
    assert all(g.lineage is first.lineage for g in grown)
    inserted = offer(15)  # older than the newest: inside the sorted sequence
    assert inserted.lineage is not first.lineage
    assert offer(10_000).lineage is inserted.lineage
    acc.set_precisions(0.02, 50.0)
    renoised = acc.kept_pairs()[e]
    assert renoised.lineage is not inserted.lineage
    assert np.all(renoised.sigma == 0.02) and np.all(inserted.sigma == 0.05)  # old view kept
    acc.clear()
    assert offer(20_000).lineage is not renoised.lineage


def test_a_full_edge_that_replaces_a_pair_starts_a_new_lineage():
    rng = np.random.default_rng(8)
    acc = PairAccumulator(keyframe_rotation_rad=1e-9, keyframe_translation_m=1e-9,
                          max_pairs_per_edge=5)
    e = ("tag_0", "cam_0")
    for i in range(5):
        acc.offer(*e, i, _pose(rng), _pose(rng), 0.05, 100.0)
    full = acc.kept_pairs()[e]
    frozen = full.A.copy()
    stamp = 5
    while acc.counters()["replaced_redundant"] == 0:
        acc.offer(*e, stamp, _pose(rng), _pose(rng), 0.05, 100.0)
        stamp += 1
    after = acc.kept_pairs()[e]
    assert after.lineage is not full.lineage
    assert np.array_equal(full.A, frozen)  # the snapshot before is untouched


def test_a_copied_accumulator_hands_out_its_own_arrays():
    """A deep copy (or a pickle) taken after a snapshot: its snapshots are views of its own
    arrays (the pairs appended to it are in them), and neither copy changes the other."""
    import copy
    import pickle

    rng = np.random.default_rng(9)
    acc = PairAccumulator(keyframe_rotation_rad=1e-9, keyframe_translation_m=1e-9)
    e = ("tag_0", "cam_0")
    for i in range(5):
        acc.offer(*e, i, _pose(rng), _pose(rng), 0.05, 100.0)
    before = acc.kept_pairs()[e]
    for other in (copy.deepcopy(acc), pickle.loads(pickle.dumps(acc))):
        A_new = _pose(rng)
        assert other.offer(*e, 10, A_new, _pose(rng), 0.05, 100.0)
        got = other.kept_pairs()[e]
        assert got.n == 6 and np.array_equal(got.A[:5], before.A)
        assert np.array_equal(got.A[5], A_new)
        assert got.lineage is not before.lineage
        assert acc.kept_pairs()[e].n == 5

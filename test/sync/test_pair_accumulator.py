"""PairAccumulator: keyframes, listeners, memory bound, full-edge policy, to_problem."""

import gc
import tracemalloc

import numpy as np
import pytest

from rwhec_ros.core.lie import invert_transform, make_transform, rotation_distance, so3_exp
from rwhec_ros.simulation.synthetic import perturb_measurements, random_transforms
from rwhec_ros.sync.accumulator import PairAccumulator, problem_from_edges

MS = 1_000_000
DEG = np.pi / 180.0


def pairs_for(rng, A, X=None, Y=None, sigma=0.005, kappa=400.0):
    """Consistent ``B = Y^-1 A X`` (noisy) for poses ``A`` (N, 4, 4)."""
    X = random_transforms(rng, 1)[0] if X is None else X
    Y = random_transforms(rng, 1)[0] if Y is None else Y
    B = perturb_measurements(rng, invert_transform(Y) @ A @ X, sigma, kappa)
    return B


def test_keyframes_stationary_then_moving():
    rng = np.random.default_rng(0)
    A_rest = random_transforms(rng, 1)[0]
    n_rest, n_rot, n_trans = 100, 30, 30
    # Stationary robot, then rotation in 0.7 deg steps (about the tag carrier origin, so t_A is
    # unchanged), then translation in 4 mm steps (R_A unchanged).
    steps = [A_rest] * n_rest
    for i in range(1, n_rot + 1):
        steps.append(A_rest @ make_transform(so3_exp([0, 0, 0.7 * DEG * i]), np.zeros(3)))
    last = steps[-1]
    for i in range(1, n_trans + 1):
        steps.append(make_transform(np.eye(3), [0.004 * i, 0, 0]) @ last)
    A = np.stack(steps)
    B = pairs_for(rng, A)
    acc = PairAccumulator()  # defaults: 2 deg, 1 cm
    kept = [
        acc.offer("tag_0", "cam_0", i * 33 * MS, A[i], B[i], 0.005, 400.0) for i in range(len(A))
    ]
    # Independent expectation: only the first stationary pair; then every 3rd step
    # (3 x 0.7 = 2.1 deg > 2 deg; 3 x 4 mm = 12 mm > 10 mm; 2 steps are below both).
    expected = [i == 0 for i in range(n_rest)]
    expected += [i % 3 == 0 for i in range(1, n_rot + 1)]
    expected += [i % 3 == 0 for i in range(1, n_trans + 1)]
    assert kept == expected
    c = acc.counters()
    assert c["kept"] == 1 + 10 + 10
    assert c["skipped_no_motion"] == len(A) - 21
    assert acc.counts() == {("tag_0", "cam_0"): 21}
    e = acc.edges()[("tag_0", "cam_0")]
    np.testing.assert_array_equal(e.A, A[np.array(expected)])
    np.testing.assert_array_equal(e.B, B[np.array(expected)])
    assert e.stamps_ns.dtype == np.int64 and np.all(np.diff(e.stamps_ns) > 0)


def test_listeners_see_every_kept_pair():
    rng = np.random.default_rng(1)
    A = random_transforms(rng, 6)
    A[3] = A[2]  # not moved: not kept, not reported
    B = pairs_for(rng, A)
    seen = []
    acc = PairAccumulator()

    def listener(x, y, A_i, B_i):
        seen.append((x, y, A_i, B_i))

    acc.add_listener(listener)
    for i in range(6):
        acc.offer("t", "c", i, A[i], B[i], 0.01, 100.0)
    assert [s[:2] for s in seen] == [("t", "c")] * 5
    np.testing.assert_array_equal(np.stack([s[2] for s in seen]), A[[0, 1, 2, 4, 5]])
    np.testing.assert_array_equal(np.stack([s[3] for s in seen]), B[[0, 1, 2, 4, 5]])
    acc.remove_listener(listener)
    acc.offer("t", "c", 10, random_transforms(rng, 1)[0], B[0], 0.01, 100.0)
    assert len(seen) == 5
    with pytest.raises(ValueError, match="callback"):
        acc.remove_listener(listener)
    with pytest.raises(ValueError, match="callback"):
        acc.add_listener("not callable")


def min_pairwise_distance(A, rot_scale, trans_scale):
    """Brute force over all pairs, with scipy's geodesic distance (independent of the module)."""
    i, j = np.triu_indices(len(A), k=1)
    rot = rotation_distance(A[i, :3, :3], A[j, :3, :3]) / rot_scale
    trans = np.linalg.norm(A[i, :3, 3] - A[j, :3, 3], axis=-1) / trans_scale
    return float(np.maximum(rot, trans).min())


def test_full_edge_replaces_most_redundant_and_counts():
    rng = np.random.default_rng(2)
    n, cap = 150, 20
    A = random_transforms(rng, n, translation_scale=0.3)
    B = pairs_for(rng, A)
    acc = PairAccumulator(max_pairs_per_edge=cap)
    spread = []
    for i in range(n):
        acc.offer("t", "c", i, A[i], B[i], 0.01, 100.0)
        if i >= cap - 1:
            e = acc.edges()[("t", "c")]
            spread.append(min_pairwise_distance(e.A, acc.keyframe_rotation_rad, 0.01))
    c = acc.counters()
    assert acc.counts()[("t", "c")] == cap
    assert c["offered"] == n and c["skipped_no_motion"] == 0  # random poses all moved
    assert c["kept"] == cap + c["replaced_redundant"]
    assert c["kept"] + c["dropped_full"] == n
    assert c["replaced_redundant"] > 0 and c["dropped_full"] > 0
    # Invariant of the policy: the closest two stored poses never get closer (brute force).
    assert all(b >= a - 1e-9 for a, b in zip(spread, spread[1:]))  # 1e-9: arctan2 vs scipy
    assert spread[-1] > spread[0]
    # Stored pairs are still consistent pairs (A_i, B_i) taken together, sorted by stamp.
    e = acc.edges()[("t", "c")]
    idx = e.stamps_ns
    np.testing.assert_array_equal(e.A, A[idx])
    np.testing.assert_array_equal(e.B, B[idx])


def test_would_keep_predicts_every_offer_without_changing_anything():
    """``would_keep`` (stamp and A only) answers exactly what ``offer`` then does, through every
    rule: first pair, no motion, duplicate stamp, full edge (replace or drop), max_edges."""
    rng = np.random.default_rng(12)
    n, cap = 400, 12
    # A slow random walk: about half the steps move less than the keyframe thresholds.
    steps = [random_transforms(rng, 1)[0]]
    for _ in range(n - 1):
        d = make_transform(so3_exp(rng.normal(0.0, 1.5 * DEG, 3)), rng.normal(0.0, 0.006, 3))
        steps.append(steps[-1] @ d)
    A = np.stack(steps)
    B = pairs_for(rng, A)
    acc = PairAccumulator(max_pairs_per_edge=cap, max_edges=2)
    edges = [("t0", "c"), ("t1", "c"), ("t2", "c")]  # the third is beyond max_edges
    outcomes = set()
    for i in range(n):
        x, y = edges[i % 3]
        stamp = i - 3 * (i % 7 == 6)  # every 7th: the stamp of the same edge's previous offer
        before = (acc.counters(), acc.counts())
        predicted = acc.would_keep(x, y, stamp, A[i])
        assert (acc.counters(), acc.counts()) == before  # nothing changed
        kept = acc.offer(x, y, stamp, A[i], B[i], 0.01, 100.0)
        assert predicted == kept, i
        outcomes.add(next(k for k, v in acc.counters().items() if v != before[0][k]
                          and k != "offered"))
    # every rule was exercised
    assert outcomes >= {"kept", "skipped_no_motion", "dropped_full", "dropped_max_edges",
                        "duplicate_stamp"}
    assert acc.counters()["replaced_redundant"] > 0


def test_memory_bound_respected():
    rng = np.random.default_rng(3)
    max_pairs, max_edges, n_offer = 130, 3, 160
    A = random_transforms(rng, n_offer)
    B = random_transforms(rng, n_offer)
    gc.collect()
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        acc = PairAccumulator(max_pairs_per_edge=max_pairs, max_edges=max_edges)
        for e in range(max_edges + 1):
            for i in range(n_offer):
                acc.offer(f"tag_{e}", "cam_0", i, A[i], B[i], 0.01, 100.0)
        gc.collect()
        held = tracemalloc.get_traced_memory()[0] - base
    finally:
        tracemalloc.stop()
    assert acc.counts() == {(f"tag_{e}", "cam_0"): max_pairs for e in range(max_edges)}
    assert acc.counters()["dropped_max_edges"] == n_offer
    assert acc.nbytes() == max_edges * max_pairs * 360  # slots grew 64 -> 128 -> 130
    assert held <= acc.memory_bound_bytes()  # everything allocated, object headers included
    assert acc.memory_bound_bytes() == max_edges * (360 * max_pairs + 8192)


def test_duplicates_invalid_and_strict():
    rng = np.random.default_rng(4)
    A = random_transforms(rng, 3)
    acc = PairAccumulator()
    assert acc.offer("t", "c", 5, A[0], A[1], 0.01, 100.0)
    assert not acc.offer("t", "c", 5, A[2], A[1], 0.01, 100.0)
    bad_B = A[1].copy()
    bad_B[0, 0] = np.nan
    assert not acc.offer("t", "c", 6, A[2], bad_B, 0.01, 100.0)
    assert not acc.offer("t", "c", 7, A[2], A[1], -0.01, 100.0)
    assert not acc.offer("t", "c", 8.0, A[2], A[1], 0.01, 100.0)
    c = acc.counters()
    assert (c["duplicate_stamp"], c["rejected_invalid"], c["kept"]) == (1, 3, 1)
    with pytest.raises(ValueError, match=r"offer \(t, c\) B\[0\]: non-finite"):
        acc.offer("t", "c", 6, A[2], bad_B, 0.01, 100.0, strict=True)
    with pytest.raises(ValueError, match="sigma"):
        acc.offer("t", "c", 7, A[2], A[1], -0.01, 100.0, strict=True)


def test_frame_role_conflicts_raise():
    acc = PairAccumulator()
    acc.offer("tag_0", "cam_0", 0, np.eye(4), np.eye(4), 0.01, 100.0)
    with pytest.raises(ValueError, match="Y-frame"):
        acc.offer("cam_0", "cam_1", 1, np.eye(4), np.eye(4), 0.01, 100.0)
    with pytest.raises(ValueError, match="X-frame"):
        acc.offer("tag_1", "tag_0", 1, np.eye(4), np.eye(4), 0.01, 100.0)
    with pytest.raises(ValueError, match="differ"):
        acc.offer("a", "a", 1, np.eye(4), np.eye(4), 0.01, 100.0)
    with pytest.raises(ValueError, match="x"):
        acc.offer("", "cam_0", 1, np.eye(4), np.eye(4), 0.01, 100.0)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"keyframe_rotation_rad": 0.0}, "keyframe_rotation_rad"),
        ({"keyframe_translation_m": np.inf}, "keyframe_translation_m"),
        ({"max_pairs_per_edge": 1}, "max_pairs_per_edge"),
        ({"max_edges": 0}, "max_edges"),
    ],
)
def test_constructor_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        PairAccumulator(**kwargs)


def test_to_problem_excludes_and_orders():
    rng = np.random.default_rng(5)
    X = random_transforms(rng, 3)
    Y = random_transforms(rng, 2)
    acc = PairAccumulator()
    n_pairs = {("tag_2", "cam_1"): 5, ("tag_0", "cam_0"): 4, ("tag_1", "cam_0"): 2,
               ("tag_0", "cam_1"): 3}
    for (x, y), n in n_pairs.items():
        A = random_transforms(rng, n)
        B = pairs_for(rng, A, X[int(x[-1])], Y[int(y[-1])])
        for i in range(n):
            acc.offer(x, y, 1000 + i, A[i], B[i], 0.01 + i * 1e-3, 100.0 + i)
    problem, excluded = acc.to_problem(min_pairs=3)
    assert excluded == {("tag_1", "cam_0"): "2 pairs < min_pairs=3"}
    assert problem.x_names == ("tag_0", "tag_2") and problem.y_names == ("cam_0", "cam_1")
    assert [(e.x, e.y) for e in problem.edges] == [
        ("tag_0", "cam_0"), ("tag_0", "cam_1"), ("tag_2", "cam_1")]
    e = problem.edges[2]
    np.testing.assert_array_equal(e.A, acc.edges()[("tag_2", "cam_1")].A)
    np.testing.assert_array_equal(e.sigma, 0.01 + np.arange(5) * 1e-3)
    assert not problem.unknown_scale

    problem, excluded = acc.to_problem(x_names=["tag_2", "tag_1"], y_names=["cam_1", "cam_0"],
                                       unknown_scale=True, min_pairs=1)
    assert problem.x_names == ("tag_2", "tag_1") and problem.y_names == ("cam_1", "cam_0")
    assert [(e.x, e.y) for e in problem.edges] == [("tag_2", "cam_1"), ("tag_1", "cam_0")]
    assert excluded == {("tag_0", "cam_0"): "X frame 'tag_0' not in x_names",
                        ("tag_0", "cam_1"): "X frame 'tag_0' not in x_names"}
    assert problem.unknown_scale

    with pytest.raises(ValueError, match="no edge"):
        acc.to_problem(min_pairs=6)
    with pytest.raises(ValueError, match="min_pairs"):
        acc.to_problem(min_pairs=0)

    # the live re-solve's snapshot: read-only arrays, the same problem without re-validation
    kept = acc.kept_pairs()
    assert {k: v.n for k, v in kept.items()} == acc.counts()
    with pytest.raises(ValueError, match="read-only"):
        kept[("tag_2", "cam_1")].A[0] = 0.0  # the accumulator cannot be changed through it
    assert np.all(acc.kept_pairs()[("tag_2", "cam_1")].A[0][3] == [0, 0, 0, 1])
    reference, excl_ref = acc.to_problem(min_pairs=3)
    problem, excluded = problem_from_edges(acc.kept_pairs(), min_pairs=3, validate=False)
    assert excluded == excl_ref and problem.frame_names == reference.frame_names
    for a, b in zip(problem.edges, reference.edges, strict=True):
        assert (a.x, a.y) == (b.x, b.y)
        for name in ("A", "B", "sigma", "kappa"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_edges_are_dataset_records_with_the_accumulator_tolerance():
    """edges() returns the Dataset's own record type, validated with the accumulator's
    rotation tolerance: pairs it accepted with a looser tolerance still make a Dataset."""
    from rwhec_ros.data.dataset import Dataset, DatasetEdge

    rng = np.random.default_rng(12)
    A = random_transforms(rng, 3)
    B = pairs_for(rng, A)
    A[0, :3, :3] *= 1.0 + 1e-5  # |R^T R - I| ~ 2e-5: above the default 1e-6, below 1e-4
    acc = PairAccumulator(rotation_tol=1e-4)  # random poses: far apart, all keyframes
    assert all(acc.offer("tag_0", "cam_0", i * MS, A[i], B[i], 0.005, 400.0) for i in range(3))
    e = acc.edges()[("tag_0", "cam_0")]
    assert isinstance(e, DatasetEdge) and e.rotation_tol == 1e-4
    ds = Dataset.from_accumulator(acc)
    np.testing.assert_array_equal(ds.edges[0].A, A)
    with pytest.raises(ValueError, match=r"edge \(tag_0, cam_0\) A\[0\]: rotation block"):
        DatasetEdge("tag_0", "cam_0", e.stamps_ns, e.A, e.B, e.sigma, e.kappa)


def test_set_precisions_rewrites_every_kept_pair_only():
    rng = np.random.default_rng(5)
    A = random_transforms(rng, 12)  # random poses: every one is a keyframe
    B = pairs_for(rng, A)
    acc = PairAccumulator()
    for i in range(6):
        acc.offer("tag_0", "cam_0", i * MS, A[i], B[i], 0.005, 400.0)
        acc.offer("tag_1", "cam_0", i * MS, A[i + 6], B[i + 6], 0.005, 400.0)
    assert acc.set_precisions(0.02, 50.0) == 12
    for e in acc.edges().values():
        assert np.all(e.sigma == 0.02) and np.all(e.kappa == 50.0)
    acc.offer("tag_0", "cam_0", 10 * MS, A[0] @ make_transform(so3_exp([0.3, 0, 0]),
                                                                np.zeros(3)), B[0], 0.007, 90.0)
    e = acc.edges()[("tag_0", "cam_0")]
    assert e.sigma[-1] == 0.007 and e.kappa[-1] == 90.0  # later pairs keep their own values
    problem, _ = acc.to_problem(min_pairs=1)
    assert sorted(set(np.concatenate([x.sigma for x in problem.edges]))) == [0.007, 0.02]
    for bad, name in [((0.0, 1.0), "sigma"), ((0.01, np.inf), "kappa")]:
        with pytest.raises(ValueError, match=name):
            acc.set_precisions(*bad)

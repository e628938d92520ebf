"""PoseBuffer: ordering, duplicates, resets, capacity, validation and lookups (no ROS)."""

import numpy as np
import pytest

from rwhec_ros.simulation.synthetic import random_transforms
from rwhec_ros.sync.buffer import LookupStatus, PoseBuffer
from rwhec_ros.sync.interpolation import interpolate_se3

MS = 1_000_000  # ns per millisecond
T0_NS = 1_700_000_000 * 1_000_000_000  # a realistic epoch stamp (exceeds 2^53: must stay int)


def filled(rng, n=10, period_ms=10, **kwargs):
    buf = PoseBuffer(**kwargs)
    stamps = [T0_NS + i * period_ms * MS for i in range(n)]
    poses = random_transforms(rng, n, translation_scale=0.5)
    for s, T in zip(stamps, poses):
        assert buf.add(s, T)
    return buf, stamps, poses


def nonzero(counters):
    return {k: v for k, v in counters.items() if v}


def test_interpolates_between_bracketing_samples():
    rng = np.random.default_rng(0)
    buf, stamps, poses = filled(rng)
    stamp = stamps[3] + 4 * MS  # 40 % of the way to stamps[4]
    # Bit-exact: the buffer calls the same function with u = 4 ms / 10 ms.
    np.testing.assert_array_equal(buf.lookup(stamp), interpolate_se3(poses[3], poses[4], 0.4))
    np.testing.assert_array_equal(buf.lookup(stamps[6]), poses[6])
    assert nonzero(buf.counters()) == {"added": 10, "lookup_interpolated": 1, "lookup_exact": 1}


def test_stamps_outside_buffer_rejected_and_counted():
    rng = np.random.default_rng(1)
    buf, stamps, poses = filled(rng, extrapolation_tol_ns=5 * MS, max_gap_ns=100 * MS)
    # Within the tolerance outside the buffer: nearest sample, unchanged.
    np.testing.assert_array_equal(buf.lookup(stamps[0] - 5 * MS), poses[0])
    np.testing.assert_array_equal(buf.lookup(stamps[-1] + 5 * MS), poses[-1])
    assert buf.lookup(stamps[0] - 5 * MS - 1) is None
    assert buf.lookup(stamps[-1] + 5 * MS + 1) is None  # a WAIT stamp, counted as after_buffer
    assert buf.lookup(stamps[-1] + 500 * MS) is None
    c = buf.counters()
    assert (c["lookup_nearest"], c["lookup_before_buffer"], c["lookup_after_buffer"]) == (2, 1, 2)
    assert PoseBuffer().lookup(T0_NS) is None
    assert PoseBuffer().lookup_status(T0_NS) is LookupStatus.EMPTY


def test_gap_too_large_and_nearest_inside_gap():
    rng = np.random.default_rng(2)
    poses = random_transforms(rng, 3)
    buf = PoseBuffer(max_gap_ns=100 * MS, extrapolation_tol_ns=5 * MS)
    for s, T in zip([0, 100 * MS, 301 * MS], poses):
        buf.add(s, T)
    assert buf.lookup(50 * MS) is not None  # gap of exactly max_gap_ns is interpolated
    assert buf.lookup_status(200 * MS) is LookupStatus.GAP_TOO_LARGE
    assert buf.lookup(200 * MS) is None
    np.testing.assert_array_equal(buf.lookup(103 * MS), poses[1])  # within tol of a sample
    np.testing.assert_array_equal(buf.lookup(297 * MS), poses[2])
    c = buf.counters()
    assert (c["lookup_gap_too_large"], c["lookup_nearest"], c["lookup_interpolated"]) == (1, 2, 1)


def test_lookup_status_wait_then_ok_when_pose_arrives():
    rng = np.random.default_rng(3)
    buf, stamps, poses = filled(rng, max_gap_ns=100 * MS, extrapolation_tol_ns=5 * MS)
    image = stamps[-1] + 30 * MS
    before = buf.counters()
    assert buf.lookup_status(image) is LookupStatus.WAIT
    assert buf.lookup_status(image).retry
    assert buf.counters() == before  # lookup_status does not count
    assert buf.lookup_status(stamps[-1] + 101 * MS) is LookupStatus.AFTER_BUFFER
    assert not LookupStatus.AFTER_BUFFER.retry
    assert buf.lookup_status(stamps[0] - 6 * MS) is LookupStatus.BEFORE_BUFFER
    new_pose = random_transforms(rng, 1)[0]
    buf.add(stamps[-1] + 40 * MS, new_pose)
    assert buf.lookup_status(image) is LookupStatus.OK
    np.testing.assert_array_equal(buf.lookup(image), interpolate_se3(poses[-1], new_pose, 0.75))


def test_duplicates_counted_first_wins():
    rng = np.random.default_rng(4)
    buf, stamps, poses = filled(rng, n=3)
    assert not buf.add(stamps[1], np.eye(4))
    assert buf.counters()["duplicate"] == 1
    assert len(buf) == 3
    np.testing.assert_array_equal(buf.lookup(stamps[1]), poses[1])


def test_out_of_order_inserted_in_order_and_counted():
    rng = np.random.default_rng(5)
    poses = random_transforms(rng, 20)
    stamps = [T0_NS + i * 10 * MS for i in range(20)]
    sorted_buf = PoseBuffer()
    for s, T in zip(stamps, poses):
        sorted_buf.add(s, T)
    order = rng.permutation(20)
    shuffled = PoseBuffer()
    for i in order:
        assert shuffled.add(stamps[i], poses[i])
    np.testing.assert_array_equal(shuffled.stamps(), np.array(stamps, dtype=np.int64))
    # Each insertion that lands before the current newest is out of order.
    newest, expected = -1, 0
    for i in order:
        expected += i < newest
        newest = max(newest, i)
    assert shuffled.counters()["out_of_order"] == expected > 0
    for q in (stamps[0] + 3 * MS, stamps[7] + 9 * MS, stamps[19] + 2 * MS):
        np.testing.assert_array_equal(shuffled.lookup(q), sorted_buf.lookup(q))


def test_one_stale_sample_is_dropped_and_counted_not_a_reset():
    """Issue 39: 11 stale poses gave 11 resets of the whole buffer. A stale sample between samples
    of the current time line is dropped and counted; the buffer is untouched."""
    rng = np.random.default_rng(6)
    buf, stamps, _ = filled(rng, n=150, period_ms=10)  # spans 1.49 s
    assert buf.add(stamps[-1] - 900 * MS + 1, np.eye(4))  # 0.9 s back: only out of order
    assert buf.counters()["reset_backwards_jump"] == 0 and len(buf) == 151
    before = buf.lookup(stamps[100] + 3 * MS)
    t = stamps[-1]
    for k in range(11):  # 11 stale samples, each followed by a fresh one
        assert not buf.add(stamps[0] - 10 * MS - k * MS, np.eye(4))
        t += 10 * MS
        assert buf.add(t, np.eye(4))
    c = buf.counters()
    assert c["reset_backwards_jump"] == 0 and c["dropped_stale"] == 11
    assert len(buf) == 151 + 11 and buf.oldest_ns == stamps[0]
    np.testing.assert_array_equal(buf.lookup(stamps[100] + 3 * MS), before)


def test_a_short_run_of_stale_samples_is_dropped_when_the_time_line_goes_on():
    rng = np.random.default_rng(7)
    buf, stamps, _ = filled(rng, n=150, period_ms=10, backwards_jump_samples=5)
    for k in range(4):  # one short of a persistent jump
        assert not buf.add(stamps[0] - 2000 * MS + k * 10 * MS, np.eye(4))
    assert buf.counters()["dropped_stale"] == 0  # held aside, not decided yet
    assert buf.lookup(stamps[0] - 2000 * MS, count=False) is None  # not looked up meanwhile
    assert buf.add(stamps[-1] + 10 * MS, np.eye(4))  # the current time line goes on
    c = buf.counters()
    assert c["dropped_stale"] == 4 and c["reset_backwards_jump"] == 0 and len(buf) == 151


@pytest.mark.parametrize("run", [1, 5])
def test_a_persistent_backwards_jump_resets_to_the_new_time_line(run):
    """A bag played in a loop: every sample after the jump is stale; after ``run`` of them the
    buffer holds that run (nothing of the new time line is lost) and the old one is gone."""
    rng = np.random.default_rng(8)
    buf, stamps, _ = filled(rng, n=150, period_ms=10, backwards_jump_samples=run)
    loop = [stamps[0] - 10 * MS + k * 10 * MS for k in range(8)]  # 1.5 s back, then onwards
    poses = random_transforms(rng, len(loop), translation_scale=0.5)
    held = [buf.add(s, T) for s, T in zip(loop, poses)]
    assert held == [False] * (run - 1) + [True] * (len(loop) - run + 1)
    c = buf.counters()
    assert c["reset_backwards_jump"] == 1 and c["dropped_stale"] == 0
    assert len(buf) == len(loop) and buf.oldest_ns == loop[0] and buf.newest_ns == loop[-1]
    assert buf.lookup(stamps[100]) is None  # the old time line is gone
    np.testing.assert_array_equal(buf.lookup(loop[0]), poses[0])  # the run's first sample kept
    u = interpolate_se3(poses[1], poses[2], 0.5)
    np.testing.assert_allclose(buf.lookup(loop[1] + 5 * MS), u, atol=1e-12)


def test_capacity_evicts_oldest_and_drops_older():
    buf = PoseBuffer(capacity=5)
    for i in range(8):
        buf.add(T0_NS + i * MS, np.eye(4))
    assert len(buf) == 5 and buf.oldest_ns == T0_NS + 3 * MS
    assert not buf.add(T0_NS + 2 * MS, np.eye(4))  # older than everything in a full buffer
    assert buf.add(T0_NS + 5 * MS + MS // 2, np.eye(4))  # inside: evicts the oldest
    assert nonzero(buf.counters()) == {
        "added": 9,
        "evicted": 4,
        "dropped_too_old": 1,
        "out_of_order": 1,
    }
    assert buf.oldest_ns == T0_NS + 4 * MS


@pytest.mark.parametrize(
    "stamp, T, counter",
    [
        (T0_NS, np.full((4, 4), np.nan), "rejected_non_finite"),
        (T0_NS, np.diag([1.0, 1.0, np.inf, 1.0]), "rejected_non_finite"),
        (T0_NS, np.diag([2.0, 2.0, 2.0, 1.0]), "rejected_not_rigid"),  # scaled rotation
        (T0_NS, np.diag([1.0, 1.0, -1.0, 1.0]), "rejected_not_rigid"),  # reflection, det -1
        (T0_NS, np.zeros((4, 4)), "rejected_not_rigid"),  # e.g. from a zero quaternion
        (T0_NS, np.vstack([np.eye(4)[:3], [0.0, 0.0, 1.0, 1.0]]), "rejected_not_rigid"),
        (T0_NS, np.eye(3), "rejected_shape"),
        (T0_NS, "not a pose", "rejected_shape"),
        (1.5e18, np.eye(4), "rejected_bad_stamp"),  # float seconds/ns are not accepted
        (-1, np.eye(4), "rejected_bad_stamp"),
        (True, np.eye(4), "rejected_bad_stamp"),
    ],
)
def test_bad_samples_counted_not_raised(stamp, T, counter):
    buf = PoseBuffer()
    assert buf.add(stamp, T) is False
    assert nonzero(buf.counters()) == {counter: 1}
    assert len(buf) == 0
    with pytest.raises(ValueError, match="stamp_ns|T at stamp"):
        buf.add(stamp, T, strict=True)


def test_numpy_integer_stamps_and_copies():
    buf = PoseBuffer()
    T = np.eye(4)
    assert buf.add(np.int64(T0_NS), T)
    T[0, 3] = 5.0  # caller mutates its array afterwards
    assert buf.lookup(T0_NS)[0, 3] == 0.0
    buf.lookup(T0_NS)[0, 3] = 7.0  # and the returned array
    assert buf.lookup(T0_NS)[0, 3] == 0.0


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"capacity": 1}, "capacity"),
        ({"capacity": 10.0}, "capacity"),
        ({"max_gap_ns": 0}, "max_gap_ns"),
        ({"extrapolation_tol_ns": -1}, "extrapolation_tol_ns"),
        ({"backwards_jump_ns": 0}, "backwards_jump_ns"),
        ({"backwards_jump_samples": 0}, "backwards_jump_samples"),
        ({"rotation_tol": 0.0}, "rotation_tol"),
    ],
)
def test_constructor_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        PoseBuffer(**kwargs)


def test_lookup_rejects_non_integer_stamp():
    with pytest.raises(ValueError, match="stamp_ns"):
        PoseBuffer().lookup(1.5)

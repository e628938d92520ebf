"""The pose stream recorded around kept pairs (rwhec_ros.sync.pose_track): lookups equal to the
pose buffer's, rates exact on constant-twist motion, the windows recorded whatever comes first
(sample or mark), snapshots that never change, the memory bound, validation."""

from __future__ import annotations

import numpy as np
import pytest

from rwhec_ros.core.lie import make_transform, so3_exp
from rwhec_ros.sync.buffer import PoseBuffer
from rwhec_ros.sync.interpolation import se3_exp
from rwhec_ros.sync.pose_track import PoseTrack, PoseTrackData, track_window_ns

MS = 1_000_000
XI = np.array([0.3, -0.2, 0.1, 0.4, 0.2, -0.5])  # constant twist [m/s, rad/s]
A0 = make_transform(so3_exp(np.array([0.1, 0.2, 0.3])), np.array([1.0, 2.0, 3.0]))


def pose(t_ns: int) -> np.ndarray:
    return se3_exp(XI * (t_ns * 1e-9)) @ A0


def samples(t0: int, t1: int, step: int = 10 * MS):
    return [(t, pose(t)) for t in range(t0, t1 + 1, step)]


def test_lookup_equals_the_pose_buffer_and_rates_are_exact_on_constant_twist():
    rng = np.random.default_rng(0)
    stream = [(t, make_transform(so3_exp(rng.normal(size=3)), rng.normal(size=3)))
              for t in range(0, 1000 * MS, 10 * MS)]
    buf = PoseBuffer(capacity=1000, max_gap_ns=100 * MS, extrapolation_tol_ns=0)
    for t, T in stream:
        buf.add(t, T)
    data = PoseTrackData(np.array([t for t, _ in stream]), np.array([T for _, T in stream]),
                         100 * MS)
    q = rng.integers(0, 990 * MS, size=50)
    A, ok = data.lookup(q)
    assert ok.all()
    for a, s in zip(A, q, strict=True):
        np.testing.assert_allclose(a, buf.lookup(int(s)), atol=1e-12)  # same interpolation
    # outside the samples, or inside a gap above max_gap_ns: not served
    gap = PoseTrackData(np.array([0, 10 * MS, 500 * MS]), np.array([A0, A0, A0]), 100 * MS)
    assert gap.lookup([5 * MS, 100 * MS, 600 * MS, -1])[1].tolist() == [True, False, False,
                                                                        False]
    const = PoseTrackData(*map(np.array, zip(*samples(0, 1000 * MS), strict=True)), 100 * MS)
    xi, ok = const.rates([200 * MS, 505 * MS, 995 * MS])
    assert ok.tolist() == [True, True, False]  # 995 + 10 ms is past the last sample
    np.testing.assert_allclose(xi[:2], [XI, XI], atol=1e-9)  # exact on constant twist
    shift, angle = const.motion([500 * MS], 50 * MS)
    np.testing.assert_allclose(angle, [0.1 * np.linalg.norm(XI[3:])], rtol=1e-9)
    assert shift[0] > 0


def test_windows_are_recorded_whether_the_mark_or_the_samples_come_first():
    """A mark records the recent samples around it and the later ones within its window; the
    recorded set is the same in either order and holds only the windows' samples."""
    window = track_window_ns(0.1)  # + max_gap inside the track
    early, late = PoseTrack(window, 20 * MS), PoseTrack(window, 20 * MS)
    stream = samples(0, 3000 * MS)
    marks = [1000 * MS, 1005 * MS, 2500 * MS]
    for t, T in stream:  # marks after all samples: filled from the recent ones
        early.add(t, T)
    for m in marks:
        early.mark(m)
    for m in marks:  # marks before the samples: filled as they arrive
        late.mark(m)
    for t, T in stream:
        late.add(t, T)
    a, b = early.data(), late.data()
    np.testing.assert_array_equal(a.stamps_ns, b.stamps_ns)
    np.testing.assert_array_equal(a.poses, b.poses)
    half = window + 20 * MS
    expected = [t for t, _ in stream if any(abs(t - m) <= half for m in marks)]
    assert a.stamps_ns.tolist() == expected
    # every stamp within the offsets' range of a mark can be re-interpolated with its rate
    q = np.array(marks)[:, None] + np.array([-100, -37, 0, 42, 100]) * MS
    assert a.rates(q.ravel())[1].all()


def test_snapshots_never_change_and_memory_is_bounded():
    track = PoseTrack(50 * MS, 20 * MS, max_samples=30)
    track.mark(500 * MS)
    for t, T in samples(400 * MS, 600 * MS, 20 * MS):
        track.add(t, T)
    snap = track.data()
    assert track.data() is snap  # nothing recorded since
    before = snap.stamps_ns.copy(), snap.poses.copy()
    with pytest.raises(ValueError):
        snap.poses[0, 0, 0] = 2.0  # read-only
    track.add(431 * MS, pose(431 * MS))  # late sample inside the window: inserted in order
    np.testing.assert_array_equal(snap.stamps_ns, before[0])
    np.testing.assert_array_equal(snap.poses, before[1])
    assert 431 * MS in track.data().stamps_ns
    for t in range(800, 5000, 10):  # a new window beyond max_samples: counted, not recorded
        track.mark(t * MS)
        track.add(t * MS, pose(t * MS))
    assert len(track) == 30 and track.counters["full"] > 0


def test_bad_input_is_refused_with_the_field():
    with pytest.raises(ValueError, match=r"poses: expected shape \(2, 4, 4\)"):
        PoseTrackData(np.array([0, 1]), np.zeros((3, 4, 4)), 10)
    with pytest.raises(ValueError, match=r"stamps_ns\[1\]: must be after"):
        PoseTrackData(np.array([5, 5]), np.array([A0, A0]), 10)
    with pytest.raises(ValueError, match="integer nanoseconds"):
        PoseTrackData(np.array([0.5, 1.5]), np.array([A0, A0]), 10)
    with pytest.raises(ValueError, match="max_gap_ns"):
        PoseTrackData(np.array([0, 1]), np.array([A0, A0]), 0)
    with pytest.raises(ValueError, match="window_ns"):
        PoseTrack(-1, 10)

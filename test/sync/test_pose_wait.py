"""PoseLatency and wait_deadline: how long an image waits for its pose (no ROS)."""

import pytest

from rwhec_ros.sync.pose_wait import MIN_MARGIN_NS, PoseLatency, wait_deadline

MS = 1_000_000


def test_ages_over_the_window_with_a_clock_offset():
    lat = PoseLatency(window_ns=1000 * MS, min_samples=3)
    offset = 5_000_000 * MS  # stamps of another clock, 5000 s behind: only constant matters
    assert lat.ages() is None
    for k, age_ms in enumerate([30, 230, 265, 27, 40]):
        now = 10_000 * MS + k * 50 * MS
        lat.record(now - offset - age_ms * MS, now)
    assert lat.ages() == (offset + 27 * MS, offset + 265 * MS)
    assert lat.count() == 5
    # 1 s later, with nothing new, the window is empty again
    assert lat.ages(now_ns=10_000 * MS + 1_300 * MS) is None


def test_old_ages_leave_the_window_and_a_clock_going_back_clears_it():
    lat = PoseLatency(window_ns=1000 * MS, min_samples=1)
    lat.record(0, 500 * MS)  # a 500 ms age
    for k in range(20):
        now = 600 * MS + k * 100 * MS
        lat.record(now - 10 * MS, now)
    lo, hi = lat.ages()
    assert lo == hi == 10 * MS  # the 500 ms age is more than 1 s old now
    lat.record(0, 100 * MS)  # a simulator reset: the clock went back 2.4 s
    assert lat.ages() == (100 * MS, 100 * MS) and lat.count() == 1


def test_bucketed_memory_stays_bounded_at_a_high_rate():
    lat = PoseLatency(window_ns=1000 * MS, min_samples=1)
    for k in range(20_000):  # 20 kHz for 1 s
        now = k * MS // 20
        lat.record(now - 3 * MS, now)
    assert len(lat._buckets) <= 11
    assert lat.ages() == (3 * MS, 3 * MS)


def test_deadline_follows_the_ages_and_is_capped_by_the_wait():
    gap, wait = 100 * MS, 1000 * MS
    s, arrived = 50_000 * MS, 50_030 * MS
    # no ages yet: only the cap
    d = wait_deadline(s, arrived, None, max_gap_ns=gap, max_wait_ns=wait)
    assert (d.at_ns, d.timeout) == (arrived + wait, True)
    # issue 39's pose stream: ages 27-265 ms; margin a quarter of the spread
    d = wait_deadline(s, arrived, (27 * MS, 265 * MS), max_gap_ns=gap, max_wait_ns=wait)
    assert not d.timeout
    assert d.at_ns == s + gap + 265 * MS + (265 - 27) * MS // 4
    # a steady stream: the smallest margin
    d = wait_deadline(s, arrived, (5 * MS, 6 * MS), max_gap_ns=gap, max_wait_ns=wait)
    assert d.at_ns == s + gap + 6 * MS + MIN_MARGIN_NS
    # ages beyond the cap: the cap, said so
    d = wait_deadline(s, arrived, (5 * MS, 2000 * MS), max_gap_ns=gap, max_wait_ns=wait)
    assert (d.at_ns, d.timeout) == (arrived + wait, True)


@pytest.mark.parametrize("kw", [{"window_ns": 10}, {"min_samples": 0}])
def test_invalid_arguments(kw):
    with pytest.raises(ValueError, match=next(iter(kw))):
        PoseLatency(**kw)

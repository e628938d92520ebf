"""RateGate: one event per period, thread-safe, 0 = off."""

import threading

import pytest

from rwhec_ros.session.rate_gate import RateGate


def test_one_event_per_period():
    now = [10.0]
    gate = RateGate(2.0, clock=lambda: now[0])  # period 0.5 s
    assert gate.take() and not gate.take()
    now[0] += 0.49
    assert not gate.take()
    now[0] += 0.02  # 0.51 s after the first
    assert gate.take() and not gate.take()


def test_off_and_bad_rates():
    assert not RateGate(0.0).take()
    for bad in (-1.0, float("inf"), float("nan")):
        with pytest.raises(ValueError, match="rate_hz"):
            RateGate(bad)


def test_threads_share_one_slot():
    gate = RateGate(0.001)  # one slot in 1000 s
    results = []
    threads = [threading.Thread(target=lambda: results.append(gate.take())) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert sorted(results) == [False] * 7 + [True]

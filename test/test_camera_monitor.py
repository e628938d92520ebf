"""Per-camera monitoring: transport loss from the stamps' spacing, and the /diagnostics rows."""

from __future__ import annotations

import numpy as np
import pytest

from rwhec_ros.messages import LEVEL_OK, LEVEL_WARN
from rwhec_ros.session.camera_monitor import CameraDiagnostics, StampRateMonitor

MS = 1_000_000
PERIOD = 33_333_333  # 30 Hz


def stamps(n: int, rng: np.random.Generator, lost: float, jitter_ns: int = 500_000) -> list:
    """Stamps of a 30 Hz camera with capture jitter, a fraction ``lost`` missing at random."""
    t = np.arange(n) * PERIOD + rng.integers(-jitter_ns, jitter_ns, n)
    return [int(s) for s in t[rng.random(n) >= lost]]


@pytest.mark.parametrize("lost", [0.0, 0.1, 0.5, 0.7])
def test_loss_estimate_from_stamp_spacing(lost):
    rng = np.random.default_rng(int(100 * lost))
    m = StampRateMonitor(["cam0"], window=200)
    for s in stamps(2000, rng, lost):
        m.record("cam0", s)
    est = m.estimate("cam0")
    # 30 Hz published, whatever the loss: the 25th percentile of the spacings is one period
    # (1 ms of jitter on 33 ms: within 5 %)
    assert est.publish_rate_hz == pytest.approx(30.0, rel=0.05)
    # 200 samples of a Bernoulli loss: the estimate within 0.08 of the truth (about 2.5 sigma
    # of the binomial spread at 50 %, plus the jitter's bias on the period)
    assert est.lost_fraction == pytest.approx(lost, abs=0.08)
    assert est.received_rate_hz == pytest.approx(30.0 * (1 - lost), rel=0.15)


def test_monitor_edges():
    m = StampRateMonitor(["a"], window=10, min_samples=5)
    for s in range(4):
        m.record("a", s * PERIOD)
    assert m.estimate("a") is None  # too few samples
    m.record("a", 4 * PERIOD)
    assert m.estimate("a").lost_fraction == 0.0
    m.record("b", 0)  # unknown camera: ignored
    m.record("a", 1.5)  # not an integer stamp: ignored
    assert m.estimate("b") is None
    m.record("a", 0)  # a repeated stamp counts once
    assert m.estimate("a").samples == 5
    m.record("a", -10 * 1_000_000_000)  # a bag restarting 10 s earlier: the window restarts
    assert m.estimate("a") is None
    with pytest.raises(ValueError, match="window"):
        StampRateMonitor(["a"], window=2)
    with pytest.raises(ValueError, match="min_samples"):
        StampRateMonitor(["a"], window=10, min_samples=11)


def test_camera_rows_warn_on_transport_loss_and_queue_drops():
    rng = np.random.default_rng(1)
    diag = CameraDiagnostics(["cam0", "cam1"])
    for s in stamps(150, rng, 0.0):
        diag.record("cam0", s)
    for s in stamps(300, rng, 0.5):
        diag.record("cam1", s)
    session = {"cam0": {"images": 150, "skipped_no_motion": 100, "detected": 50, "used": 9,
                        "rejected": 0, "pairs_kept": 12},
               "cam1": {"images": 150, "skipped_no_motion": 0, "detected": 150, "used": 0,
                        "rejected": 0, "pairs_kept": 0}}
    queue = {"cam0": {"received": 150, "dropped": 0, "queued": 0, "processed": 150},
             "cam1": {"received": 155, "dropped": 5, "queued": 0, "processed": 150}}
    rows = diag.rows(session, queue, prefix="calibrator")
    assert [r["name"] for r in rows] == ["calibrator: camera cam0", "calibrator: camera cam1"]
    ok, lossy = rows
    assert ok["level"] == LEVEL_OK
    assert ok["message"] == "150 received, 100 skipped (no motion), 50 searched, 0 dropped, " \
        "12 pairs"
    values = dict(ok["values"])
    assert values["received"] == "150" and values["skipped_no_motion"] == "100"
    assert float(values["lost_in_transport"]) < 0.05
    assert lossy["level"] == LEVEL_WARN
    assert "lost in transport" in lossy["message"] and "Losing images" in lossy["message"]
    assert "5 images dropped from the full queue" in lossy["message"]
    # the queue warning is about new drops: none since the last report
    again = diag.rows(session, queue, prefix="calibrator")[1]
    assert "dropped from the full queue" not in again["message"]
    assert again["level"] == LEVEL_WARN  # the transport still loses half
    with pytest.raises(ValueError, match="loss_warn_fraction"):
        CameraDiagnostics(["a"], loss_warn_fraction=1.0)

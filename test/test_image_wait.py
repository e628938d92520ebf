"""Images waiting for the pose at their stamp (issue 39): the session's rule, its causes and
bounds, with a fake clock (no ROS)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rwhec_ros.config import CalibratorConfig, read_parameter_file
from rwhec_ros.session import CalibrationSession
from rwhec_ros.simulation import demo_rig

DEMO_YAML = Path(__file__).resolve().parents[1] / "config" / "demo.yaml"
NS = 1_000_000_000
MS = 1_000_000


def config(tmp: Path, **overrides) -> CalibratorConfig:
    flat = {k: v for k, v in read_parameter_file(DEMO_YAML).items()
            if not k.startswith("cameras.")}
    flat.update({"output.directory": str(tmp), "cameras.names": ["cam0"], "tags.ids": [3],
                 "cameras.cam0.image_topic": "/demo/cam0/image_raw",
                 "cameras.cam0.camera_info_topic": "/demo/cam0/camera_info"})
    flat.update(overrides)
    return CalibratorConfig.from_parameters(flat)


class Clock:
    def __init__(self, t: int = 0) -> None:
        self.t = t

    def __call__(self) -> int:
        return self.t


class Blank:
    """A lazily decoded image without tags (examined: ``no_tags``)."""

    def __init__(self, intr) -> None:
        self.gray = np.zeros((intr.height, intr.width), np.uint8)
        self.nbytes = self.gray.nbytes
        self.calls = 0

    def __call__(self) -> np.ndarray:
        self.calls += 1
        return self.gray


def session_with_clock(tmp_path, **overrides) -> tuple[CalibrationSession, Clock, object]:
    clock = Clock(100 * NS)
    session = CalibrationSession(config(tmp_path, **overrides), clock=clock)
    intr = demo_rig().intrinsics["cam0"]
    session.set_camera_info("cam0", intr)
    return session, clock, intr


def stream(seconds: float, pose_age_ms, image_age_ms: float = 30.0, start: int = 100 * NS):
    """Arrival-ordered events ``(arrival, kind, stamp)``: poses at 200 Hz arriving
    ``pose_age_ms(k)`` after their stamp, images at 30 Hz arriving ``image_age_ms`` after."""
    ev = [(start + k * 5 * MS + int(pose_age_ms(k) * MS), 0, start + k * 5 * MS)
          for k in range(int(seconds * 200) + 1)]
    ev += [(start + k * NS // 30 + int(image_age_ms * MS), 1, start + k * NS // 30)
           for k in range(int(seconds * 30))]
    return sorted(ev)


def moving(stamp: int) -> np.ndarray:
    """The pose at ``stamp`` of an arm moving at 0.2 m/s (1 mm between samples 5 ms apart,
    beyond sync.at_rest_translation_m: the stop-and-go rule of sync/at_rest.py never applies)."""
    T = np.eye(4)
    T[0, 3] = 0.2 * (stamp % (1000 * NS)) / NS
    return T


def feed(session, clock, intr, events, *, until=None):
    outcomes = []
    for arrival, kind, stamp in events:
        clock.t = arrival
        if kind == 0:
            session.add_pose(stamp, moving(stamp))
        else:
            outcomes.append(session.add_image("cam0", stamp, Blank(intr)))
    return outcomes


def no_pose(session) -> dict:
    return {k: v for k, v in session.counters().items() if k.startswith("no_pose_at_stamp")}


def test_a_pose_stream_lagging_the_images_by_265_ms_loses_no_image(tmp_path):
    """Issue 39's transport: poses 27-265 ms late, images 30 ms late; before, every image more
    than sync.max_gap_s (0.1 s) newer than the newest pose was rejected at once."""
    session, clock, intr = session_with_clock(tmp_path)

    def age(k):  # the executor stalls the pose callbacks: every 400 ms the poses of 235 ms
        i = k % 80  # arrive at once, 265 ms to 30 ms after their stamps; then 30 ms late
        return 30.0 + (47 - i) * 5.0 if i < 47 else 30.0

    events = stream(4.0, age)
    outcomes = feed(session, clock, intr, events)
    values = dict(session.pose_wait_values())
    assert float(values["pose_age_max_s"]) == pytest.approx(0.265, abs=1e-9)
    clock.t += 2 * NS  # nothing more comes: whatever still waits is answered by the clock
    session.add_pose(events[-1][2] + 5 * MS, moving(events[-1][2] + 5 * MS))
    c = session.counters()
    assert no_pose(session) == {}
    assert c["images_pending"] > 0  # they did wait
    # every image had its pose: examined (no tags) or skipped by the motion gate (no motion)
    assert c["images_without_tags"] + c["images_skipped_no_motion"] == 120
    assert session.camera_counters()["cam0"]["no_pose"] == 0
    assert sum(o.status == "pending" for o in outcomes) == c["images_pending"]


def test_the_pose_stream_stops_images_wait_their_deadline_then_after_buffer(tmp_path):
    session, clock, intr = session_with_clock(tmp_path)
    events = stream(2.0, lambda k: 20.0)
    feed(session, clock, intr, [e for e in events if e[1] == 1 or e[2] < 101 * NS])
    # poses stopped at 101 s (ages 20 ms): an image at s waits until s + 0.1 + 0.02 + 0.02 s
    last = max(e[2] for e in events if e[1] == 1)
    assert session.pose_ready(last, arrived_ns=last + 30 * MS) is False
    clock.t = last + 139 * MS
    assert not session.pose_ready(last, arrived_ns=last + 30 * MS)
    clock.t = last + 141 * MS
    assert session.pose_ready(last, arrived_ns=last + 30 * MS)
    session.add_pose(90 * NS, moving(90 * NS))  # any input lets the session answer the due ones
    assert session.counters()["pending_images"] == 0
    lost = no_pose(session)
    assert set(lost) == {"no_pose_at_stamp:after_buffer"}
    assert lost["no_pose_at_stamp:after_buffer"] == sum(
        1 for e in events if e[1] == 1 and e[2] > 101 * NS + 10 * MS)  # 10 ms: held nearest
    assert session.no_pose_counts() == {"cam0": {"after_buffer": lost[
        "no_pose_at_stamp:after_buffer"]}}


def test_a_lag_beyond_max_pose_wait_is_a_timeout_naming_the_parameter(tmp_path):
    session, clock, intr = session_with_clock(tmp_path, **{"sync.max_pose_wait_s": 0.2})
    events = stream(2.0, lambda k: 400.0)  # poses always 400 ms late
    feed(session, clock, intr, events)
    lost = no_pose(session)
    # the first images gave up before the first pose arrived at all (empty)
    assert set(lost) == {"no_pose_at_stamp:wait_timeout", "no_pose_at_stamp:empty"}
    assert lost["no_pose_at_stamp:empty"] <= 7 and lost["no_pose_at_stamp:wait_timeout"] > 40
    assert dict(session.pose_wait_values())["image_wait_s"].endswith("(sync.max_pose_wait_s)")


def test_no_pose_at_all_is_empty_after_the_wait(tmp_path):
    session, clock, intr = session_with_clock(tmp_path, **{"sync.max_pose_wait_s": 0.5})
    for k in range(30):
        clock.t = 100 * NS + k * NS // 10
        session.add_image("cam0", clock.t - 30 * MS, Blank(intr))
    assert no_pose(session) == {"no_pose_at_stamp:empty": 25}  # the last 0.5 s still wait
    assert session.flush_pending() == 5
    assert no_pose(session) == {"no_pose_at_stamp:empty": 30}


def test_waiting_images_are_bounded_in_memory_oldest_given_up(tmp_path):
    intr = demo_rig().intrinsics["cam0"]
    mb = 10 * intr.width * intr.height / 1e6  # room for ten images
    session, clock, intr = session_with_clock(tmp_path, **{"sync.max_waiting_mb": mb})
    session.add_pose(100 * NS, moving(100 * NS))
    for k in range(25):  # newer than the newest pose, well within the wait
        clock.t = 100 * NS + k * MS
        assert session.add_image("cam0", 100 * NS + (k + 20) * MS, Blank(intr)).status == \
            "pending"
    assert session.counters()["pending_images"] == 10
    assert no_pose(session) == {"no_pose_at_stamp:wait_memory": 15}
    session.record_no_pose("cam0", "wait_memory")  # the node's queue gives one up too
    assert session.no_pose_counts()["cam0"] == {"wait_memory": 16}
    assert session.camera_counters()["cam0"]["no_pose"] == 16


def test_an_image_in_a_gap_waits_for_the_reordered_poses(tmp_path):
    session, clock, intr = session_with_clock(tmp_path)
    clock.t = 100 * NS + 300 * MS  # the poses arrive 55-300 ms late
    for k in list(range(0, 10)) + list(range(40, 50)):  # 150 ms gap: poses 10-39 are later
        session.add_pose(100 * NS + k * 5 * MS, moving(100 * NS + k * 5 * MS))
    image = Blank(intr)
    assert session.add_image("cam0", 100 * NS + 120 * MS, image).status == "pending"
    clock.t = 100 * NS + 400 * MS  # before its deadline 0.12 + 0.1 + 0.3 + 0.061 s
    for k in range(10, 40):
        session.add_pose(100 * NS + k * 5 * MS, moving(100 * NS + k * 5 * MS))
    assert image.calls == 1 and no_pose(session) == {}


def test_without_a_clock_the_newest_stamp_is_the_clock(tmp_path):
    session = CalibrationSession(config(tmp_path))
    intr = demo_rig().intrinsics["cam0"]
    session.set_camera_info("cam0", intr)
    for k in range(20):
        session.add_pose(100 * NS + k * 5 * MS, moving(100 * NS + k * 5 * MS))
    assert session.now_ns() == 100 * NS + 95 * MS
    # an image after the last pose waits while later stamps arrive ...
    assert session.add_image("cam0", 100 * NS + 150 * MS, Blank(intr)).status == "pending"
    assert session.now_ns() == 100 * NS + 150 * MS
    for k in range(1, 6):
        session.add_image("cam0", 100 * NS + 150 * MS + k * 33 * MS, Blank(intr))
    # ... until its deadline (0.1 s + ages 0-5 ms + 20 ms) passes on that clock
    assert no_pose(session) == {"no_pose_at_stamp:after_buffer": 2}


def test_the_retired_parameter_says_what_replaced_it(tmp_path):
    with pytest.raises(ValueError, match=r"sync.max_pending_images: unknown parameter .*"
                       r"retired .*sync.max_pose_wait_s and sync.max_waiting_mb"):
        config(tmp_path, **{"sync.max_pending_images": 32})


def test_a_stream_at_rest_that_stops_keeps_images_waiting_for_the_next_sample(tmp_path):
    """Stop-and-go (sync/at_rest.py) joined to the wait: after a stream at rest stops, an image
    newer than its newest pose waits past the pose deadline, up to sync.at_rest_max_gap_s after
    that pose, for the next sample that may bridge it; the next agreeing sample pairs it."""
    session, clock, intr = session_with_clock(tmp_path, **{"sync.at_rest_max_gap_s": 1.0})
    for k in range(20):  # at rest: the same pose at 200 Hz, then nothing
        session.add_pose(100 * NS + k * 5 * MS, np.eye(4))
    stamp = 100 * NS + 300 * MS
    clock.t = stamp + 30 * MS
    assert session.add_image("cam0", stamp, Blank(intr)).status == "pending"
    clock.t = 100 * NS + 900 * MS  # well past its pose deadline, within 1 s of the newest pose
    assert not session.pose_ready(stamp, arrived_ns=stamp + 30 * MS)
    clock.t = 100 * NS + 1100 * MS  # 1 s after the newest pose: final
    assert session.pose_ready(stamp, arrived_ns=stamp + 30 * MS)
    # the same image with the next sample at rest 0.8 s later: paired at rest
    session2, clock2, _ = session_with_clock(tmp_path, **{"sync.at_rest_max_gap_s": 1.0})
    for k in range(20):
        session2.add_pose(100 * NS + k * 5 * MS, np.eye(4))
    clock2.t = stamp + 30 * MS
    image = Blank(intr)
    assert session2.add_image("cam0", stamp, image).status == "pending"
    clock2.t = 100 * NS + 900 * MS
    session2.add_pose(100 * NS + 895 * MS, np.eye(4))
    assert image.calls == 1 and no_pose(session2) == {}
    assert session2.counters()["pose_at_rest"] == 1


def test_an_image_waits_in_pose_time_with_a_known_time_offset(tmp_path):
    """sync.time_offset.<camera> (t_pose = t_image + offset) moves the stamp the wait is
    about: the node's queue and the bag replay ask pose_ready with session.pose_time."""
    session, clock, intr = session_with_clock(tmp_path, **{"sync.time_offset.cam0": 0.05})
    for k in range(20):  # poses up to 100.095 s
        session.add_pose(100 * NS + k * 5 * MS, moving(100 * NS + k * 5 * MS))
    raw = 100 * NS + 60 * MS
    assert session.pose_time("cam0", raw) == 100 * NS + 110 * MS
    assert session.pose_time("cam0", "x") is None
    # back on the camera's clock (the stamp ~/detections carries): the image's own stamp
    assert session.image_time("cam0", session.pose_time("cam0", raw)) == raw
    clock.t = raw + 30 * MS
    assert session.pose_ready(raw, clock.t)  # bracketed in image time ...
    assert not session.pose_ready(session.pose_time("cam0", raw), clock.t)  # ... not in pose time
    image = Blank(intr)
    assert session.add_image("cam0", raw, image, arrived_ns=clock.t).status == "pending"
    for k in range(20, 30):
        session.add_pose(100 * NS + k * 5 * MS, moving(100 * NS + k * 5 * MS))
    assert image.calls == 1 and no_pose(session) == {}

"""FairImageQueue: per-camera FIFOs served round-robin, one image per camera in service,
readiness, drop-oldest live and blocking offline; with QueueWorker threads."""

from __future__ import annotations

import threading
import time

import pytest

from rwhec_ros.session import FairImageQueue, QueueWorker


def test_round_robin_one_in_service_per_key_and_fifo():
    q = FairImageQueue(["a", "b", "c"], 10)
    for i in range(6):
        q.put("a", f"a{i}")  # a fast camera
    q.put("b", "b0")
    q.put("c", "c0")
    got = [q.get(0)]
    assert got == [("a", "a0")]
    # "a" is in service: the others come first, "a" waits for task_done
    got += [q.get(0), q.get(0)]
    assert got[1:] == [("b", "b0"), ("c", "c0")]
    assert q.get(0.01) is None  # a1 is queued but a0 is still in service
    q.task_done(got[0])
    assert q.get(0) == ("a", "a1")  # oldest first
    stats = q.stats()
    assert stats["a"] == {"received": 6, "dropped": 0, "dropped_expendable": 0,
                          "dropped_memory": 0, "processed": 1,
                          "queued": 4}
    assert len(q) == 4
    with pytest.raises(KeyError):
        q.put("z", 1)


def test_a_fast_camera_cannot_starve_the_others():
    q = FairImageQueue(["fast", "slow"], 3)
    served = []
    for i in range(20):  # the fast camera floods; its queue keeps only the 3 newest
        q.put("fast", i)
        if i % 5 == 0:
            q.put("slow", i)
        entry = q.get(0)
        served.append(entry)
        q.task_done(entry)
    keys = [k for k, _ in served]
    assert keys.count("slow") == 4  # every slow image was served
    assert q.stats()["slow"]["dropped"] == 0
    assert q.dropped == q.stats()["fast"]["dropped"]


def test_full_key_drops_its_oldest_live_and_blocks_offline():
    live = FairImageQueue(["a", "b"], 2)
    assert live.put("a", 1) and live.put("a", 2)
    assert not live.put("a", 3)  # drops 1
    assert live.put("b", 9)  # another camera's room is its own
    assert live.stats()["a"]["dropped"] == 1 and live.get(0) == ("a", 2)

    # with an expendable predicate (the motion gate would skip it), that item goes first
    pick = FairImageQueue(["a"], 3, expendable=lambda key, item: item % 2 == 0)
    for i in (1, 2, 3):
        assert pick.put("a", i)
    assert not pick.put("a", 5)  # drops 2, the oldest expendable, not 1
    assert not pick.put("a", 7)  # nothing expendable left: drops the oldest, 1
    assert pick.get(0) == ("a", 3)
    assert pick.stats()["a"]["dropped"] == 2 and pick.stats()["a"]["dropped_expendable"] == 1

    offline = FairImageQueue(["a"], 1, block=True)
    offline.put("a", 1)
    done = threading.Event()

    def producer():
        offline.put("a", 2)  # blocks until 1 is taken
        done.set()

    t = threading.Thread(target=producer)
    t.start()
    assert not done.wait(0.1)
    entry = offline.get(1.0)
    assert entry == ("a", 1)
    assert done.wait(2.0)
    t.join(2.0)
    assert offline.stats()["a"]["dropped"] == 0 and len(offline) == 1


def test_items_wait_until_ready_then_in_order():
    newest = {"t": 0}
    q = FairImageQueue(["a", "b"], 10, ready=lambda stamp: stamp <= newest["t"],
                       recheck_s=0.01)
    q.put("a", 5)
    q.put("a", 6)
    q.put("b", 1)
    assert q.get(0.02) is None  # nothing ready yet
    newest["t"] = 1
    q.notify()
    first_b = q.get(0.1)
    assert first_b == ("b", 1)
    q.task_done(first_b)
    newest["t"] = 10
    entry = q.get(0.1)
    assert entry == ("a", 5)
    q.task_done(entry)
    assert q.get(0.1) == ("a", 6)
    # closing hands out what is left without the ready check
    newest["t"] = 0
    q.put("b", 99)
    q.close()
    assert q.get(0.1) == ("b", 99)
    assert q.get(0.1) is None  # "a" was never marked done, nothing queued: empty


def test_workers_keep_each_camera_in_order_and_join():
    keys = [f"cam{k}" for k in range(4)]
    q = FairImageQueue(keys, 4, block=True)
    seen = {k: [] for k in keys}
    active = {k: 0 for k in keys}
    overlap = []
    lock = threading.Lock()

    def handler(entry):
        key, i = entry
        with lock:
            active[key] += 1
            if active[key] > 1:
                overlap.append(key)
        time.sleep(0.001)
        with lock:
            seen[key].append(i)
            active[key] -= 1

    workers = [QueueWorker(q, handler, name=f"w{i}").start() for i in range(3)]
    for i in range(40):
        for k in keys:
            q.put(k, i)
    assert q.join(20.0)
    for w in workers:
        w.stop()
    assert not overlap  # never two images of one camera at once
    assert all(seen[k] == list(range(40)) for k in keys)  # each camera in order, none lost
    assert all(s["processed"] == 40 for s in q.stats().values())


def test_validation():
    with pytest.raises(ValueError, match="maxsize"):
        FairImageQueue(["a"], 0)
    with pytest.raises(ValueError, match="keys"):
        FairImageQueue(["a", "a"], 1)
    with pytest.raises(ValueError, match="keys"):
        FairImageQueue([], 1)


def test_a_slow_expendable_predicate_does_not_hold_up_the_consumers():
    """The drop decision of a full camera's queue runs outside the queue's lock: while it
    judges (here: blocked until released), a consumer takes another camera's image, and a
    victim a consumer took meanwhile is not dropped twice (the oldest goes instead)."""
    judging, release = threading.Event(), threading.Event()

    def expendable(key, item):
        judging.set()
        release.wait(5.0)
        return item == "a1"

    q = FairImageQueue(["a", "b"], 2, expendable=expendable)
    q.put("a", "a0")
    q.put("a", "a1")
    q.put("b", "b0")
    done = []
    t = threading.Thread(target=lambda: done.append(q.put("a", "a2")))
    t.start()
    assert judging.wait(5.0)
    t0 = time.monotonic()
    first = q.get(1.0)  # round robin: a's oldest, while the put is still judging
    assert first == ("a", "a0") and time.monotonic() - t0 < 0.5
    second = q.get(1.0)
    assert second == ("b", "b0")
    release.set()
    t.join(5.0)
    assert done == [True]  # a consumer made room meanwhile: nothing dropped
    assert q.stats()["a"]["dropped"] == 0
    q.task_done(first)
    assert q.get(1.0) == ("a", "a1")


def test_waiting_items_do_not_fill_a_keys_backlog_memory_bounds_them():
    """Issue 39: images waiting for a late pose stream filled the 8 slots of their camera and
    were dropped. Items that waited do not count as the backlog, even once ready (a late pose
    stream catching up makes many ready at once); memory bounds every item, the oldest first."""
    newest = {"t": 0}
    drops = []
    q = FairImageQueue(["a", "b"], 2, ready=lambda item: item[0] <= newest["t"],
                       weight=lambda item: item[1], max_bytes=100,
                       on_drop=lambda key, item, waiting: drops.append((key, item[0], waiting)))
    for stamp in range(1, 9):  # 8 waiting items of 10 bytes on "a": 4x the backlog
        assert q.put("a", (stamp, 10))
    assert q.stats()["a"]["dropped"] == 0 and len(q) == 8 and q.nbytes == 80
    newest["t"] = 20  # all ready now: still no backlog (they waited)
    assert q.put("a", (9, 10)) and q.put("a", (10, 10))  # ready when put: a backlog of 2
    assert q.stats()["a"]["dropped"] == 0
    assert not q.put("a", (11, 10))  # the backlog is full: the key's oldest item goes
    assert q.stats()["a"]["dropped"] == 1 and q.get(0) == ("a", (2, 10))
    newest["t"] = 5  # items 6.. wait again (for this test's sake)
    # memory: 40 bytes on "b" push the total past 100: the oldest items held go, any key
    assert q.put("b", (1, 40))
    assert drops == [("a", k, False) for k in (3, 4, 5)]  # the oldest held, ready ones
    assert q.put("b", (2, 40))
    assert drops[3:] == [("a", k, True) for k in (6, 7, 8, 9)]  # then waiting ones
    s = q.stats()
    assert (s["a"]["dropped_memory"], s["a"]["dropped"], s["b"]["dropped"]) == (7, 8, 0)
    assert q.nbytes == 40 + 40 + 2 * 10
    assert q.discard() == 4 and len(q) == 0 and q.nbytes == 0


def test_without_ready_maxsize_still_bounds_every_item():
    q = FairImageQueue(["a"], 2, weight=len, max_bytes=10**6)
    assert q.put("a", "x") and q.put("a", "y") and not q.put("a", "z")
    assert q.get(0) == ("a", "y") and q.nbytes == 1

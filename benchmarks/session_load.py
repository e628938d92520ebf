"""Session load benchmark: 8 cameras into the live session, at 640 x 480 and at camera rate at
1280 x 1024 (Markdown).

Run from the repository root (about 30 minutes on a busy 2-core machine; it writes
``benchmarks/session_load.md``)::

    python benchmarks/session_load.py [--seconds 60] [--pool 20] [--hd-seconds 12]
                                      [--cache DIR] [--section all|vga|hd] [--output FILE.md]

The second section (1280 x 1024, 8 cameras x 30 Hz, 200 Hz poses, live-paced, plus
``rwhec-calibrate bag`` on a compressed recording) is ``benchmarks/camera_rate_load.py``; its
docstring describes it. The first section:

The scene is the paper's real-world setting in miniature: :func:`rwhec_ros.simulation.demo_rig`
with 8 cameras (640 x 480) and 16 tags, a motion-capture pose stream ``T_world_rig`` at 1 kHz
(0.5 mm / 0.5 mrad noise per axis) and 8 x 20 Hz images, for ``--seconds`` of simulated time.

To keep it fast, ``--pool`` images per camera are rendered once (the first ``pool / 20`` seconds
of the trajectory) and replayed in a loop; the pose stream loops with the same period
(``T_world_rig(t mod period)``), so every image stays consistent with the pose at its stamp.
Because the loop repeats, the keyframe test rejects most pairs after the first period; the
per-image work (detection, pose lookup, keyframe test) is the live path's all the same. Images go
in as (H, W) uint8 arrays (the node's ``mono8`` conversion, a zero-copy view, is not timed).

The session processes images synchronously in ``add_image``. Runs:

1. **live, 1 worker** -- the node's arrangement: a producer thread paced to the wall clock calls
   ``add_pose`` for every pose (as the pose callback does, then ``FairImageQueue.notify``) and
   puts every image into the node's :class:`~rwhec_ros.session.FairImageQueue` (one bounded
   drop-oldest queue per camera, ``sync.image_queue_size`` = 4 each, images held until their
   pose is there); one :class:`~rwhec_ros.session.QueueWorker` runs ``add_image``. Dropped
   images are those the queue discarded because the worker fell behind.
2. **live, 2 workers** -- the same with ``sync.detection_threads: 2``.
3. **live, 1 worker, producer 4x real time** -- the producer paced at four times the wall clock
   (640 images/s): the producer is faster than the consumer, the queue drops.
4. **offline, synchronous** -- one thread feeds everything as fast as it can (what
   ``rwhec-calibrate bag`` does): the throughput ceiling of one core.
5. The offline run again under ``tracemalloc`` (which slows allocation-heavy code, hence a
   separate run): its peak is the memory the session allocates (the image pool is allocated
   before tracing starts).

Detection time share: ``TargetDetector.detect`` is wrapped with a timer (benchmark-only
instrumentation); share = time in ``detect`` / time in ``add_image``. Numbers depend on the
machine and its load (the load average is printed).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import platform
import resource
import sys
import tempfile
import threading
import time
import tracemalloc
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from camera_rate_load import DetectTimer, pace  # noqa: E402 - beside this script

from rwhec_ros.cli import demo_parameters  # noqa: E402
from rwhec_ros.config import CalibratorConfig  # noqa: E402
from rwhec_ros.session import CalibrationSession, FairImageQueue, QueueWorker  # noqa: E402
from rwhec_ros.simulation import demo_rig  # noqa: E402

NS = 1_000_000_000
POSE_RATE_HZ = 1000
IMAGE_RATE_HZ = 20
N_CAMERAS = 8
N_TAGS = 16
QUEUE_SIZE = 4  # per camera, the default
START_NS = NS


@dataclass
class Stream:
    """Pre-rendered pool and looped pose stream."""

    rig: object
    period_ns: int
    poses: np.ndarray  # (period * 1 kHz, 4, 4) measured T_world_rig over one period
    images: dict  # camera -> list of (H, W) uint8, one per image instant of one period


def make_stream(pool: int, rng: np.random.Generator) -> Stream:
    rig = demo_rig(N_CAMERAS, N_TAGS)
    period_ns = pool * NS // IMAGE_RATE_HZ
    n_poses = period_ns * POSE_RATE_HZ // NS
    poses = np.array([rig.pose_measurement(k / POSE_RATE_HZ, rng, 5e-4, 5e-4)
                      for k in range(n_poses)])
    images = {cam: [] for cam in rig.cameras}
    for i in range(pool):
        T = rig.T_world_rig(i / IMAGE_RATE_HZ)
        for cam in rig.cameras:
            images[cam].append(rig.render(cam, T, rng, supersample=2))
    return Stream(rig, period_ns, poses, images)


def events(stream: Stream, seconds: float):
    """``(stamp_ns, camera or None, payload)`` in stamp order: a pose every 1 ms, 8 images every
    50 ms (image stamps coincide with pose stamps: exact lookups)."""
    pose_step = NS // POSE_RATE_HZ
    image_step = NS // IMAGE_RATE_HZ
    n_poses = len(stream.poses)
    pool = len(next(iter(stream.images.values())))
    for k in range(int(round(seconds * POSE_RATE_HZ)) + 1):
        s = k * pose_step
        yield START_NS + s, None, stream.poses[k % n_poses]
        if s % image_step == 0:
            i = (s // image_step) % pool
            for cam in stream.rig.cameras:
                yield START_NS + s, cam, stream.images[cam][i]


def new_session(stream: Stream, out_dir: str) -> CalibrationSession:
    flat = demo_parameters(stream.rig, output_directory=out_dir)
    flat.update({"sync.image_queue_size": QUEUE_SIZE, "sync.max_gap_s": 0.05,
                 "sync.extrapolation_tolerance_s": 0.005, "sync.pose_buffer_size": 4000})
    session = CalibrationSession(CalibratorConfig.from_parameters(flat))
    for cam in stream.rig.cameras:
        session.set_camera_info(cam, stream.rig.intrinsics[cam])
    return session


def run_live(stream: Stream, seconds: float, workers: int, out_dir: str,
             speed: float = 1.0) -> dict:
    session = new_session(stream, out_dir)
    queue = FairImageQueue(stream.rig.cameras, QUEUE_SIZE,
                           ready=lambda item: session.pose_ready(item[0]))
    busy = {"t": 0.0}
    busy_lock = threading.Lock()

    def handler(entry):
        cam, (stamp, payload) = entry
        t0 = time.perf_counter()
        session.add_image(cam, stamp, payload)
        dt = time.perf_counter() - t0
        with busy_lock:
            busy["t"] += dt

    pose_time = 0.0
    produced = 0
    max_lag = 0.0
    with DetectTimer() as timer:
        pool = [QueueWorker(queue, handler, name=f"bench-{i}").start() for i in range(workers)]
        t_start, c_start = time.perf_counter(), time.process_time()
        for stamp, cam, payload in events(stream, seconds):
            max_lag = max(max_lag, pace(t_start, stamp - START_NS, speed))
            if cam is None:
                t0 = time.perf_counter()
                session.add_pose(stamp, payload, source="world")
                pose_time += time.perf_counter() - t0
                queue.notify()
            else:
                queue.put(cam, (stamp, payload))
                produced += 1
        queue.close()  # the rest, also the last images whose later pose never comes
        queue.join(30.0)
        for w in pool:
            w.stop(timeout=30.0)
        wall = time.perf_counter() - t_start
        cpu = time.process_time() - c_start
    processed = sum(w.processed for w in pool)
    return {
        "wall": wall, "produced": produced, "processed": processed, "dropped": queue.dropped,
        "detect": timer.total, "busy": busy["t"], "cpu": cpu,
        "pose_mean_us": 1e6 * pose_time
        / max(1, int(round(seconds * POSE_RATE_HZ)) + 1), "max_lag": max_lag,
        "counters": session.counters(),
    }


def run_offline(stream: Stream, seconds: float, out_dir: str, *, trace: bool = False) -> dict:
    session = new_session(stream, out_dir)
    busy = 0.0
    produced = 0
    if trace:
        tracemalloc.start()
    with DetectTimer() as timer:
        t_start, c_start = time.perf_counter(), time.process_time()
        for stamp, cam, payload in events(stream, seconds):
            if cam is None:
                session.add_pose(stamp, payload, source="world")
            else:
                t0 = time.perf_counter()
                session.add_image(cam, stamp, payload)
                busy += time.perf_counter() - t0
                produced += 1
        wall = time.perf_counter() - t_start
        cpu = time.process_time() - c_start
    peak = tracemalloc.get_traced_memory()[1] if trace else 0
    tracemalloc.stop()
    return {"wall": wall, "produced": produced, "processed": produced, "dropped": 0,
            "detect": timer.total, "busy": busy, "cpu": cpu, "tracemalloc_peak": peak,
            "counters": session.counters()}


def fmt_row(name: str, r: dict, seconds: float) -> str:
    share = r["detect"] / r["busy"] if r["busy"] > 0 else float("nan")
    c = r["counters"]
    return (f"| {name} | {r['wall']:.1f} | {r['produced']} | {r['processed']} | {r['dropped']} "
            f"| {r['processed'] / r['wall']:.1f} | {r['dropped'] / r['wall']:.1f} "
            f"| {100 * share:.0f} % | {1e3 * r['busy'] / max(1, r['processed']):.2f} "
            f"| {r['cpu'] / r['wall']:.2f} "
            f"| {c.get('pairs_kept', 0)} | {c.get('poses', 0)} |")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="simulated seconds (60)")
    ap.add_argument("--pool", type=int, default=20, help="pre-rendered images per camera (20)")
    ap.add_argument("--hd-seconds", type=float, default=12.0,
                    help="simulated seconds of the 1280 x 1024 section (12)")
    ap.add_argument("--cache", type=Path, default=None,
                    help="keep the 1280 x 1024 image pool in this directory between runs")
    ap.add_argument("--section", choices=("all", "vga", "hd"), default="all")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--output", type=Path,
                    default=Path(__file__).resolve().with_name("session_load.md"),
                    help="Markdown file to write (default benchmarks/session_load.md; "
                         "'-' prints only)")
    args = ap.parse_args(argv)
    lines = ["# Session load benchmark", ""]
    if args.section in ("all", "vga"):
        lines += vga_section(args)
    if args.section in ("all", "hd"):
        from camera_rate_load import section

        lines += section(args.hd_seconds, args.cache, args.seed)
    text = "\n".join(lines)
    print(text)
    if str(args.output) != "-":
        args.output.write_text(text + "\n", encoding="utf-8")
    return 0


def vga_section(args: argparse.Namespace) -> list[str]:
    """The 640 x 480 section (the runs of the module docstring)."""
    rss_start = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t0 = time.perf_counter()
    stream = make_stream(args.pool, np.random.default_rng(args.seed))
    t_render = time.perf_counter() - t0
    rss_pool = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        live1 = run_live(stream, args.seconds, 1, tmp)
        live2 = run_live(stream, args.seconds, 2, tmp)
        fast = run_live(stream, args.seconds, 1, tmp, speed=4.0)
        offline = run_offline(stream, args.seconds, tmp)
        traced = run_offline(stream, args.seconds, tmp, trace=True)
    load_after = os.getloadavg()
    rss_end = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss

    n_img = N_CAMERAS * IMAGE_RATE_HZ
    return [
        f"## {N_CAMERAS} cameras x {IMAGE_RATE_HZ} Hz at 640 x 480, poses at 1 kHz",
        "",
        f"- generated by `python benchmarks/session_load.py` on "
        f"{_dt.date.today().isoformat()}, Python {platform.python_version()}, "
        f"{os.cpu_count()} CPUs ({platform.machine()}); load average "
        f"{load_before[0]:.1f} before, {load_after[0]:.1f} after (other jobs were running)",
        f"- input: {N_CAMERAS} cameras x {IMAGE_RATE_HZ} Hz = {n_img} images/s (640 x 480) "
        f"and {POSE_RATE_HZ} poses/s for {args.seconds:g} s of simulated time; "
        f"{N_TAGS} tags; {args.pool} pre-rendered images per camera replayed in a loop "
        f"(rendered in {t_render:.1f} s)",
        "- live runs are paced to the wall clock: images into the node's `FairImageQueue` "
        f"({QUEUE_SIZE} per camera, drop-oldest) served by `QueueWorker` threads calling "
        "`add_image`; poses by the producer thread calling `add_pose` (as the node). The "
        "offline run feeds everything synchronously on one thread, as fast as possible "
        "(`rwhec-calibrate bag`).",
        "",
        "| run | wall [s] | images in | processed | dropped | processed/s | dropped/s "
        "| detection share | ms per image | CPU cores used | pairs kept | poses |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
        fmt_row("live, 1 worker", live1, args.seconds),
        fmt_row("live, 2 workers", live2, args.seconds),
        fmt_row("live, 1 worker, producer 4x real time", fast, args.seconds),
        fmt_row("offline, synchronous", offline, args.seconds),
        "",
        f"- `add_pose` (producer thread, 1 kHz): mean {live1['pose_mean_us']:.0f} us with 1 "
        f"worker, {live2['pose_mean_us']:.0f} us with 2 workers, {fast['pose_mean_us']:.0f} us "
        f"at 4x; producer lag behind its clock at most {1e3 * live1['max_lag']:.0f} ms / "
        f"{1e3 * live2['max_lag']:.0f} ms / {1e3 * fast['max_lag']:.0f} ms",
        f"- memory: tracemalloc peak during a second offline run "
        f"{traced['tracemalloc_peak'] / 2**20:.1f} MiB (session: pose buffer, pairs, "
        f"detections; the image pool excluded; that run took {traced['wall']:.0f} s under "
        f"tracing); process max RSS {rss_start / 1024:.0f} MiB at start, "
        f"{rss_pool / 1024:.0f} MiB after rendering the pool, {rss_end / 1024:.0f} MiB at the "
        "end (`resource.getrusage`, includes the pool and the libraries)",
        "- detection share = time in `TargetDetector.detect` / time in `add_image`; the rest is "
        "pose lookup, keyframe test, identifiability update and locking. ms per image = wall "
        "time in `add_image` per processed image (grows when threads wait for a core; OpenCV "
        f"runs {cv2.getNumThreads()} threads inside detection). CPU cores used = process CPU "
        "time / wall time of the run (producer, poses, workers, OpenCV threads). With 2 cores "
        "shared by other jobs, the drops follow the machine's load",
        "",
    ]


if __name__ == "__main__":
    sys.exit(main())

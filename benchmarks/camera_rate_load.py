"""Session load at camera rate (issue 18): 8 cameras x 30 Hz at 1280 x 1024, poses at 200 Hz.

Imported by ``benchmarks/session_load.py`` (its second section); run alone with::

    python benchmarks/camera_rate_load.py [--seconds 12] [--cache DIR] [--output FILE.md]

Scene: :func:`rwhec_ros.simulation.demo_rig` with 8 cameras (1280 x 1024, f = 1000 px) and 16 tags
(25 cm, about 1 m away: 250 px), the demo trajectory (yaw turn in 24 s, roll/pitch oscillations),
motion-capture poses ``T_world_rig`` at 200 Hz (0.5 mm / 0.5 mrad noise), images at 30 Hz per
camera (240 images/s). A pool of ``POOL_S`` = 3 s of images per camera is rendered once (720
renders) and replayed in a loop with the poses of the same 3 s; 3 s is a multiple of both the
pose and the image period, so no image stamp falls between the two poses of a loop's seam and
every image matches the pose at its stamp.

Runs (same stream each):

* **offline, every image** -- one thread feeds poses and images synchronously (images between two
  pose stamps wait in the session for the next pose), ``detection.motion_gate: false``:
  (a) with ``detection.decimate: 1`` (the detection of ``main`` before issue 18's vision
  changes, 7abf143) and (b) with the default ``decimate: auto`` (2 here). (b) is the reference
  "every frame" run: its pairs, and which images gave them.
* **offline, motion gate** -- (c) as (b) with the gate on and ``detection.discovery_step: 0``
  (every edge counts, also of tags out of view): its pairs must equal (b)'s; (d) the gate with
  the defaults (discovery step 0.5: near its camera's last searched pose an image counts only
  the tags found there; a tag found for the first time is then looked for in the images skipped
  since the camera's previous search): fewer images searched, slightly different pairs.
* **live** -- a producer thread paced to the wall clock adds the poses (as the node's pose
  callback, then ``FairImageQueue.notify``) and puts the images (arrays, the raw transport) into
  the node's :class:`~rwhec_ros.session.FairImageQueue` (8 per camera, images held until their
  pose is there, a full queue dropping first an image the gate would skip);
  ``sync.detection_threads: auto`` :class:`~rwhec_ros.session.QueueWorker` threads call
  ``add_image``. With the node's
  defaults, with every edge counting, and with the gate off.
* **bag** -- the same stream recorded as a rosbag2 file with JPEG ``CompressedImage`` messages
  (quality 95, image_transport's format) plus a ``CameraInfo`` per image, replayed end to end by
  ``rwhec-calibrate bag`` in-process (reading, deserialising, decoding, detection, solve): the new
  defaults on 2 threads (auto) and on 1, every edge counting on 2, and the old path (decimate 1,
  no gate, 1 thread). The time inside ``CalibrationSession.calibrate`` (the final solve and its
  assessment) is reported apart from the replay.

Measured: wall time, process CPU time (all threads, ``time.process_time``), pairs kept,
detection CPU (process CPU inside ``TargetDetector.detect``, meaningful on the one-thread runs
only), images dropped by the live queue and how many of them gave a pair in the reference run,
and the calibration against the reference and against the truth.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rwhec_ros.cli import demo_parameters  # noqa: E402
from rwhec_ros.cli import main as cli_main  # noqa: E402
from rwhec_ros.config import CalibratorConfig  # noqa: E402
from rwhec_ros.core.lie import rotation_distance  # noqa: E402
from rwhec_ros.data.dataset import Dataset  # noqa: E402
from rwhec_ros.data.rosbag import (  # noqa: E402
    CAMERA_INFO,
    COMPRESSED_IMAGE,
    POSE_STAMPED,
    jazzy_typestore,
    message_from_fields,
    write_bag,
)
from rwhec_ros.messages import (  # noqa: E402
    intrinsics_to_camera_info_fields,
    ns_to_stamp_fields,
    transform_to_pose_stamped_fields,
)
from rwhec_ros.session import CalibrationSession, FairImageQueue, QueueWorker  # noqa: E402
from rwhec_ros.simulation import DEMO_POSE_TOPIC, demo_camera_topics, demo_rig  # noqa: E402
from rwhec_ros.vision.target_detector import TargetDetector  # noqa: E402

NS = 1_000_000_000
N_CAMERAS, N_TAGS = 8, 16
WIDTH, HEIGHT, FOCAL = 1280, 1024, 1000.0
IMAGE_RATE_HZ, POSE_RATE_HZ = 30, 200
POOL_S = 3  # a multiple of 1/30 s and 1/200 s (and of their common 100 ms)
START_NS = NS
JPEG_QUALITY = 95


class MethodTimer:
    """Wraps ``cls.name`` (benchmark-only instrumentation): calls, wall time summed over all
    threads (``total``) and process CPU time inside it (``cpu``: all threads of the process, so
    only meaningful when one thread is inside at a time)."""

    def __init__(self, cls: type, name: str) -> None:
        self.cls, self.name = cls, name
        self.lock = threading.Lock()
        self.total = 0.0
        self.cpu = 0.0
        self.calls = 0
        self._original = getattr(cls, name)

    def __enter__(self) -> MethodTimer:
        original, timer = self._original, self

        def timed(*args, **kwargs):
            t0, c0 = time.perf_counter(), time.process_time()
            try:
                return original(*args, **kwargs)
            finally:
                dt, dc = time.perf_counter() - t0, time.process_time() - c0
                with timer.lock:
                    timer.total += dt
                    timer.cpu += dc
                    timer.calls += 1

        setattr(self.cls, self.name, timed)
        return self

    def __exit__(self, *exc) -> None:
        setattr(self.cls, self.name, self._original)


class DetectTimer(MethodTimer):
    """:class:`MethodTimer` of ``TargetDetector.detect`` (the session's detector: marker search,
    refinement and pose of every target)."""

    def __init__(self) -> None:
        super().__init__(TargetDetector, "detect")


def pace(t0: float, offset_ns: int, speed: float = 1.0) -> float:
    """Sleep until ``offset_ns`` of stream time after the wall-clock instant ``t0``
    (``time.perf_counter``) at ``speed`` times real time; returns how late we already were [s]."""
    target = t0 + offset_ns / NS / speed
    now = time.perf_counter()
    if target > now:
        time.sleep(target - now)
        return 0.0
    return now - target


@dataclass
class Scene:
    rig: object
    poses: np.ndarray  # (POOL_S * 200, 4, 4) measured T_world_rig over one pool period
    images: dict  # camera -> list of (H, W) uint8, POOL_S * 30 per camera
    jpegs: dict  # camera -> list of JPEG bytes of the same images


def make_scene(rng: np.random.Generator, cache: Path | None = None,
               pool_s: int = POOL_S) -> tuple[Scene, float]:
    """Render (or load from ``cache``) the pool of ``pool_s`` whole seconds; returns the scene
    and the render time [s]."""
    rig = demo_rig(N_CAMERAS, N_TAGS, width=WIDTH, height=HEIGHT, focal_px=FOCAL)
    n_images = pool_s * IMAGE_RATE_HZ
    poses = np.array([rig.pose_measurement(k / POSE_RATE_HZ, rng, 5e-4, 5e-4)
                      for k in range(pool_s * POSE_RATE_HZ)])
    t0 = time.perf_counter()
    path = None if cache is None else cache / f"pool_{WIDTH}x{HEIGHT}_{pool_s}s_{len(poses)}.npy"
    if path is not None and path.is_file():
        stack = np.load(path)
    else:
        stack = np.array([[rig.render(cam, rig.T_world_rig(i / IMAGE_RATE_HZ), rng,
                                      supersample=2) for cam in rig.cameras]
                          for i in range(n_images)])
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            np.save(path, stack)
    images = {cam: [stack[i, k] for i in range(n_images)] for k, cam in enumerate(rig.cameras)}
    jpegs = {cam: [cv2.imencode(".jpg", g, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])[1]
                   .tobytes() for g in imgs] for cam, imgs in images.items()}
    return Scene(rig, poses, images, jpegs), time.perf_counter() - t0


def events(scene: Scene, seconds: float):
    """``(stamp_ns, camera or None, pool index)`` in stamp order: a pose every 5 ms, one image
    per camera every 1/30 s (at equal stamps the pose first, then the cameras in order)."""
    n_pose = len(scene.poses)
    n_img = len(next(iter(scene.images.values())))
    end = int(round(seconds * NS))
    timeline = [(k * NS // POSE_RATE_HZ, 0, k) for k in range(end * POSE_RATE_HZ // NS + 1)]
    timeline += [(k * NS // IMAGE_RATE_HZ, 1, k) for k in range(end * IMAGE_RATE_HZ // NS)]
    for s, kind, k in sorted(timeline):
        if kind == 0:
            yield START_NS + s, None, k % n_pose
        else:
            for cam in scene.rig.cameras:
                yield START_NS + s, cam, k % n_img


def config_flat(rig, out_dir: str, *, gate: bool, decimate, threads) -> dict:
    flat = demo_parameters(rig, output_directory=out_dir)
    flat.update({"sync.max_gap_s": 0.05, "sync.extrapolation_tolerance_s": 0.005,
                 "sync.pose_buffer_size": 4000, "detection.motion_gate": gate,
                 "detection.decimate": decimate, "sync.detection_threads": threads})
    flat.pop("sync.image_queue_size", None)  # the default: 8 per camera
    return flat


def new_session(scene: Scene, flat: dict) -> CalibrationSession:
    session = CalibrationSession(CalibratorConfig.from_parameters(flat))
    for cam in scene.rig.cameras:
        session.set_camera_info(cam, scene.rig.intrinsics[cam])
    return session


def useful_images(session: CalibrationSession) -> set:
    """(camera, stamp) of every image that gave a kept pair."""
    return {(y, int(s)) for (_, y), e in session._acc.edges().items() for s in e.stamps_ns}


def run_offline(scene: Scene, seconds: float, flat: dict) -> dict:
    session = new_session(scene, flat)
    n = 0
    with DetectTimer() as timer:
        t0, c0 = time.perf_counter(), time.process_time()
        for stamp, cam, i in events(scene, seconds):
            if cam is None:
                session.add_pose(stamp, scene.poses[i], source="world")
            else:
                session.add_image(cam, stamp, scene.images[cam][i])
                n += 1
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"session": session, "images": n, "wall": wall, "cpu": cpu,
            "detect_cpu": timer.cpu, "detect_calls": timer.calls, "dropped": set()}


def cpu_times() -> tuple[int, int] | None:
    """``(steal, total)`` CPU jiffies of the machine so far (``/proc/stat``), or None: the
    share of CPU time the hypervisor gave to other machines during a run (a virtual machine's
    2 cores are not always 2 cores)."""
    try:
        fields = [int(v) for v in Path("/proc/stat").read_text().split("\n")[0].split()[1:]]
    except (OSError, ValueError, IndexError):
        return None
    return (fields[7] if len(fields) > 7 else 0), sum(fields[:8])


def steal_share(t0: tuple[int, int] | None, t1: tuple[int, int] | None) -> float:
    """Stolen share of the CPU time between two :func:`cpu_times` (NaN when unknown)."""
    if t0 is None or t1 is None or t1[1] <= t0[1]:
        return float("nan")
    return (t1[0] - t0[0]) / (t1[1] - t0[1])


def run_live(scene: Scene, seconds: float, flat: dict) -> dict:
    session = new_session(scene, flat)
    steal0 = cpu_times()
    cfg = session.config
    queue = FairImageQueue(cfg.camera_names, cfg.sync.image_queue_size,
                           ready=lambda item: session.pose_ready(item[0]),
                           expendable=lambda cam, item: session.gate_would_skip(cam, item[0]))
    processed, lock = set(), threading.Lock()

    def handler(entry):
        cam, (stamp, i) = entry
        session.add_image(cam, stamp, scene.images[cam][i])
        with lock:
            processed.add((cam, stamp))

    produced, max_lag = [], 0.0
    threads = cfg.detection_thread_count()
    with DetectTimer() as timer:
        workers = [QueueWorker(queue, handler, name=f"bench-{k}").start() for k in range(threads)]
        t0, c0 = time.perf_counter(), time.process_time()
        for stamp, cam, i in events(scene, seconds):
            max_lag = max(max_lag, pace(t0, stamp - START_NS))
            if cam is None:
                session.add_pose(stamp, scene.poses[i], source="world")
                queue.notify()
            else:
                queue.put(cam, (stamp, i))
                produced.append((cam, stamp))
        t_end = time.perf_counter()
        queue.close()  # hands out what is left (the last images wait for poses that never come)
        queue.join(60.0)
        for w in workers:
            w.stop(timeout=30.0)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    dropped = set(produced) - processed
    return {"session": session, "images": len(produced), "wall": wall, "cpu": cpu,
            "feed_wall": t_end - t0, "detect_cpu": float("nan"), "detect_calls": timer.calls,
            "dropped": dropped, "max_lag": max_lag, "threads": threads,
            "queue": queue.stats(), "steal": steal_share(steal0, cpu_times())}


def write_compressed_bag(scene: Scene, seconds: float, path: Path) -> tuple[Path, int]:
    store = jazzy_typestore()
    rig = scene.rig
    infos = {cam: intrinsics_to_camera_info_fields(rig.intrinsics[cam], 0, f"{cam}_optical")
             for cam in rig.cameras}

    def messages():
        for stamp, cam, i in events(scene, seconds):
            if cam is None:
                fields = transform_to_pose_stamped_fields(scene.poses[i], "world", stamp)
                yield DEMO_POSE_TOPIC, POSE_STAMPED, stamp, message_from_fields(
                    POSE_STAMPED, fields, typestore=store)
                continue
            image_topic, info_topic = demo_camera_topics(cam)
            header = {"stamp": ns_to_stamp_fields(stamp), "frame_id": f"{cam}_optical"}
            info = dict(infos[cam], header=header)
            yield info_topic, CAMERA_INFO, stamp, message_from_fields(
                CAMERA_INFO, info, typestore=store)
            fields = {"header": header, "format": "mono8; jpeg compressed mono8",
                      "data": scene.jpegs[cam][i]}
            yield image_topic + "/compressed", COMPRESSED_IMAGE, stamp, message_from_fields(
                COMPRESSED_IMAGE, fields, typestore=store)

    write_bag(path, messages(), typestore=store)
    size = sum(f.stat().st_size for f in path.rglob("*") if f.is_file())
    return path, size


def run_bag(scene: Scene, bag: Path, flat: dict, work: Path, name: str) -> dict:
    flat = dict(flat)
    for cam in scene.rig.cameras:
        flat[f"cameras.{cam}.image_transport"] = "compressed"
    cfg_path = work / f"{name}.yaml"
    cfg_path.write_text(CalibratorConfig.from_parameters(flat).to_yaml())
    out = work / f"out_{name}"
    with (DetectTimer() as timer, MethodTimer(CalibrationSession, "calibrate") as solve,
          contextlib.redirect_stdout(io.StringIO()) as text):
        t0, c0 = time.perf_counter(), time.process_time()
        code = cli_main(["bag", str(bag), "--config", str(cfg_path), "-o", str(out), "--quiet"],
                        stdout=sys.stdout, stderr=io.StringIO())
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    data = Dataset.load(out / "dataset.yaml")
    counts = {}
    for line in text.getvalue().splitlines():  # "input: a=1, b=2, ..."
        if line.startswith("input: "):
            counts = {k: int(v) for k, v in (kv.split("=") for kv in line[7:].split(", "))}
    return {"code": code, "wall": wall, "cpu": cpu, "pairs": data.n_pairs,
            "solve_wall": solve.total, "solve_cpu": solve.cpu, "counts": counts,
            "detect_cpu": timer.cpu, "detect_calls": timer.calls, "stdout": text.getvalue(),
            "threads": CalibratorConfig.from_parameters(flat).detection_thread_count(),
            "data": data}


def result_of(session: CalibrationSession):
    out = session.calibrate()
    if not out.success:
        raise RuntimeError(out.message)
    return out.result


def frame_differences(a, b) -> tuple[float, float]:
    """Largest translation [m] and rotation [rad] difference over the frames both estimate."""
    t, r = 0.0, 0.0
    for names, Ma, Mb_names, Mb in ((a.x_names, a.X, b.x_names, b.X),
                                    (a.y_names, a.Y, b.y_names, b.Y)):
        idx = {n: i for i, n in enumerate(Mb_names)}
        for i, n in enumerate(names):
            if n in idx:
                j = idx[n]
                t = max(t, float(np.linalg.norm(Ma[i, :3, 3] - Mb[j, :3, 3])))
                r = max(r, float(rotation_distance(Ma[i, :3, :3], Mb[j, :3, :3])))
    return t, r


def truth_errors(rig, result) -> tuple[float, float]:
    X = np.array([rig.T_world_tag[int(n.split("_")[1])] for n in result.x_names])
    Y = np.array([rig.T_rig_cam[n] for n in result.y_names])
    e = result.errors_to(X, Y)
    return float(max(e["t_x"].max(), e["t_y"].max())), float(max(e["r_x"].max(),
                                                                 e["r_y"].max()))


def same_pairs(s1: CalibrationSession, s2: CalibrationSession) -> bool:
    e1, e2 = s1._acc.edges(), s2._acc.edges()
    if e1.keys() != e2.keys():
        return False
    return all(np.array_equal(getattr(e1[k], f), getattr(e2[k], f))
               for k in e1 for f in ("stamps_ns", "A", "B", "sigma", "kappa"))


def section(seconds: float, cache: Path | None, seed: int = 0,
            pool_s: int = POOL_S) -> list[str]:
    """The Markdown lines of this benchmark."""
    load0 = os.getloadavg()
    scene, t_render = make_scene(np.random.default_rng(seed), cache, pool_s)
    rig = scene.rig
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        runs = {}
        old = config_flat(rig, tmp, gate=False, decimate=1, threads=1)
        every = config_flat(rig, tmp, gate=False, decimate="auto", threads=1)
        gated = config_flat(rig, tmp, gate=True, decimate="auto", threads="auto")
        edges = dict(gated, **{"detection.discovery_step": 0.0})  # every edge counts
        one = {"sync.detection_threads": 1}
        runs["a"] = run_offline(scene, seconds, old)
        runs["b"] = run_offline(scene, seconds, every)
        runs["c"] = run_offline(scene, seconds, dict(edges, **one))
        runs["d"] = run_offline(scene, seconds, dict(gated, **one))
        runs["live"] = run_live(scene, seconds, gated)
        runs["live_edges"] = run_live(scene, seconds, edges)
        runs["live_nogate"] = run_live(scene, seconds, dict(gated, **{
            "detection.motion_gate": False}))
        bag, bag_bytes = write_compressed_bag(scene, seconds, work / "bag")
        bags = {
            "new2": run_bag(scene, bag, gated, work, "new2"),
            "edges2": run_bag(scene, bag, edges, work, "edges2"),
            "new1": run_bag(scene, bag, dict(gated, **one), work, "new1"),
            "old": run_bag(scene, bag, old, work, "old"),
        }
    load1 = os.getloadavg()
    ref = runs["b"]["session"]
    useful = useful_images(ref)
    ref_pairs = ref.counters().get("pairs_kept", 0)
    ref_result = result_of(ref)
    ref_t, ref_r = truth_errors(rig, ref_result)
    n_img = len(rig.cameras) * IMAGE_RATE_HZ

    lines = [
        f"## Camera rate: {N_CAMERAS} cameras x {IMAGE_RATE_HZ} Hz at {WIDTH} x {HEIGHT} "
        f"({n_img} images/s), poses at {POSE_RATE_HZ} Hz (issue 18)",
        "",
        f"- {seconds:g} s of simulated time ({runs['b']['images']} images, "
        f"{seconds * POSE_RATE_HZ + 1:.0f} poses); {N_TAGS} tags of 25 cm about 1 m from the "
        f"cameras; a {pool_s} s pool of images per camera (rendered in {t_render:.0f} s) "
        f"replayed in a loop with the poses of the same {pool_s} s; load average "
        f"{load0[0]:.1f} before, {load1[0]:.1f} after on {os.cpu_count()} CPUs (other jobs "
        "were running: see the note below the tables)",
        "- reference = (b), every image examined with the new detector; `pairs vs ref` = pairs "
        "kept relative to it; `useful dropped` = images the live queue dropped that gave a pair "
        "in (b); `calib. vs ref` = largest difference of any estimated frame to (b)'s "
        f"calibration; (b) itself is {1e3 * ref_t:.2f} mm / {np.degrees(ref_r):.3f} deg from the "
        "truth (the noise level), `truth` = the run's own largest error to the truth",
        "- motion gate, every edge = `detection.discovery_step: 0` (an edge whose tag is out of "
        "view holds the gate open: the same pairs as (b)); motion gate = the default "
        "`discovery_step: 0.5` (near its camera's last searched pose an image counts only the "
        "tags found there; a tag found there for the first time is looked for in the images "
        "skipped since the previous search); `searched` includes those looked at again",
        "",
        "| run | threads | images in | skipped by the gate | searched | dropped (useful) "
        "| pairs kept | pairs vs ref | same pairs as ref | calib. vs ref (mm / deg) "
        "| truth (mm / deg) | wall [s] | CPU [s] | CPU per image [ms] "
        "| detection CPU per pair [ms] |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    names = {
        "a": "(a) offline, every image, decimate 1 (old detection)",
        "b": "(b) offline, every image, decimate auto",
        "c": "(c) offline, motion gate, every edge",
        "d": "(d) offline, motion gate (defaults)",
        "live": "live, motion gate (node defaults)",
        "live_edges": "live, motion gate, every edge",
        "live_nogate": "live, every image",
    }
    for key, label in names.items():
        r = runs[key]
        s = r["session"]
        c = s.counters()
        pairs = c.get("pairs_kept", 0)
        skipped = c.get("images_skipped_no_motion", 0)
        searched = (sum(v["detected"] for v in s.camera_counters().values())
                    + c.get("images_searched_back", 0))
        n_useful = len(r["dropped"] & useful)
        result = result_of(s)
        dt, dr = frame_differences(result, ref_result)
        tt, tr = truth_errors(rig, result)
        per_pair = (f"{1e3 * r['detect_cpu'] / max(1, pairs):.1f}" if np.isfinite(
            r["detect_cpu"]) else "-")
        threads = r.get("threads", 1)
        lines.append(
            f"| {label} | {threads} | {r['images']} | {skipped} | {searched} "
            f"| {len(r['dropped'])} ({n_useful}) | {pairs} "
            f"| {100 * (pairs - ref_pairs) / max(1, ref_pairs):+.2f} % "
            f"| {'yes' if same_pairs(s, ref) else 'no'} | {1e3 * dt:.3f} / {np.degrees(dr):.4f} "
            f"| {1e3 * tt:.2f} / {np.degrees(tr):.3f} "
            f"| {r['wall']:.1f} | {r['cpu']:.1f} | {1e3 * r['cpu'] / r['images']:.2f} "
            f"| {per_pair} |")

    def detect_per_pair(r):
        return r["detect_cpu"] / max(1, r["session"].counters().get("pairs_kept", 0))

    old_pp, new_pp = detect_per_pair(runs["a"]), detect_per_pair(runs["d"])
    lines += [""]
    for key in ("live", "live_edges", "live_nogate"):
        live = runs[key]
        lines.append(
            f"- {names[key]}: the producer fed {live['images']} images in "
            f"{live['feed_wall']:.1f} s ({live['images'] / live['feed_wall']:.0f} images/s "
            f"offered; lag behind its clock at most {1e3 * live['max_lag']:.0f} ms); CPU "
            f"stolen by the hypervisor during the run {100 * live['steal']:.1f} %; per camera "
            "received / dropped: "
            + ", ".join(f"{k} {v['received']}/{v['dropped']}" for k, v in live["queue"].items()))
    lines += [
        f"- detection CPU per kept pair (one-thread runs): (a) old {1e3 * old_pp:.1f} ms, "
        f"(d) new {1e3 * new_pp:.1f} ms: {old_pp / new_pp:.1f}x lower",
        "",
        f"### Offline `rwhec-calibrate bag` on the compressed recording ({bag_bytes / 2**20:.0f} "
        f"MiB: {runs['b']['images']} JPEG images of quality {JPEG_QUALITY}, a CameraInfo per "
        "image, the poses)",
        "",
        "| run | threads | exit code | searched | pairs kept | wall [s] | replay [s] "
        "| images/s replay | calibrate [s] | images/s end to end | CPU [s] "
        "| replay CPU per image [ms] | detection CPU per pair [ms] |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    labels = {"new2": "motion gate, decimate auto (defaults)",
              "edges2": "motion gate, every edge, decimate auto",
              "new1": "motion gate, decimate auto, 1 thread",
              "old": "every image, decimate 1, 1 thread (old path)"}
    n_images = runs["b"]["images"]
    for key, label in labels.items():
        r = bags[key]
        per_pair = (f"{1e3 * r['detect_cpu'] / max(1, r['pairs']):.1f}" if r["threads"] == 1
                    else "-")
        replay = r["wall"] - r["solve_wall"]
        searched = (n_images - r["counts"].get("images_skipped_no_motion", 0)
                    + r["counts"].get("images_searched_back", 0))
        lines.append(
            f"| {label} | {r['threads']} | {r['code']} | {searched} | {r['pairs']} "
            f"| {r['wall']:.1f} | {replay:.1f} | {n_images / replay:.0f} "
            f"| {r['solve_wall']:.1f} | {n_images / r['wall']:.0f} | {r['cpu']:.1f} "
            f"| {1e3 * (r['cpu'] - r['solve_cpu']) / n_images:.2f} | {per_pair} |")
    ratio = ((bags["old"]["cpu"] - bags["old"]["solve_cpu"]) / max(1, bags["old"]["pairs"])) / (
        (bags["new1"]["cpu"] - bags["new1"]["solve_cpu"]) / max(1, bags["new1"]["pairs"]))
    lines += [
        "",
        f"- replay CPU per kept pair, old path / new defaults (1 thread each): {ratio:.1f}x",
        "- replay = reading and deserialising the bag, JPEG decoding, detection, "
        "synchronisation (wall and CPU of the whole run minus `calibrate`); calibrate = the "
        "final solve with its assessment (cross-validation, uncertainty), a fixed cost that "
        "does not grow with the images (it grows with the pairs); detection CPU = process CPU "
        "inside `TargetDetector.detect` (one-thread runs only; it includes OpenCV's own worker "
        "threads).",
        "",
    ]
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=12.0, help="simulated seconds (12)")
    ap.add_argument("--cache", type=Path, default=None,
                    help="directory to keep the rendered pool in between runs")
    ap.add_argument("--pool", type=int, default=POOL_S,
                    help=f"seconds of images rendered and looped ({POOL_S}; whole seconds)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--output", type=Path, default=None, help="Markdown file (default: print)")
    args = ap.parse_args(argv)
    text = "\n".join(section(args.seconds, args.cache, args.seed, args.pool))
    print(text)
    if args.output is not None:
        args.output.write_text(text + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())

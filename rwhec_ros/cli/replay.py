"""Subcommands that feed the live session: ``bag`` (a rosbag2 recording, message by message through
the node's message handlers) and ``demo`` (the simulated rig)."""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np

from ..config.targets import target_parameters
from ..session.paths import plain_output_root
from ..vision.targets import TargetSpec
from .common import (
    EXIT_OK,
    BadInput,
    Printer,
    Progress,
    SolveSettings,
    check_positive,
    config_from_parameters,
    output_paths,
    prior_overrides,
    read_config,
    solver_overrides,
)
from .run import Run, pause_for_test
from .solving import calibrate_session, input_line

__all__ = ["cmd_bag", "cmd_demo", "demo_parameters", "LiveWatch"]

#: Prefixes of the parameters that describe the simulated rig itself (kept by ``demo --config``);
#: ``sync.time_offset.<camera>`` names the configuration's cameras, not the rig's.
RIG_PARAMETER_PREFIXES = ("camera_carrier.", "tag_carrier.", "pose_source.", "cameras.", "tags.",
                          "targets.", "sync.time_offset.")


def cmd_bag(args: argparse.Namespace, say: Printer) -> int:
    from ..data.rosbag import (
        CAMERA_INFO,
        COMPRESSED_IMAGE,
        IMAGE,
        POSE_STAMPED,
        TF_MESSAGE,
        TfTree,
        bag_topics,
    )
    from ..session import CalibrationSession, MessageHandlers
    from .detections import detection_images

    config = read_config(args, solver_overrides(args))
    root = plain_output_root(config.output.directory)
    paths = output_paths(args, report=args.report, root=root)  # refuse early, before any work
    topics = bag_topics(args.bag)
    ps = config.pose_source

    routes: dict[str, tuple[str, str | None, str]] = {}
    for cam in config.cameras:
        compressed = cam.image_transport == "compressed"
        routes[cam.subscribed_topic] = ("compressed" if compressed else "image", cam.name,
                                        COMPRESSED_IMAGE if compressed else IMAGE)
        routes[cam.camera_info_topic] = ("info", cam.name, CAMERA_INFO)
    if ps.type == "topic":
        routes[ps.topic] = ("pose", None, POSE_STAMPED)
    elif "/tf" not in topics and "/tf_static" not in topics:
        raise BadInput(f"bag {str(args.bag)!r}: pose_source.type is 'tf' but the bag has no "
                       f"/tf or /tf_static; topics in the bag: {sorted(topics)}")
    # one rule for every input the configuration names: missing -> bad input (exit code 2)
    missing = [f"{topic} ({'pose_source.topic' if kind == 'pose' else f'camera {cam}'})"
               for topic, (kind, cam, _) in routes.items() if topic not in topics]
    if missing:
        hints = "".join(_transport_hint(cam, topics) for cam in config.cameras
                        if cam.subscribed_topic not in topics)
        raise BadInput(f"bag {str(args.bag)!r}: no topic " + ", ".join(missing)
                       + f"; topics in the bag: {sorted(topics)}" + hints)
    for topic, (_, cam, msgtype) in routes.items():
        if topics[topic][0] != msgtype:
            raise BadInput(f"bag {str(args.bag)!r}: topic {topic} has type {topics[topic][0]}, "
                           f"expected {msgtype}" + _type_hint(cam, topic, topics[topic][0]))
    for tf_topic in ("/tf", "/tf_static"):
        if ps.type == "tf" and tf_topic in topics and topics[tf_topic][0] != TF_MESSAGE:
            raise BadInput(f"bag {str(args.bag)!r}: {tf_topic} has type "
                           f"{topics[tf_topic][0]}, expected {TF_MESSAGE}")

    session = CalibrationSession(config)
    handlers = MessageHandlers(session)
    drawn = detection_images(args)  # --detections DIR
    settings = SolveSettings.from_parameters(config.to_parameters())
    run = Run("bag", say, paths, root, force=args.force,
              **{"resume_options": settings.resume_options(args.report),
                 **getattr(args, "run_as", {})})  # check: its directory and resume command
    try:
        run.enter("reading", pause=False)  # the pause: half-way through the messages
        try:
            tf_failure, errors = _replay(args, say, session, handlers, routes, TfTree,
                                         drawn)
        except ValueError as exc:  # a bag damaged part-way: keep what was read
            session.close()
            kept = run.keep(session.dataset())
            raise BadInput(f"{exc}" + (f"; {run.kept_words()}" if kept else "")) from None
        session.close()
        for exc in errors[:3]:
            say.warning("bag", f"detection thread error: {type(exc).__name__}: {exc}")
        counters = session.counters()
        for sentence in session.rejections():
            say.warning("bag", sentence)
        if tf_failure and not counters.get("pairs_kept"):
            say.warning("bag", tf_failure)
        finish = getattr(args, "finish", None) or calibrate_session  # check: its own
        code, _ = finish(say, session, run, report=args.report, inputs=[input_line(counters)]
                         + ([] if drawn is None else [drawn.line()]))
        return code
    except KeyboardInterrupt as exc:
        session.close()
        raise run.interrupted(exc, session.dataset) from None


def _replay(args, say: Printer, session, handlers, routes,
            tf_tree_type, drawn=None) -> tuple[str, list[BaseException]]:
    """Feed the bag's messages to the session (images on ``sync.detection_threads`` threads,
    :class:`~rwhec_ros.session.replay.ReplayFeeder`); returns why tf lookups failed (or "") and
    the detection threads' errors. On Ctrl-C the threads stop and the exception propagates.
    ``drawn`` (:class:`~rwhec_ros.cli.detections.DetectionImages`) draws each image examined."""
    from ..data.rosbag import read_messages
    from ..messages import stamp_to_ns
    from ..session.info_wait import CameraInfoWait
    from ..session.replay import ReplayFeeder
    from ..sync.at_rest import AtRestRule

    config = session.config
    ps = config.pose_source
    tf = None
    if ps.type == "tf":  # the whole recording's tf first: lookups never wait for later data
        tf = tf_tree_type(max_gap_ns=int(round(config.sync.max_gap_s * 1e9)),
                          tolerance_ns=int(round(config.sync.extrapolation_tolerance_s * 1e9)),
                          at_rest=AtRestRule.from_sync(config.sync))
        progress = Progress(say.err, "reading /tf", enabled=not args.quiet)
        for m in read_messages(args.bag, ["/tf", "/tf_static"], on_progress=progress):
            tf.add_message(m.msg, static=m.topic == "/tf_static")
        progress.close()
    failure = ""
    stream = _TfStream(tf, ps, session) if tf is not None else None  # for the time offsets

    def draw(cam: str, msg, outcome) -> None:
        try:
            stamp = stamp_to_ns(msg.header.stamp)
        except (ValueError, TypeError, AttributeError):
            stamp = "bad_stamp"
        drawn(cam, stamp, outcome)

    feeder = ReplayFeeder(handlers, threads=config.detection_thread_count(),
                          queue_size=config.sync.image_queue_size,
                          on_outcome=None if drawn is None else draw)

    def image(cam: str, held: tuple) -> None:
        nonlocal failure
        msg, compressed = held
        T = None
        if tf is not None:
            try:
                stamp = stamp_to_ns(msg.header.stamp)
                stream.feed_until(stamp)
                T = tf.lookup(ps.parent, ps.child, stamp
                              + int(round(config.sync.time_offset_s(cam) * 1e9)))
            except LookupError as exc:
                session.record("no_tf_at_stamp")
                failure = failure or (
                    f"no tf from {ps.parent} to {ps.child} at the image stamps ({exc}); frames "
                    f"in the recording: {sorted(tf.frames)}")
                return
            except (ValueError, TypeError, AttributeError):
                pass  # a bad stamp: on_image rejects and counts it
        feeder.image(cam, msg, compressed=compressed, T_parent_child=T)

    waiting = CameraInfoWait()  # images a few ms ahead of their camera's first CameraInfo
    def live_words() -> str:
        status = session.live.status()
        # the live estimate judges precision only: say so beside the verdict of the full solve
        return status.line() + (" (precision of the live estimate; the full solve's verdict "
                                "follows)" if status.estimate is not None else "")

    progress = Progress(say.err, "reading bag", enabled=not args.quiet, status=live_words)
    watch = LiveWatch(session.live, say, enabled=not args.quiet, lines=not progress.tty)

    def on_progress(done: int, total: int) -> None:
        watch(done, total)
        progress(done, total)
        if done == total // 2:
            pause_for_test("reading")

    try:
        for m in read_messages(args.bag, list(routes), on_progress=on_progress):
            kind, cam, _ = routes[m.topic]
            if kind == "pose":
                feeder.pose(m.msg)
            elif kind == "info":
                handlers.on_camera_info(cam, m.msg)
                if session.has_camera_info(cam):
                    for held in waiting.release(cam):
                        image(cam, held)
            elif not session.has_camera_info(cam):
                try:
                    stamp = stamp_to_ns(m.msg.header.stamp)
                except (ValueError, TypeError, AttributeError):
                    stamp = None
                if stamp is None:
                    image(cam, (m.msg, kind == "compressed"))
                else:
                    for held in waiting.hold(cam, stamp, (m.msg, kind == "compressed")):
                        image(cam, held)
            else:
                image(cam, (m.msg, kind == "compressed"))
        for cam, held in waiting.drain():
            image(cam, held)
        feeder.close()
    except KeyboardInterrupt:
        feeder.abort()
        raise
    finally:
        progress.close()
    return failure, feeder.errors


class LiveWatch:
    """Drives the session's live re-solve from the read loop (``LiveSolver.tick``, which never
    blocks; not at all unless ``enabled``: ``--quiet`` shows nothing, so nothing is solved) and,
    where no progress bar shows it (``lines``: not a terminal), prints a line with the first
    live estimate and whenever its convergence verdict changes."""

    def __init__(self, live, say: Printer, *, enabled: bool, lines: bool) -> None:
        self.live, self.say, self.enabled, self.lines = live, say, enabled, lines
        self.shown = None

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        self.live.tick()
        if not self.lines:
            return
        est = self.live.estimate
        if est is not None and est.converged != self.shown:
            self.shown = est.converged
            self.say.progress(f"live estimate at message {done}/{total}: {est.line()}")


class _TfStream:
    """The pose stream of a tf pose source for the time offsets
    (:meth:`~rwhec_ros.session.CalibrationSession.add_stream_pose`): the chain ``pose_source.
    parent -> child`` at the stamps of its dynamic links' samples
    (:meth:`~rwhec_ros.data.rosbag.TfTree.chain_stamps`), fed as the images come, up to the
    time-offset window after each image (the session records the stream around its kept pairs
    only, and the newest ``sync.pose_buffer_size`` samples before their marks)."""

    def __init__(self, tf, pose_source, session) -> None:
        from ..sync.pose_track import track_window_ns

        sync = session.config.sync
        self.tf, self.ps, self.session = tf, pose_source, session
        self.stamps = (tf.chain_stamps(pose_source.parent, pose_source.child)
                       if sync.estimate_time_offset else np.zeros(0, dtype=np.int64))
        self.ahead = track_window_ns(sync.time_offset_range_s) + int(sync.max_gap_s * 1e9)
        self.next = 0

    def feed_until(self, stamp_ns: int) -> None:
        end = int(np.searchsorted(self.stamps, int(stamp_ns) + self.ahead, side="right"))
        for s in self.stamps[self.next:end]:
            try:
                T = self.tf.lookup(self.ps.parent, self.ps.child, int(s))
            except LookupError:
                continue
            self.session.add_stream_pose(int(s), T)
        self.next = max(self.next, end)


def _type_hint(camera: str | None, topic: str, found: str) -> str:
    """A hint when a camera's image topic holds the other transport's messages."""
    from ..data.rosbag import COMPRESSED_IMAGE, IMAGE

    if camera is None:
        return ""
    if found == COMPRESSED_IMAGE:
        base = topic.removesuffix("/compressed")
        return (f"; for compressed images set cameras.{camera}.image_transport: compressed "
                f"and cameras.{camera}.image_topic: {base} (the images are read from "
                f"<image_topic>/compressed)")
    if found == IMAGE:
        return f"; for raw images set cameras.{camera}.image_transport: raw"
    return ""


def _transport_hint(cam, topics) -> str:
    """A hint when the bag holds the camera's images on the other transport's topic."""
    raw, compressed = cam.image_topic, cam.image_topic + "/compressed"
    if cam.image_transport == "raw" and compressed in topics:
        return (f"; the bag has {compressed}: set cameras.{cam.name}.image_transport: "
                "compressed")
    if cam.image_transport == "compressed" and raw in topics:
        return f"; the bag has {raw}: set cameras.{cam.name}.image_transport: raw"
    return ""


def demo_parameters(rig, *, output_directory: str = "", mode: str = "fast") -> dict[str, Any]:
    """Flat calibrator parameters for a simulated rig (the values of ``config/demo.yaml``, with
    the rig's cameras, tags and boards, named as :meth:`SimulatedRig.target_names` says):
    motion-capture ``PoseStamped`` ``world -> rig``, cameras on
    ``rig``, tags in ``world``; ``output_directory`` as ``output.directory`` (``""``: the
    default of :mod:`rwhec_ros.session.paths`)."""
    from ..simulation import DEMO_POSE_TOPIC, DEMO_RIG_FRAME, DEMO_WORLD_FRAME, demo_camera_topics

    flat: dict[str, Any] = {
        "camera_carrier.frame": DEMO_RIG_FRAME, "camera_carrier.moving": True,
        "tag_carrier.frame": DEMO_WORLD_FRAME, "tag_carrier.moving": False,
        "pose_source.type": "topic", "pose_source.topic": DEMO_POSE_TOPIC,
        "pose_source.parent": DEMO_WORLD_FRAME, "pose_source.child": DEMO_RIG_FRAME,
        "cameras.names": list(rig.cameras),
        "tags.family": rig.family, "tags.ids": list(rig.single_tag_ids),
        "tags.default_size": float(rig.tag_size),
        "noise.sigma": 0.0, "noise.kappa": 0.0, "noise.from_reprojection": False,
        "sync.max_gap_s": 0.1, "sync.extrapolation_tolerance_s": 0.01,
        "sync.image_queue_size": 6,
        "keyframe.min_rotation_rad": 0.05, "keyframe.min_translation_m": 0.02,
        "keyframe.max_pairs_per_edge": 200,
        "solver.mode": mode, "solver.min_pairs": 3, "solver.reject_outliers": False,
        "output.directory": output_directory,
    }
    boards = [TargetSpec(f"board_{j}", board=b) for j, b in sorted(rig.boards.items())]
    if boards:
        flat["targets.names"] = [t.name for t in boards]
        for t in boards:
            flat.update(target_parameters(t))
    for cam in rig.cameras:
        image_topic, info_topic = demo_camera_topics(cam)
        flat[f"cameras.{cam}.image_topic"] = image_topic
        flat[f"cameras.{cam}.camera_info_topic"] = info_topic
        flat[f"cameras.{cam}.frame"] = f"{cam}_optical"
    return flat


def cmd_demo(args: argparse.Namespace, say: Printer) -> int:
    from ..session import CalibrationSession
    from ..simulation import demo_board_rig, simulated_stream

    if args.cameras < 1 or args.tags < 1:
        raise BadInput(f"--cameras/--tags: must be >= 1, got {args.cameras}/{args.tags}")
    check_positive("--seconds", args.seconds)
    check_positive("--rate", args.rate)
    overrides = solver_overrides(args)
    settings = read_config(args)
    t0 = time.perf_counter()
    try:
        rig = demo_board_rig(args.board, args.cameras, args.tags, what="--board")
    except ValueError as exc:
        raise BadInput(str(exc)) from None
    if args.bag is not None:
        return _write_demo_bag(args, say, rig)
    flat = demo_parameters(rig)
    if settings is not None:
        flat.update({k: v for k, v in settings.to_parameters().items()
                     if not k.startswith(RIG_PARAMETER_PREFIXES)})
    flat.update(overrides)
    flat.update(prior_overrides(args, flat))
    config = config_from_parameters(flat, "demo")
    root = plain_output_root(config.output.directory)
    paths = output_paths(args, report=args.report, root=root)  # refuse early, before any work
    session = CalibrationSession(config)
    run = Run("demo", say, paths, root, force=args.force,
              resume_options=SolveSettings.from_parameters(flat).resume_options(args.report))
    try:
        for cam in rig.cameras:
            session.set_camera_info(cam, rig.intrinsics[cam])
        say.progress(f"simulating: {len(rig.cameras)} cameras, {len(rig.single_tag_ids)} "
                     f"tags, {len(rig.boards)} boards, {args.seconds:g} s at {args.rate:g} Hz")
        rng = np.random.default_rng(args.seed)
        n_images = 0
        run.enter("reading", pause=False)  # the pause: half-way through the images
        half = int(args.seconds * args.rate * len(rig.cameras)) // 2
        for stamp, cam, data in simulated_stream(rig, rng, seconds=args.seconds,
                                                 image_rate_hz=args.rate):
            if cam is None:
                session.add_pose(stamp, data, source=config.pose_source.parent)
            else:
                session.add_image(cam, stamp, data)
                n_images += 1
                if n_images == half:
                    pause_for_test("reading")
        session.close()
        counters = session.counters()
        simulated = (f"demo: {len(rig.cameras)} cameras, {len(rig.single_tag_ids)} tags, "
                     f"{len(rig.boards)} boards, {args.seconds:g} s, {n_images} images "
                     f"rendered and searched, {counters.get('pairs_kept', 0)} pairs kept "
                     f"({time.perf_counter() - t0:.1f} s)")
        code, outcome = calibrate_session(say, session, run, report=args.report,
                                          inputs=[simulated])
    except KeyboardInterrupt as exc:
        session.close()
        raise run.interrupted(exc, session.dataset) from None
    if outcome.result is None:
        return code
    result = outcome.result
    positions = rig.target_names()
    X_true = np.array([rig.T_world_tag[positions[n]] for n in result.x_names])
    Y_true = np.array([rig.T_rig_cam[n] for n in result.y_names])
    err = result.errors_to(X_true, Y_true)
    say("errors against the simulation's ground truth:")
    for names, t_key, r_key in ((result.y_names, "t_y", "r_y"), (result.x_names, "t_x", "r_x")):
        for i, name in enumerate(names):
            say(f"  {name}: {1e3 * err[t_key][i]:.2f} mm, {np.degrees(err[r_key][i]):.3f} deg")
    t_max = 1e3 * max(err["t_x"].max(), err["t_y"].max())
    r_max = np.degrees(max(err["r_x"].max(), err["r_y"].max()))
    say(f"  max: {t_max:.2f} mm, {r_max:.3f} deg over {len(result.x_names) + len(result.y_names)}"
        f" frames ({time.perf_counter() - t0:.1f} s in total)")
    return code


def _write_demo_bag(args: argparse.Namespace, say: Printer, rig) -> int:
    """``demo --bag DIR``: the simulated recording written as a rosbag2 directory (sqlite3, or
    ``--storage mcap``) instead of being calibrated; an existing DIR is refused unless
    ``--force`` (then replaced once the new recording is complete)."""
    import shutil
    import tempfile
    from pathlib import Path

    from ..simulation import write_simulated_bag

    target = Path(args.bag)
    if target.exists() and not args.force:
        raise BadInput(f"--bag: {str(target)!r} already exists (a recording is never "
                       "overwritten): give another directory, or --force to replace it")
    target.parent.mkdir(parents=True, exist_ok=True)
    say.progress(f"recording the simulation: {len(rig.cameras)} cameras, "
                 f"{len(rig.single_tag_ids)} tags, {args.seconds:g} s at {args.rate:g} Hz")
    with tempfile.TemporaryDirectory(prefix=f".{target.name}.", dir=target.parent) as tmp:
        staged = Path(tmp) / target.name
        write_simulated_bag(staged, rig, np.random.default_rng(args.seed), seconds=args.seconds,
                            image_rate_hz=args.rate, storage=args.storage)
        if target.exists():  # --force: the new recording replaces the old one, complete
            shutil.rmtree(target) if target.is_dir() else target.unlink()
        staged.rename(target)  # the same name: the storage file is <name>.db3 / .mcap
    say.files({"bag": target})
    say(f"calibrate it with: rwhec-calibrate bag {target} --config config/demo.yaml")
    return EXIT_OK

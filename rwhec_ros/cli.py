"""``rwhec-calibrate``: offline calibration from files, rosbag2 recordings and a simulation.

No ROS is needed. Every subcommand prints the summary of the node's ``calibrate`` service
(certified?, ``rho_hat``, each frame's estimate ``parent->child``, edges excluded and why) and
writes the session's output files: the result YAML (``certified``, ``suboptimality_bound``,
``scale``, ``frames``, ``timing_s``, ``identifiability``, ``config``, ...), the data set and a
launch file of ``static_transform_publisher`` nodes; ``--report`` adds a PNG and an HTML page
(:mod:`rwhec_ros.report`). Outputs are never overwritten: a new ``calibration_<UTC stamp>``
directory under the output directory, or for ``csv -o OUT.yaml`` exactly ``OUT.yaml`` with
``OUT.launch.py``, ``OUT.dataset.yaml`` (and ``OUT.report.png``/``.html``) beside it, refused
when any exists unless ``--force``.

Subcommands::

    rwhec-calibrate csv DIR [-o OUT.yaml] [--unknown-scale] [--sigma S] [--kappa K]
                            [--min-pairs N] [--mode fast|sdp|local] [--robust] [--report]
    rwhec-calibrate bag BAG --config CONFIG.yaml [-o OUTDIR] [--mode ...] [--report]
    rwhec-calibrate dataset FILE [-o OUTDIR] [--mode ...] [--min-pairs N] [--report]
    rwhec-calibrate demo [--cameras N] [--tags N] [--seconds S] [--seed S] [-o OUTDIR] [--report]
    rwhec-calibrate report RESULT.yaml [--dataset FILE]

``csv`` reads the paper's layout (:func:`rwhec_ros.data.paper_csv.read_paper_csv`; tags
``tag_<j>`` are X, cameras ``cam_<k>`` are Y; defaults sigma 0.1 m, kappa 125, 3 pairs per edge
as the authors). ``bag`` feeds a rosbag2 recording (sqlite3 or mcap) message by message, in log
time order, into a :class:`~rwhec_ros.session.CalibrationSession` through the node's
:class:`~rwhec_ros.session.handlers.MessageHandlers`, with the same configuration file as the node
(PoseStamped topic, or ``/tf`` + ``/tf_static`` looked up at each image stamp). Unlike the node,
images are processed synchronously (none is dropped) and the tf lookup sees the whole recording
(the node waits ``sync.tf_timeout_s``). ``dataset`` solves a saved data set
(:mod:`rwhec_ros.data.dataset`). ``demo`` runs the simulated rig of :mod:`rwhec_ros.simulation`
through rendering, detection, synchronisation and the solver, and compares with the truth.

Exit codes: 0 certified solution; 1 solution found but not certified (files are written);
2 bad input (the message names the file and line or the parameter); 3 no solution (not enough
data, solver failure).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TextIO

import numpy as np
import yaml

from . import __version__

__all__ = ["main", "build_parser", "demo_parameters", "EXIT_CERTIFIED", "EXIT_NOT_CERTIFIED",
           "EXIT_BAD_INPUT", "EXIT_NO_SOLUTION"]

EXIT_CERTIFIED = 0
EXIT_NOT_CERTIFIED = 1
EXIT_BAD_INPUT = 2
EXIT_NO_SOLUTION = 3

PROG = "rwhec-calibrate"
MODES = ("fast", "sdp", "local")
#: Default output root when neither ``-o`` nor a configuration names one.
DEFAULT_OUTPUT = "rwhec_output"


class _BadInput(Exception):
    """Bad input for the CLI: printed without a traceback, exit code 2."""


class _Printer:
    """Where the CLI talks: ``out`` for results, ``err`` for progress and errors."""

    def __init__(self, out: TextIO, err: TextIO) -> None:
        self.out, self.err = out, err

    def __call__(self, text: str = "") -> None:
        print(text, file=self.out)

    def summary(self, message: str) -> None:
        """The session's one-line summary, one ``;``-separated part per line."""
        for part in message.split("; "):
            print(part, file=self.out)


class _Progress:
    """Progress bar on stderr (a terminal only; elsewhere one line at the end)."""

    def __init__(self, err: TextIO, label: str, *, enabled: bool = True) -> None:
        self.err, self.label = err, label
        self.tty = enabled and hasattr(err, "isatty") and err.isatty()
        self.enabled = enabled
        self.t0 = time.monotonic()
        self.last = -1.0
        self.done = self.total = 0

    def __call__(self, done: int, total: int) -> None:
        self.done, self.total = done, total
        now = time.monotonic()
        if not self.tty or (now - self.last < 0.2 and done < total):
            return
        self.last = now
        frac = done / total if total else 1.0
        bar = "#" * int(30 * frac)
        self.err.write(f"\r{self.label} [{bar:<30}] {100 * frac:5.1f}% {done}/{total} messages, "
                       f"{now - self.t0:.1f} s")
        self.err.flush()

    def close(self) -> None:
        if not self.enabled:
            return
        if self.tty:
            self.err.write("\n")
        self.err.write(f"{self.label}: {self.done} messages in {time.monotonic() - self.t0:.1f} s"
                       "\n")
        self.err.flush()


# ------------------------------------------------------------------------------------------------
# parser


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``rwhec-calibrate`` (subcommands csv, bag, dataset, demo, report)."""
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Certifiably globally optimal robot-world/hand-eye calibration "
                    "(A_i X_j = Y_k B_i) without ROS.",
        epilog="Exit codes: 0 certified, 1 not certified, 2 bad input, 3 no solution.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def common(p: argparse.ArgumentParser, *, mode_default: str | None) -> None:
        p.add_argument("--mode", choices=MODES, default=mode_default,
                       help="solver mode (default: %(default)s"
                            + ("" if mode_default else ", or the configuration's solver.mode")
                            + ")")
        p.add_argument("--report", action="store_true",
                       help="also write the report PNG and HTML page beside the result")

    p = sub.add_parser("csv", help="the paper's CSV layout (tag_<j>_cam_<k>_A.csv / _B.csv)")
    p.add_argument("directory", metavar="DIR", type=Path)
    p.add_argument("-o", "--output", metavar="OUT.yaml", type=Path,
                   help="result YAML path; OUT.launch.py, OUT.dataset.yaml (and OUT.report.*) "
                        f"go beside it (default: a new directory under {DEFAULT_OUTPUT}/)")
    p.add_argument("--force", action="store_true", help="overwrite existing output files")
    p.add_argument("--unknown-scale", action="store_true",
                   help="estimate a common scale of the B translations (paper Problem 3)")
    p.add_argument("--sigma", type=float, default=0.1,
                   help="translation std of B [m] (default %(default)s, as the authors)")
    p.add_argument("--kappa", type=float, default=125.0,
                   help="Langevin concentration of B rotations (default %(default)s)")
    p.add_argument("--min-pairs", type=int, default=3,
                   help="edges with fewer pairs are left out (default %(default)s)")
    p.add_argument("--robust", action="store_true",
                   help="outlier pre-pass (solver.reject_outliers) before the solve")
    p.add_argument("--camera-carrier", default="rig",
                   help="frame the cameras (Y) are published in (default %(default)s)")
    p.add_argument("--tag-carrier", default="world",
                   help="frame the tags (X) are published in (default %(default)s)")
    common(p, mode_default="fast")

    p = sub.add_parser("bag", help="a rosbag2 recording (sqlite3 or mcap) with the node's config")
    p.add_argument("bag", metavar="BAG", type=Path)
    p.add_argument("--config", required=True, type=Path, metavar="CONFIG.yaml",
                   help="the node's parameter file (config/*.yaml)")
    p.add_argument("--node-name", default=None,
                   help="section of the parameter file (default: its only one, or calibrator)")
    p.add_argument("-o", "--output", metavar="OUTDIR", type=Path,
                   help="output directory (default: the configuration's output.directory)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    common(p, mode_default=None)

    p = sub.add_parser("dataset", help="a data set saved by the session or the CLI")
    p.add_argument("file", metavar="FILE", type=Path)
    p.add_argument("-o", "--output", metavar="OUTDIR", type=Path,
                   help="output directory (default: the data set configuration's "
                        f"output.directory, else {DEFAULT_OUTPUT})")
    p.add_argument("--min-pairs", type=int, default=None,
                   help="edges with fewer pairs are left out (default: solver.min_pairs, 3)")
    p.add_argument("--robust", action="store_true", help="outlier pre-pass before the solve")
    p.add_argument("--camera-carrier", default="rig",
                   help="camera carrier frame when the data set names none (default %(default)s)")
    p.add_argument("--tag-carrier", default="world",
                   help="tag carrier frame when the data set names none (default %(default)s)")
    common(p, mode_default=None)

    p = sub.add_parser("demo", help="simulated mobile rig: render, detect, sync, solve, compare")
    p.add_argument("--cameras", type=int, default=3, help="cameras on the rig (%(default)s)")
    p.add_argument("--tags", type=int, default=6, help="tags in the room (%(default)s)")
    p.add_argument("--seconds", type=float, default=24.0,
                   help="simulated duration [s] (default %(default)s: one full yaw turn)")
    p.add_argument("--rate", type=float, default=5.0, help="image rate [Hz] (%(default)s)")
    p.add_argument("--seed", type=int, default=0, help="random seed (%(default)s)")
    p.add_argument("-o", "--output", metavar="OUTDIR", type=Path, default=Path(DEFAULT_OUTPUT),
                   help="output directory (default %(default)s)")
    common(p, mode_default="fast")

    p = sub.add_parser("report", help="report PNG + HTML of a written result")
    p.add_argument("result", metavar="RESULT.yaml", type=Path)
    p.add_argument("--dataset", type=Path, default=None,
                   help="the data set that was solved (default: the one beside the result)")
    return parser


# ------------------------------------------------------------------------------------------------
# shared steps


def _output_paths_for(result_path: Path):
    """Session layout (``.../result.yaml``) or the explicit ``OUT.yaml`` layout."""
    from .data.results import output_paths, session_output_paths

    if result_path.name == "result.yaml":
        return session_output_paths(result_path.parent)
    return output_paths(result_path)


def _identifiability(problem, result):
    """Whole-problem identifiability at the solution (as the session), or None on failure."""
    try:
        from .core.identifiability import analyze

        return analyze(problem, solution=(result.X, result.Y, float(result.scale)))
    except Exception:  # noqa: BLE001 - an optional extra, as in the session
        return None


def _solve_and_write(
    say: _Printer,
    problem,
    dataset,
    naming,
    paths,
    *,
    mode: str,
    robust: bool,
    excluded: dict[str, str],
    config: dict[str, Any],
    source: dict[str, Any],
    force: bool,
    report: bool,
) -> int:
    """Solve ``problem`` and write the outputs like the session does (csv and dataset)."""
    from .data.results import result_document, write_outputs
    from .session import solve_problem, static_transforms_launch, summary

    try:
        result, dropped, _ = solve_problem(problem, mode=mode, reject_outliers=robust)
    except Exception as exc:  # noqa: BLE001 - reported, exit code 3
        say(f"solver failed: {type(exc).__name__}: {exc}")
        return EXIT_NO_SOLUTION
    excluded.update(dropped)
    ident = _identifiability(problem, result)
    doc = result_document(result, naming, excluded=excluded,
                          identifiability=None if ident is None else ident.to_dict(),
                          config=config, source=source)
    c = result.certificate
    launch = static_transforms_launch(naming.transforms(result), header=(
        f"certified: {result.certified}, suboptimality bound {c.suboptimality_bound:.3g}, "
        f"from {source.get('type', '?')} {source.get('path', '')}"))
    files = write_outputs(paths, result_yaml=yaml.safe_dump(doc, sort_keys=False),
                          launch_text=launch, dataset=dataset, force=force)
    say.summary(summary(result, problem, excluded, naming))
    _print_files(say, files)
    if report:
        _write_report(say, doc, problem, paths, ident)
    return EXIT_CERTIFIED if result.certified else EXIT_NOT_CERTIFIED


def _print_files(say: _Printer, files: dict[str, str]) -> None:
    for key, path in files.items():
        say(f"{key}: {path}")


def _write_report(say: _Printer, doc: dict, problem, paths, ident=None) -> None:
    from .report import write_report

    files = write_report(doc, problem, paths.report_png, paths.report_html,
                         identifiability=ident)
    say(f"report: {files.png}")
    say(f"report page: {files.html}")


def _session_outcome(say: _Printer, session, report: bool) -> tuple[int, Any]:
    """``session.calibrate()``, printed; the report from the written data set."""
    outcome = session.calibrate()
    say.summary(outcome.message)
    if not outcome.success:
        return EXIT_NO_SOLUTION, outcome
    _print_files(say, outcome.files)
    if report and "dataset" in outcome.files and "result" in outcome.files:
        from .data.dataset import Dataset

        problem = Dataset.load(outcome.files["dataset"]).to_problem(
            min_pairs=session.config.solver.min_pairs)
        doc = yaml.safe_load(outcome.result_yaml)
        _write_report(say, doc, problem, _output_paths_for(Path(outcome.files["result"])))
    code = EXIT_CERTIFIED if outcome.result.certified else EXIT_NOT_CERTIFIED
    return code, outcome


def _config_with_overrides(path: Path, node_name: str | None, overrides: dict[str, Any]):
    from .config import CalibratorConfig, read_parameter_file

    flat = read_parameter_file(path, node_name)
    flat.update(overrides)
    try:
        return CalibratorConfig.from_parameters(flat)
    except ValueError as exc:
        raise _BadInput(f"config file {str(path)!r}: {exc}") from None


def _check_positive(name: str, value: float) -> None:
    if not (np.isfinite(value) and value > 0):
        raise _BadInput(f"{name}: must be finite and > 0, got {value!r}")


# ------------------------------------------------------------------------------------------------
# subcommands


def _cmd_csv(args: argparse.Namespace, say: _Printer) -> int:
    from .data.dataset import Dataset
    from .data.paper_csv import read_paper_csv
    from .data.results import FrameNaming, new_output_dir, output_paths, session_output_paths

    _check_positive("--sigma", args.sigma)
    _check_positive("--kappa", args.kappa)
    if args.min_pairs < 1:
        raise _BadInput(f"--min-pairs: must be >= 1, got {args.min_pairs}")
    if args.output is not None:  # refuse early, before any work
        paths = output_paths(args.output)
        targets = [paths.result, paths.launch, paths.dataset, paths.dataset.with_suffix(".npz")]
        if args.report:
            targets += [paths.report_png, paths.report_html]
        existing = [str(p) for p in targets if p.exists()]
        if existing and not args.force:
            raise _BadInput(f"refusing to overwrite existing file(s) {existing} "
                            "(use --force to overwrite)")
    # all edges first (min_pairs=1), so that the edges left out can be reported
    everything = read_paper_csv(args.directory, sigma=args.sigma, kappa=args.kappa,
                                min_pairs=1, unknown_scale=args.unknown_scale)
    naming = FrameNaming.from_carriers(everything.x_names, everything.y_names,
                                       camera_carrier=args.camera_carrier,
                                       tag_carrier=args.tag_carrier)
    source = {"type": "paper_csv", "path": str(args.directory)}
    carriers = {n: p for n, (p, _) in naming.frames.items()}
    dataset = Dataset.from_problem(everything, metadata={"source": source}, carriers=carriers)
    excluded = {f"({e.x}, {e.y})": f"{e.n} pairs < min_pairs={args.min_pairs}"
                for e in dataset.edges if e.n < args.min_pairs}
    try:
        problem = dataset.to_problem(min_pairs=args.min_pairs)
    except ValueError as exc:
        say(f"not enough data: {exc}")
        return EXIT_NO_SOLUTION
    config = {
        "camera_carrier.frame": args.camera_carrier,
        "tag_carrier.frame": args.tag_carrier,
        "tags.unknown_scale": bool(args.unknown_scale),
        "noise.sigma": float(args.sigma),
        "noise.kappa": float(args.kappa),
        "solver.mode": args.mode,
        "solver.min_pairs": int(args.min_pairs),
        "solver.reject_outliers": bool(args.robust),
    }
    if args.output is None:
        paths = session_output_paths(new_output_dir(DEFAULT_OUTPUT))
    return _solve_and_write(say, problem, dataset, naming, paths, mode=args.mode,
                            robust=args.robust, excluded=excluded, config=config, source=source,
                            force=args.force, report=args.report)


def _cmd_dataset(args: argparse.Namespace, say: _Printer) -> int:
    from .config import CalibratorConfig
    from .data.dataset import Dataset
    from .data.results import FrameNaming, new_output_dir, session_output_paths

    data = Dataset.load(args.file)
    params = dict(data.metadata.get("config") or {})
    config = None
    if params:
        try:
            config = CalibratorConfig.from_parameters(params)
        except ValueError as exc:
            raise _BadInput(f"{args.file}: metadata.config: {exc}") from None
    mode = args.mode or (config.solver.mode if config else "fast")
    if args.min_pairs is not None:
        min_pairs = args.min_pairs
    else:
        min_pairs = config.solver.min_pairs if config else 3
    if min_pairs < 1:
        raise _BadInput(f"--min-pairs: must be >= 1, got {min_pairs}")
    if config is not None:
        naming = FrameNaming.from_config(config)
        root = args.output or Path(config.output.directory)
    else:
        naming = FrameNaming.from_carriers(
            data.x_names, data.y_names, camera_carrier=args.camera_carrier,
            tag_carrier=args.tag_carrier, carriers=data.carriers)
        root = args.output or Path(DEFAULT_OUTPUT)
        params = {"camera_carrier.frame": args.camera_carrier,
                  "tag_carrier.frame": args.tag_carrier,
                  "tags.unknown_scale": data.unknown_scale}
    params.update({"solver.mode": mode, "solver.min_pairs": int(min_pairs),
                   "solver.reject_outliers": bool(args.robust)})
    excluded = {f"({e.x}, {e.y})": f"{e.n} pairs < min_pairs={min_pairs}"
                for e in data.edges if e.n < min_pairs}
    try:
        problem = data.to_problem(min_pairs=min_pairs)
    except ValueError as exc:
        say(f"not enough data: {exc}")
        return EXIT_NO_SOLUTION
    paths = session_output_paths(new_output_dir(root))
    return _solve_and_write(say, problem, data, naming, paths, mode=mode, robust=args.robust,
                            excluded=excluded, config=params,
                            source={"type": "dataset", "path": str(args.file)},
                            force=False, report=args.report)


def _cmd_bag(args: argparse.Namespace, say: _Printer) -> int:
    from .data.rosbag import (
        CAMERA_INFO,
        IMAGE,
        POSE_STAMPED,
        TF_MESSAGE,
        TfTree,
        bag_topics,
        read_messages,
    )
    from .messages import stamp_to_ns
    from .session import CalibrationSession, MessageHandlers

    overrides: dict[str, Any] = {}
    if args.output is not None:
        overrides["output.directory"] = str(args.output)
    if args.mode is not None:
        overrides["solver.mode"] = args.mode
    config = _config_with_overrides(args.config, args.node_name, overrides)
    topics = bag_topics(args.bag)
    ps = config.pose_source

    routes: dict[str, tuple[str, str | None, str]] = {}
    for cam in config.cameras:
        routes[cam.image_topic] = ("image", cam.name, IMAGE)
        routes[cam.camera_info_topic] = ("info", cam.name, CAMERA_INFO)
    if ps.type == "topic":
        routes[ps.topic] = ("pose", None, POSE_STAMPED)
        if ps.topic not in topics:
            raise _BadInput(f"bag {str(args.bag)!r}: no pose topic {ps.topic} "
                            f"(pose_source.topic); topics: {sorted(topics)}")
    elif "/tf" not in topics and "/tf_static" not in topics:
        raise _BadInput(f"bag {str(args.bag)!r}: pose_source.type is 'tf' but the bag has no "
                        f"/tf or /tf_static; topics: {sorted(topics)}")
    for topic, (_, _, msgtype) in routes.items():
        if topic in topics and topics[topic][0] != msgtype:
            raise _BadInput(f"bag {str(args.bag)!r}: topic {topic} has type {topics[topic][0]}, "
                            f"expected {msgtype}")
    for tf_topic in ("/tf", "/tf_static"):
        if ps.type == "tf" and tf_topic in topics and topics[tf_topic][0] != TF_MESSAGE:
            raise _BadInput(f"bag {str(args.bag)!r}: {tf_topic} has type "
                            f"{topics[tf_topic][0]}, expected {TF_MESSAGE}")
    for cam in config.cameras:
        for topic in (cam.image_topic, cam.camera_info_topic):
            if topic not in topics:
                print(f"{PROG} bag: warning: camera {cam.name}: topic {topic} is not in the bag",
                      file=say.err)

    session = CalibrationSession(config)
    handlers = MessageHandlers(session)
    tf = None
    if ps.type == "tf":  # the whole recording's tf first: lookups never wait for later data
        tf = TfTree(max_gap_ns=int(round(config.sync.max_gap_s * 1e9)),
                    tolerance_ns=int(round(config.sync.extrapolation_tolerance_s * 1e9)))
        progress = _Progress(say.err, "reading /tf", enabled=not args.quiet)
        for m in read_messages(args.bag, ["/tf", "/tf_static"], on_progress=progress):
            tf.add_message(m.msg, static=m.topic == "/tf_static")
        progress.close()

    progress = _Progress(say.err, "reading bag", enabled=not args.quiet)
    for m in read_messages(args.bag, list(routes), on_progress=progress):
        kind, cam, _ = routes[m.topic]
        if kind == "pose":
            handlers.on_pose_stamped(m.msg)
        elif kind == "info":
            handlers.on_camera_info(cam, m.msg)
        else:
            T = None
            if tf is not None:
                try:
                    T = tf.lookup(ps.parent, ps.child, stamp_to_ns(m.msg.header.stamp))
                except LookupError:
                    session.record("no_tf_at_stamp")
                    continue
                except (ValueError, TypeError, AttributeError):
                    pass  # a bad stamp: on_image rejects and counts it
            handlers.on_image(cam, m.msg, T)
    progress.close()
    counters = session.counters()
    say("input: " + ", ".join(f"{k}={v}" for k, v in sorted(counters.items()) if v))
    code, _ = _session_outcome(say, session, args.report)
    return code


def demo_parameters(rig, *, output_directory: str, mode: str = "fast") -> dict[str, Any]:
    """Flat calibrator parameters for a simulated rig (the values of ``config/demo.yaml``, with
    the rig's cameras and tags): motion-capture ``PoseStamped`` ``world -> rig``, cameras on
    ``rig``, tags in ``world``."""
    from .simulation import DEMO_POSE_TOPIC, DEMO_RIG_FRAME, DEMO_WORLD_FRAME, demo_camera_topics

    flat: dict[str, Any] = {
        "camera_carrier.frame": DEMO_RIG_FRAME, "camera_carrier.moving": True,
        "tag_carrier.frame": DEMO_WORLD_FRAME, "tag_carrier.moving": False,
        "pose_source.type": "topic", "pose_source.topic": DEMO_POSE_TOPIC,
        "pose_source.parent": DEMO_WORLD_FRAME, "pose_source.child": DEMO_RIG_FRAME,
        "cameras.names": list(rig.cameras),
        "tags.family": rig.family, "tags.ids": list(rig.tag_ids),
        "tags.default_size": float(rig.tag_size),
        "noise.sigma": 0.005, "noise.kappa": 400.0, "noise.from_reprojection": False,
        "sync.max_gap_s": 0.1, "sync.extrapolation_tolerance_s": 0.01,
        "sync.image_queue_size": 6,
        "keyframe.min_rotation_rad": 0.05, "keyframe.min_translation_m": 0.02,
        "keyframe.max_pairs_per_edge": 200,
        "solver.mode": mode, "solver.min_pairs": 3, "solver.reject_outliers": False,
        "output.directory": output_directory,
    }
    for cam in rig.cameras:
        image_topic, info_topic = demo_camera_topics(cam)
        flat[f"cameras.{cam}.image_topic"] = image_topic
        flat[f"cameras.{cam}.camera_info_topic"] = info_topic
        flat[f"cameras.{cam}.frame"] = f"{cam}_optical"
    return flat


def _cmd_demo(args: argparse.Namespace, say: _Printer) -> int:
    from .config import CalibratorConfig
    from .session import CalibrationSession
    from .simulation import demo_rig, simulated_stream

    if args.cameras < 1 or args.tags < 1:
        raise _BadInput(f"--cameras/--tags: must be >= 1, got {args.cameras}/{args.tags}")
    _check_positive("--seconds", args.seconds)
    _check_positive("--rate", args.rate)
    t0 = time.perf_counter()
    try:
        rig = demo_rig(args.cameras, args.tags)
    except ValueError as exc:
        raise _BadInput(str(exc)) from None
    config = CalibratorConfig.from_parameters(
        demo_parameters(rig, output_directory=str(args.output), mode=args.mode))
    session = CalibrationSession(config)
    for cam in rig.cameras:
        session.set_camera_info(cam, rig.intrinsics[cam])
    rng = np.random.default_rng(args.seed)
    n_images = 0
    for stamp, cam, data in simulated_stream(rig, rng, seconds=args.seconds,
                                             image_rate_hz=args.rate):
        if cam is None:
            session.add_pose(stamp, data, source=config.pose_source.parent)
        else:
            session.add_image(cam, stamp, data)
            n_images += 1
    counters = session.counters()
    say(f"demo: {len(rig.cameras)} cameras, {len(rig.tag_ids)} tags, {args.seconds:g} s, "
        f"{n_images} images rendered and searched, {counters.get('pairs_kept', 0)} pairs kept "
        f"({time.perf_counter() - t0:.1f} s)")
    code, outcome = _session_outcome(say, session, args.report)
    if outcome.result is None:
        return code
    result = outcome.result
    X_true = np.array([rig.T_world_tag[int(n[len("tag_"):])] for n in result.x_names])
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


def _cmd_report(args: argparse.Namespace, say: _Printer) -> int:
    from .data.dataset import Dataset
    from .data.results import load_result

    doc = load_result(args.result)
    paths = _output_paths_for(args.result)
    data_path = args.dataset or paths.dataset
    if not data_path.exists():
        raise _BadInput(f"{data_path}: no data set (give it with --dataset)")
    min_pairs = int((doc.get("config") or {}).get("solver.min_pairs", 1))
    problem = Dataset.load(data_path).to_problem(min_pairs=min_pairs)
    _write_report(say, doc, problem, paths)
    return EXIT_CERTIFIED


_COMMANDS = {
    "csv": _cmd_csv,
    "bag": _cmd_bag,
    "dataset": _cmd_dataset,
    "demo": _cmd_demo,
    "report": _cmd_report,
}


def main(argv: Sequence[str] | None = None, *, stdout: TextIO | None = None,
         stderr: TextIO | None = None) -> int:
    """Run ``rwhec-calibrate`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code.

    Bad input (unreadable or malformed files, invalid configuration, existing outputs without
    ``--force``) is reported on stderr as ``rwhec-calibrate <command>: error: <message>`` with
    exit code 2, never a traceback.
    """
    out = stdout if stdout is not None else sys.stdout
    err = stderr if stderr is not None else sys.stderr
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, usage errors (argparse printed them)
        return int(exc.code or 0)
    say = _Printer(out, err)
    try:
        return _COMMANDS[args.command](args, say)
    except (_BadInput, ValueError, FileExistsError, FileNotFoundError, IsADirectoryError,
            PermissionError) as exc:
        print(f"{PROG} {args.command}: error: {exc}", file=err)
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())

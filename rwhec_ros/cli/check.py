"""``check``: is a stored calibration still right? (bring-up, :mod:`rwhec_ros.session.bringup`)

``rwhec-calibrate check --reference result.yaml BAG_OR_DIR`` reads the new data as ``bag``
(a rosbag2 recording, with ``--config``), ``samples`` (a folder of stop-and-go views) or
``dataset`` (a ``dataset.yaml``) read them -- the same session, the same pairs -- and checks them
against the reference (a result.yaml, check.yaml, frames.yaml or URDF). It prints the answer
(``CHECK CONSISTENT`` / ``CHECK MOVED: cam1 MOVED by ...`` / ``CHECK NOT ENOUGH DATA YET``, the
verdict, one line per camera) and writes ``check.yaml`` and the reference frames with the moved
ones re-estimated (launch file, URDF snippet, frames.yaml) plus the data set into ``-o DIR``
(default: a new ``check_<UTC stamp>`` directory under the output root).

Exit codes: 0 every camera consistent (and the verdict usable), :data:`EXIT_MOVED` (5) a camera
moved, :data:`EXIT_UNDECIDED` (6) not enough data yet to decide, 4 consistent but the verdict is
unusable, and the CLI's others (2 bad input, 3 no solution).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import describe_os_error
from .common import (
    EXIT_MOVED,
    EXIT_NO_SOLUTION,
    EXIT_OK,
    EXIT_UNDECIDED,
    EXIT_UNUSABLE,
    BadInput,
    Printer,
    config_from_parameters,
    output_dir,
    read_config,
    solver_overrides,
)

__all__ = ["cmd_check", "check_exit_code", "input_kind", "add_check_parser"]


def check_exit_code(report) -> int:
    """0 consistent (verdict usable), 5 moved, 6 undecided, 4 consistent but unusable."""
    if report.status == "moved":
        return EXIT_MOVED
    if report.status == "undecided":
        return EXIT_UNDECIDED
    if report.verdict is not None and not report.verdict.usable:
        return EXIT_UNUSABLE
    return EXIT_OK


def input_kind(path: Path) -> str:
    """``bag`` (a rosbag2 directory or its .mcap/.db3 file), ``dataset`` (a YAML file, or a
    directory with a dataset.yaml and no metadata.yaml) or ``samples`` (anything else)."""
    path = Path(path)
    if not path.exists():
        raise BadInput(f"{str(path)!r}: no such file or directory")
    if path.is_dir():
        if (path / "metadata.yaml").exists():
            return "bag"
        if (path / "dataset.yaml").exists() and not (path / "samples.yaml").exists():
            return "dataset"
        return "samples"
    if path.suffix in (".mcap", ".db3"):
        return "bag"
    if path.suffix in (".yaml", ".yml"):
        try:
            head = path.read_text(encoding="utf-8", errors="replace")[:4000]
        except OSError as exc:
            raise BadInput(f"{str(path)!r}: cannot read ({describe_os_error(exc)})") from None
        return "dataset" if "rwhec_ros.dataset" in head else "samples"
    return "samples"


def add_check_parser(sub, add_output, add_config) -> argparse.ArgumentParser:
    """The ``check`` subcommand's parser (used by :func:`rwhec_ros.cli.parser.build_parser`)."""
    p = sub.add_parser("check", help="bring-up: check new data against a stored calibration, "
                       "name the camera that moved, re-estimate only it")
    p.add_argument("input", metavar="BAG_OR_DIR", type=Path,
                   help="the new data: a rosbag2 recording (with --config), a folder of "
                        "stop-and-go views (as samples) or a dataset.yaml")
    p.add_argument("--reference", type=Path, required=True, metavar="FILE",
                   help="the stored calibration: result.yaml, check.yaml, frames.yaml or a "
                        "URDF/xacro with the calibrated frames as fixed joints (required)")
    p.add_argument("--tolerance-mm", type=float, default=None,
                   help="accepted change of a camera's translation [mm] (default: the "
                        "configuration's check.tolerance_translation_m, else 2)")
    p.add_argument("--tolerance-deg", type=float, default=None,
                   help="accepted change of a camera's rotation [deg] (default: the "
                        "configuration's check.tolerance_rotation_deg, else 0.2)")
    p.add_argument("--false-alarm-rate", type=float, default=None,
                   help="probability of any wrong camera decision (default: the "
                        "configuration's check.false_alarm_rate, else 0.01)")
    p.add_argument("--hold", choices=("none", "targets"), default=None,
                   help="what holds the reference while a camera is tested: none (the pose "
                        "stream; targets tested too) or targets (tags fixed and untouched) "
                        "(default: the configuration's check.hold, else none)")
    p.add_argument("--noise", choices=("data", "stated"), default=None,
                   help="noise of the test: from the residuals per camera, or as stated "
                        "(default: the configuration's check.noise, else data)")
    add_output(p, "directory that receives check.yaml, static_transforms.launch.py, "
                  "calibration.urdf.xacro, frames.yaml and dataset.yaml; existing files are "
                  "refused unless --force (default: a new check_<UTC stamp> directory under "
                  "the configuration's output.directory, else rwhec_output/)")
    add_config(p, "the node's parameter file: required for a bag; for views and data sets "
                  "as samples and dataset take it (default: none)")
    p.add_argument("--mode", choices=("fast", "sdp", "local"), default=None,
                   help="solver mode (default: the configuration's solver.mode, else fast)")
    p.add_argument("--min-pairs", type=int, default=None, metavar="N",
                   help="leave out edges with fewer pairs (default: the configuration's "
                        "solver.min_pairs, else 3)")
    p.add_argument("--intrinsics", action="append", default=None, metavar="[CAMERA=]FILE",
                   help="views: intrinsics of a camera, as for samples (default: the data's)")
    p.add_argument("--layout", default="auto",
                   choices=("auto", "manifest", "industrial_calibration",
                            "camera_calibration_toolkit"),
                   help="views: how the folder is laid out (default: %(default)s)")
    group = p.add_mutually_exclusive_group()
    group.add_argument("--eye-in-hand", action="store_true",
                       help="views: the cameras ride on the flange (default: the data's mount)")
    group.add_argument("--eye-to-hand", action="store_true",
                       help="views: the cameras are fixed (default: the data's mount)")
    p.add_argument("-q", "--quiet", action="store_true",
                   help="no progress output on stderr (default: off)")
    p.set_defaults(robust=False, prior=None, folds=None, no_guidance=False, report=False)
    return p


def _options(args: argparse.Namespace, config):
    """The :class:`~rwhec_ros.session.bringup.CheckOptions` of the command line over the
    configuration's ``check.*`` (one look: the CLI answers once)."""
    from ..config.sections import CheckConfig
    from ..core.analysis.change import ChangeTolerance
    from ..session.bringup import CheckOptions

    c = config.check if config is not None else CheckConfig()
    t_m = c.tolerance_translation_m if args.tolerance_mm is None else 1e-3 * args.tolerance_mm
    r_deg = c.tolerance_rotation_deg if args.tolerance_deg is None else args.tolerance_deg
    rate = c.false_alarm_rate if args.false_alarm_rate is None else args.false_alarm_rate
    mode = config.solver.mode if config is not None else "fast"
    if args.mode is not None:
        mode = args.mode
    try:
        return CheckOptions(tolerance=ChangeTolerance(t_m, r_deg), false_alarm_rate=rate,
                            hold=args.hold or c.hold, noise=args.noise or c.noise, mode=mode)
    except ValueError as exc:
        raise BadInput(str(exc)) from None


def _reference(args: argparse.Namespace, config, naming):
    from ..data.reference import read_reference
    from ..session.bringup import reference_lookup_names

    names = None
    if config is not None:
        names = reference_lookup_names(config)
    elif naming is not None:
        names = {n: (p, [c, n]) for n, (p, c) in naming.frames.items()}
    try:
        return read_reference(args.reference, names)
    except ValueError as exc:
        raise BadInput(f"--reference: {exc}") from None


def run_and_write(args: argparse.Namespace, say: Printer, problem, naming, config,
                  save_dataset, source: dict, inputs=()) -> int:
    """Check ``problem`` against ``--reference``, print the answer and write the outputs
    (``save_dataset(path)`` writes the data set and returns its path)."""
    from ..data.results import new_output_dir
    from ..session.bringup import run_check
    from ..session.bringup_outputs import CHECK_FILES, check_message, write_check_outputs
    from ..session.paths import plain_output_root
    from ..session.solving import verdict_options

    options = _options(args, config)
    reference = _reference(args, config, naming)
    cams = tuple(naming.y_names)
    carriers = (naming.frames[cams[0]][0] if cams else "the camera carrier",
                next((naming.frames[n][0] for n in naming.x_names), "the tag carrier"))
    for name, parent in reference.parents.items():
        want = naming.frames.get(name, ("", ""))[0]
        if parent and want and parent != want:
            raise BadInput(f"--reference: {name} is in {parent} there but in {want} here "
                           "(the carriers of the reference and of the data differ)")
    say.progress(f"checking {problem.n_measurements} pairs on {len(problem.edges)} edges "
                 f"against {reference.source}")
    try:
        report = run_check(problem, reference, options, expected_cameras=cams,
                           thresholds=verdict_options(None if config is None else
                                                      config.verdict), carriers=carriers)
    except ValueError as exc:
        raise BadInput(str(exc)) from None
    out = getattr(args, "check_output", None)
    if out is None:
        root = plain_output_root(config.output.directory if config is not None else "")
        out = new_output_dir(root, "check")
    else:
        existing = [str(Path(out) / n) for n in CHECK_FILES if (Path(out) / n).exists()]
        if existing and not args.force:
            raise BadInput(f"refusing to overwrite existing file(s) {existing} (use --force "
                           "to overwrite)")
    try:
        files = write_check_outputs(Path(out), report, naming, force=args.force, source=source,
                                    config=None if config is None else config.to_parameters())
        files["dataset"] = str(save_dataset(Path(out) / "dataset.yaml"))
    except OSError as exc:
        raise BadInput(f"cannot write the outputs: {describe_os_error(exc)}") from None
    say.summary(check_message(report))
    for line in inputs:
        say(line)
    say.files(files)
    return check_exit_code(report)


def _finish_session(say: Printer, session, run, *, report: bool, inputs=(),
                    args: argparse.Namespace) -> tuple[int, None]:
    """In place of ``calibrate_session`` for ``bag`` and ``samples``: the check of the
    session's pairs (written with the check's outputs; ``run``, the reading's
    :class:`~rwhec_ros.cli.run.Run`, keeps them only when the reading is interrupted)."""
    from ..data.results import FrameNaming
    from ..session.bringup import session_problem

    problem, _, why = session_problem(session)
    if problem is None:
        say(f"no solution: {why}")
        return EXIT_NO_SOLUTION, None
    config = session.config
    return run_and_write(args, say, problem, FrameNaming.from_config(config), config,
                         session.save_dataset, {"type": args.check_kind, "path": str(args.input)},
                         inputs), None


def cmd_check(args: argparse.Namespace, say: Printer) -> int:
    from .replay import cmd_bag
    from .samples import cmd_samples

    if args.min_pairs is not None and args.min_pairs < 1:
        raise BadInput(f"--min-pairs: must be >= 1, got {args.min_pairs}")
    args.check_output = output_dir(args)
    args.output = None  # the reading command writes nothing; the check writes into check_output
    kind = input_kind(args.input)
    args.check_kind = kind

    def finish(say_, session, run, *, report, inputs=()):
        return _finish_session(say_, session, run, report=report, inputs=inputs, args=args)

    args.finish = finish
    if kind == "bag":
        if args.config is None:
            raise BadInput("a bag needs --config FILE (the node's parameter file)")
        args.bag = args.input
        return cmd_bag(args, say)
    if kind == "samples":
        args.path = args.input
        return cmd_samples(args, say)
    return _check_dataset(args, say)


def _check_dataset(args: argparse.Namespace, say: Printer) -> int:
    from ..data.dataset import Dataset
    from ..data.results import FrameNaming

    path = args.input / "dataset.yaml" if args.input.is_dir() else args.input
    config = read_config(args, solver_overrides(args))
    data = Dataset.load(path)
    if config is None and data.metadata.get("config"):
        flat = dict(data.metadata["config"])
        flat.update(solver_overrides(args))
        config = config_from_parameters(flat, f"{path}: metadata.config")
    if config is not None:
        naming = FrameNaming.from_config(config)
        min_pairs = config.solver.min_pairs
    else:
        naming = FrameNaming.from_carriers(data.x_names, data.y_names, camera_carrier="rig",
                                           tag_carrier="world", carriers=data.carriers)
        min_pairs = args.min_pairs or 3
    try:
        problem = data.to_problem(min_pairs=min_pairs)
    except ValueError as exc:
        say(f"no solution: not enough data: {exc}")
        return EXIT_NO_SOLUTION
    return run_and_write(args, say, problem, naming, config, data.save,
                         {"type": "dataset", "path": str(path)})

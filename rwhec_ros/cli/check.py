"""``check``: is a stored calibration still right? (bring-up, :mod:`rwhec_ros.session.bringup`)

``rwhec-calibrate check --reference result.yaml BAG_OR_DIR`` reads the new data as ``bag``
(a rosbag2 recording, with ``--config``), ``samples`` (a folder of stop-and-go views) or
``dataset`` (a ``dataset.yaml``) read them -- the same session, the same pairs -- and checks them
against the reference (a result.yaml, check.yaml, frames.yaml or URDF). It prints the answer
(``CHECK CONSISTENT`` / ``CHECK MOVED: cam1 MOVED by ...`` / ``CHECK NOT ENOUGH DATA YET``, the
verdict, one line per camera) and writes ``check.yaml`` and the reference frames with the moved
ones re-estimated (launch file, URDF snippet, frames.yaml) plus the data set into ``-o DIR``
(default: a new ``check_<UTC stamp>`` directory under the output root).

A check is a :class:`~rwhec_ros.cli.run.Run` like any solving subcommand: the phases reading
(the bag, views or data set, and the reference), solving (the test's solve), analysing (the
change tests, the re-estimate of what moved, the verdict) and writing (the files staged whole,
``check.yaml`` last); the data set of the pairs gathered is kept in the output directory as soon
as reading ends; ``--force`` removes the earlier run's files (a calibration's or a check's) with
that first write; Ctrl-C and SIGTERM end it in one line with the kept data set and the ``check
DATASET --reference ...`` command that resumes it (exit 130, 143). A ``--reference`` that is one
of the files the check replaces in ``-o DIR`` is refused before any work.

Exit codes: 0 every camera consistent (and the verdict usable), :data:`EXIT_MOVED` (5) a camera
moved, :data:`EXIT_UNDECIDED` (6) not enough data yet to decide, 4 consistent but the verdict is
unusable, and the CLI's others (2 bad input, 3 no solution, 130/143 interrupted).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import describe_os_error
from .common import (
    EXIT_MOVED,
    EXIT_OK,
    EXIT_UNDECIDED,
    EXIT_UNUSABLE,
    BadInput,
    NoSolution,
    Printer,
    output_dir,
    output_paths,
    read_config,
    recorded_config,
    solver_overrides,
)
from .solving import _kept, _kept_files

__all__ = ["cmd_check", "check_exit_code", "input_kind", "add_check_parser", "resume_options"]


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
                  "calibration.urdf.xacro, frames.yaml and dataset.yaml; existing files (a "
                  "calibration's or a check's) are refused before any work, --force removes "
                  "them (default: a new check_<UTC stamp> directory under the configuration's "
                  "output.directory, else rwhec_output/)")
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


def resume_options(args: argparse.Namespace) -> list[str]:
    """The options of this check that ``check DATASET`` needs to check the kept data set the
    same way: the reference and the options given (the data set holds the configuration; a
    data set's own ``--config`` is passed on)."""
    out = ["--reference", str(args.reference)]
    for flag, value in (("--tolerance-mm", args.tolerance_mm),
                        ("--tolerance-deg", args.tolerance_deg),
                        ("--false-alarm-rate", args.false_alarm_rate), ("--hold", args.hold),
                        ("--noise", args.noise), ("--mode", args.mode),
                        ("--min-pairs", args.min_pairs)):
        if value is not None:
            out += [flag, str(value)]
    if getattr(args, "check_kind", "") == "dataset" and args.config is not None:
        out += ["--config", str(args.config)]
        if args.node_name is not None:
            out += ["--node-name", args.node_name]
    return out


def _run_as(args: argparse.Namespace) -> dict:
    """The :class:`~rwhec_ros.cli.run.Run` keywords of a check: a ``check_<UTC stamp>``
    directory without ``-o``, and ``check`` as the resume command."""
    return {"kind": "check", "resume_subcommand": "check", "resume_options": resume_options(args)}


def run_and_write(args: argparse.Namespace, say: Printer, problem, dataset, naming, config,
                  run, source: dict, inputs=()) -> int:
    """Check ``problem`` against ``--reference`` in the phases of ``run`` (a
    :class:`~rwhec_ros.cli.run.Run`, which kept ``dataset`` already), print the answer and
    write the outputs into the run's directory."""
    from ..session.bringup import run_check
    from ..session.bringup_outputs import check_message, write_check_outputs
    from ..session.solving import solver_alternatives, verdict_options

    options = _options(args, config)
    reference = _reference(args, config, naming)
    cams = tuple(naming.y_names)
    carriers = (naming.frames[cams[0]][0] if cams else "the camera carrier",
                next((naming.frames[n][0] for n in naming.x_names), "the tag carrier"))
    for name, parent in reference.parents.items():
        want = naming.frames.get(name, ("", ""))[0]
        if parent and want and parent != want:
            raise BadInput(f"--reference: {name} is in {parent} there but in {want} here "
                           "(the carriers of the reference and of the data differ)"
                           + _kept(run))
    run.enter("solving")
    say.progress(f"checking {problem.n_measurements} pairs on {len(problem.edges)} edges "
                 f"against {reference.source}")
    try:
        report = run_check(problem, reference, options, expected_cameras=cams,
                           thresholds=verdict_options(None if config is None else
                                                      config.verdict), carriers=carriers,
                           on_phase=run.enter)
    except ValueError as exc:
        raise BadInput(f"{exc}{_kept(run)}") from None
    except Exception as exc:  # noqa: BLE001 - reported, exit code 3
        raise NoSolution(
            f"the check's solve stopped with an error in mode {options.mode} "
            f"({type(exc).__name__}: {str(exc).split('. ')[0]}); "
            + solver_alternatives(options.mode, True) + _kept(run)) from None
    run.enter("writing")
    try:
        out = run.output_paths().result.parent
        files = write_check_outputs(out, report, naming, force=True, source=source,
                                    config=None if config is None else config.to_parameters())
    except OSError as exc:
        where = "" if run.paths is None else f" into {run.paths.result.parent}"
        raise BadInput(f"cannot write the outputs{where}: {describe_os_error(exc)}"
                       + _kept(run)) from None
    files.update(_kept_files(run, dataset))
    say.summary(check_message(report))
    for line in inputs:
        say(line)
    say.files(files)
    return check_exit_code(report)


def _finish_session(say: Printer, session, run, *, report: bool, inputs=(),
                    args: argparse.Namespace) -> tuple[int, None]:
    """In place of ``calibrate_session`` for ``bag`` and ``samples``: the pairs kept into the
    run's directory, then the check of them."""
    from ..data.results import FrameNaming
    from ..session.bringup import session_problem

    dataset = session.dataset()
    run.keep(dataset)
    problem, _, why = session_problem(session)
    if problem is None:
        for line in inputs:  # what was read (stdout), the reason on stderr
            say(line)
        raise NoSolution(why + _kept(run))
    config = session.config
    return run_and_write(args, say, problem, dataset, FrameNaming.from_config(config), config,
                         run, {"type": args.check_kind, "path": str(args.input)}, inputs), None


def _refuse_reference_in_output(args: argparse.Namespace) -> None:
    """``--reference`` must exist, and not be a file the check replaces in ``-o DIR`` (with
    ``--force`` it would be removed before it is read)."""
    from ..data.results import session_output_paths
    from .run import run_files

    if not args.reference.is_file():
        raise BadInput(f"--reference {str(args.reference)!r}: no such file")
    out = output_dir(args)
    if out is None:
        return
    ref = args.reference.resolve()
    if ref in {p.resolve() for p in run_files(session_output_paths(out))}:
        raise BadInput(f"--reference {str(args.reference)!r} is in -o {str(out)!r}, whose "
                       "outputs the check replaces; give another -o DIR")


def cmd_check(args: argparse.Namespace, say: Printer) -> int:
    from .replay import cmd_bag
    from .samples import cmd_samples

    if args.min_pairs is not None and args.min_pairs < 1:
        raise BadInput(f"--min-pairs: must be >= 1, got {args.min_pairs}")
    kind = input_kind(args.input)
    args.check_kind = kind
    _refuse_reference_in_output(args)

    def finish(say_, session, run, *, report, inputs=()):
        return _finish_session(say_, session, run, report=report, inputs=inputs, args=args)

    args.finish = finish
    args.run_as = _run_as(args)
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
    from ..session.paths import plain_output_root
    from .run import Run

    path = args.input / "dataset.yaml" if args.input.is_dir() else args.input
    config = read_config(args, solver_overrides(args))
    data = Dataset.load(path)
    if config is None:
        config = recorded_config(data.metadata, f"{path}: metadata.config", say, "check",
                                 solver_overrides(args))[0]
    root = plain_output_root(config.output.directory if config is not None else "")
    paths = output_paths(args, report=False, root=root)  # refuse early, before any work
    if config is not None:
        naming = FrameNaming.from_config(config)
        min_pairs = config.solver.min_pairs
    else:
        naming = FrameNaming.from_carriers(data.x_names, data.y_names, camera_carrier="rig",
                                           tag_carrier="world", carriers=data.carriers)
        min_pairs = args.min_pairs or 3
    run = Run("check", say, paths, root, force=args.force, **_run_as(args))
    try:
        run.enter("reading")  # read already: the pause is for the tests of every phase
        run.keep(data)
        try:
            problem = data.to_problem(min_pairs=min_pairs)
        except ValueError as exc:
            raise NoSolution(f"not enough data: {exc}{_kept(run)}") from None
        return run_and_write(args, say, problem, data, naming, config, run,
                             {"type": "dataset", "path": str(path)})
    except KeyboardInterrupt as exc:
        raise run.interrupted(exc) from None

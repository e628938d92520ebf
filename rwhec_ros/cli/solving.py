"""The solve of a CLI run and its outputs: :func:`solve_and_write` (``csv``, ``dataset``,
``poses``: a problem solved, assessed and written as the session does) and
:func:`calibrate_session` (``bag``, ``demo``, ``samples``: a session's ``calibrate()``), both into
the directory of a :class:`~rwhec_ros.cli.run.Run`."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from ..errors import describe_os_error
from .common import (
    BadInput,
    NoSolution,
    Printer,
    SolveSettings,
    exit_code,
    remove_stale_reports,
    write_report,
)

__all__ = ["solve_and_write", "calibrate_session", "input_line"]


def solve_and_write(
    say: Printer,
    problem,
    dataset,
    naming,
    run,
    settings: SolveSettings,
    *,
    excluded: dict[str, str],
    config: dict[str, Any],
    source: dict[str, Any],
    report: bool,
    verdict_config=None,
    publish_unusable: bool = False,
    noise_given: str = "start",
) -> int:
    """Solve ``problem``, assess it and write the outputs as the session does (``csv`` and
    ``dataset``) into the directory of ``run`` (:class:`~rwhec_ros.cli.run.Run`), which kept
    ``dataset`` already. The verdict's thresholds come from ``verdict_config`` (a
    configuration's ``verdict`` section, else the defaults); the launch file holds the usable
    frames only unless ``publish_unusable``. The noise is estimated from the data unless
    ``settings.noise_estimate`` is off; ``noise_given`` says what the problem's
    ``sigma``/``kappa`` are (stated by the user, from the reprojection, start values)."""
    from ..data.corners import corner_data
    from ..data.fingerprint import dataset_fingerprint
    from ..data.results import dump_document, result_document, solved_pairs, write_outputs
    from ..session import static_transforms_launch, summary
    from ..session.accuracy import AccuracyOptions
    from ..session.outputs import description_texts, launch_header, publishable
    from ..session.solving import solve_and_assess, solver_alternatives, verdict_options
    from ..session.time_offsets import add_offset_reasons, correct_time_offsets, offsets_then_assess

    frames = list(dataset.y_names) + list(dataset.x_names)
    for f, a, x in settings.priors:
        if f not in frames:
            raise BadInput(f"--prior {f}.{a}={x:g}: no frame {f!r} in the data; frames: "
                           f"{frames}")
    run.enter("solving")
    say.progress(f"solving: {problem.n_measurements} pairs on {len(problem.edges)} edges, mode "
                 f"{settings.mode}" + (", outlier rejection" if settings.robust else ""))
    cam_carrier = next((naming.frames[n][0] for n in naming.y_names if n in naming.frames), "")
    tag_carrier = next((naming.frames[n][0] for n in naming.x_names if n in naming.frames), "")

    kinds = _target_kinds(config)

    def estimate(p, d):
        return correct_time_offsets(
            p, d, config, mode=settings.mode, priors=settings.priors,
            unobservable_std_m=settings.unobservable_std_m, min_scale=settings.min_scale,
            reject_outliers=settings.robust, noise=settings.noise_options(noise_given, kinds))

    def assess(problem, dataset):
        return solve_and_assess(
            problem, mode=settings.mode, reject_outliers=settings.robust,
            priors=settings.priors, unobservable_std_m=settings.unobservable_std_m,
            min_scale=settings.min_scale, sdp_backend=settings.sdp_backend,
            thresholds=verdict_options(verdict_config),
            expected_x=naming.x_names, expected_y=naming.y_names, excluded=excluded,
            carriers=(cam_carrier or "the camera carrier", tag_carrier or "the tag carrier"),
            accuracy=AccuracyOptions(folds=settings.folds, guidance=settings.guidance,
                                     moving=_moving(config)),
            corners=corner_data(dataset), noise=settings.noise_options(noise_given, kinds),
            on_phase=run.enter, refine=settings.refine)

    try:
        problem, dataset, offsets, solved = offsets_then_assess(problem, dataset, estimate,
                                                                assess)
    except Exception as exc:  # noqa: BLE001 - reported, exit code 3
        raise NoSolution(
            f"the solver stopped with an error in mode {settings.mode} ({type(exc).__name__}: "
            f"{str(exc).split('. ')[0]}); "
            + solver_alternatives(settings.mode, settings.robust)
            + _kept(run)) from None
    result, verdict = solved.result, solved.verdict
    add_offset_reasons(verdict, offsets)
    excluded.update(solved.dropped)
    ident = solved.identifiability
    doc = result_document(result, naming, excluded=excluded,
                          identifiability=solved.identifiability_dict, config=config,
                          source=source, verdict=verdict, accuracy=solved.accuracy,
                          rejected_pairs=solved.rejected_pairs,
                          fingerprint=dataset_fingerprint(dataset))
    doc = offsets.into(doc)
    names = list(result.y_names) + list(result.x_names)
    transforms, left_out = publishable(naming.transforms(result), names, verdict,
                                       publish_unusable=publish_unusable)
    header = launch_header(result, verdict, left_out,
                           f"from {source.get('type', '?')} {source.get('path', '')}")
    launch = static_transforms_launch(transforms, header=header)
    urdf, frames_text = description_texts(transforms, header)
    run.enter("writing")
    try:
        paths = run.output_paths()
        # the data set is on disk already (Run.keep): the rest, result.yaml last
        files = write_outputs(paths, result_yaml=dump_document(doc), launch_text=launch,
                              force=True, urdf_text=urdf, frames_text=frames_text)
    except OSError as exc:
        where = "" if run.paths is None else f" into {run.paths.result.parent}"
        raise BadInput(f"cannot write the outputs{where}: {describe_os_error(exc)}"
                       + _kept(run)) from None
    files.update(_kept_files(run, dataset))
    if not report:
        remove_stale_reports(say, paths)
    say.summary("\n".join([summary(result, solved.problem, excluded, naming, verdict,
                                    solved.accuracy), *offsets.lines()]))
    say.files(files)
    if report:  # the pairs solved, with their given noise (the report applies the estimate's)
        pairs = solved.problem if solved.noise is None else solved_pairs(doc, problem)
        write_report(say, doc, pairs, paths.report_png, paths.report_html, ident)
    return exit_code(verdict)


def _kept(run) -> str:
    """``; the N pairs gathered are in ...; resume with: ...`` for an error message."""
    words = run.kept_words()
    return f"; {words}" if words else ""


def _kept_files(run, dataset) -> dict[str, str]:
    if run.kept is None:
        return {}
    files = {"dataset": str(run.kept)}
    if dataset.writes_npz():
        files["dataset_arrays"] = str(run.kept.with_suffix(".npz"))
    return files


def _target_kinds(parameters: Mapping[str, Any]) -> tuple[tuple[str, str], ...]:
    """The targets' kinds of a flat configuration (``()`` without targets: pose pairs from
    files)."""
    from ..config import CalibratorConfig

    if not (parameters.get("tags.ids") or parameters.get("targets.names")):
        return ()
    try:
        return CalibratorConfig.from_parameters(parameters).target_kinds
    except ValueError:  # a partial configuration (data-set metadata of an older version)
        return ()


def _moving(parameters: Mapping[str, Any]) -> str:
    """The carrier the guidance moves: ``"x"`` when the configuration says only the tag carrier
    moves, else ``"y"`` (the camera carrier)."""
    tag = bool(parameters.get("tag_carrier.moving", False))
    cam = bool(parameters.get("camera_carrier.moving", not tag))
    return "x" if tag and not cam else "y"


def input_line(counters: dict[str, int]) -> str:
    """``input: <counter>=<n>, ...``: the session's non-zero counters, sorted; the
    accumulator's ``pairs:<x>`` left out where the session's ``pairs_<x>`` says the same."""
    shown = {k: v for k, v in counters.items() if v and not (
        k.startswith("pairs:") and counters.get("pairs_" + k.removeprefix("pairs:")) == v)}
    return "input: " + ", ".join(f"{k}={v}" for k, v in sorted(shown.items()))


def calibrate_session(say: Printer, session, run, *, report: bool,
                      inputs: Sequence[str] = ()) -> tuple[int, Any]:
    """``session.calibrate()`` into the directory of ``run`` (:class:`~rwhec_ros.cli.run.Run`;
    the pairs are kept there first), printed: the summary (the verdict first), then the lines
    ``inputs`` (what was read), then the files; the report from the written data set and the
    result (``bag`` and ``demo``). No solution or outputs that cannot be written: one line
    (:class:`NoSolution`, :class:`BadInput`) naming the data set kept and how to resume. An
    ``input: `` line is written again from the session's counters after the solve."""
    from ..data.dataset import Dataset
    from ..data.results import session_output_paths, solved_pairs
    from ..session.outcomes import too_few_pairs_words

    solver = session.config.solver
    dataset = session.dataset()
    run.keep(dataset)
    run.enter("solving")
    held = 0 if dataset is None else dataset.n_pairs  # (pairs_kept counts those replaced too)
    say.progress(f"solving: {held} pairs kept, mode "
                 f"{solver.mode}" + (", outlier rejection" if solver.reject_outliers else ""))
    out = None if run.paths is None else run.paths.result.parent
    outcome = session.calibrate(out, force=True, on_phase=run.enter)
    # the counters as the solve left them (its second look may recover views)
    inputs = [input_line(session.counters()) if line.startswith("input: ") else line
              for line in inputs]
    if not outcome.success:
        for line in inputs:  # what was read (stdout), the reason on stderr
            say(line)
        counts = {(r["x"], r["y"]): r["pairs"] for r in session.diagnostics()}
        why = outcome.message
        if counts and outcome.result is None and why.startswith("not enough data"):
            why = too_few_pairs_words(counts, solver.min_pairs, "--min-pairs")
        elif why.startswith("the solver stopped"):
            why = why.replace("solver.mode", "--mode").replace("solver.reject_outliers",
                                                               "--robust")
        raise NoSolution(why.replace("; all data kept:", ";") + _kept(run))
    if outcome.write_error:  # nothing printed as if it had been written
        where = "" if run.paths is None else f" into {run.paths.result.parent}"
        raise BadInput(f"cannot write the outputs{where}: {outcome.write_error}" + _kept(run))
    say.summary(outcome.message)
    for line in inputs:
        say(line)
    say.files(outcome.files)
    if not report and "result" in outcome.files:
        remove_stale_reports(say, session_output_paths(Path(outcome.files["result"]).parent))
    if report and "dataset" in outcome.files and "result" in outcome.files:
        written = session_output_paths(Path(outcome.files["result"]).parent)
        # PyYAML's C loader where it has one: the same mapping as safe_load, ~4x faster
        doc = yaml.load(outcome.result_yaml,
                        Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
        problem = solved_pairs(doc, Dataset.load(outcome.files["dataset"]).to_problem(
            min_pairs=solver.min_pairs))  # the pairs the result was solved on
        write_report(say, doc, problem, written.report_png, written.report_html)
    return exit_code(outcome.verdict), outcome

"""Subcommands that solve data read from files: ``csv`` (the paper's layout), ``dataset`` (a saved
data set) and ``report`` (the report of a written result)."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import Any

from .common import (
    EXIT_OK,
    BadInput,
    NoSolution,
    Printer,
    SolveSettings,
    check_output_room,
    output_dir,
    output_paths,
    read_config,
    recorded_config,
    refuse_existing,
    stated_noise,
    write_report,
)
from .run import Run
from .solving import solve_and_write

__all__ = ["cmd_csv", "cmd_dataset", "cmd_report"]


def _with_carriers(naming, args: argparse.Namespace):
    """``naming`` with the parents of ``--camera-carrier`` / ``--tag-carrier`` where given."""
    frames = dict(naming.frames)
    for names, carrier in ((naming.y_names, args.camera_carrier),
                           (naming.x_names, args.tag_carrier)):
        if carrier is not None:
            frames.update({n: (carrier, frames[n][1]) for n in names})
    return replace(naming, frames=frames)


def check_carriers(camera_carrier: str, tag_carrier: str) -> None:
    """The two carriers must differ, as the configuration checker demands
    (``tag_carrier.frame`` equal to ``camera_carrier.frame`` is refused there too)."""
    if camera_carrier == tag_carrier:
        raise BadInput(f"--camera-carrier/--tag-carrier: both carriers are {camera_carrier!r}; "
                       "cameras and tags must be carried by two different frames that move "
                       "relative to each other (e.g. --camera-carrier rig --tag-carrier world)")


def verdict_settings(config) -> dict[str, Any]:
    """The verdict thresholds and publication switch of a configuration (None: defaults)."""
    if config is None:
        return {}
    return {"verdict_config": config.verdict,
            "publish_unusable": config.output.publish_unusable}


def _problem(data, min_pairs: int, run=None):
    """The data set's problem and the edges below ``min_pairs`` left out (``excluded``);
    :class:`~.common.NoSolution` when no edge is left (the pairs per edge, the option to change
    with its value, and the data set kept)."""
    from ..session.outcomes import too_few_pairs_words

    excluded = {f"({e.x}, {e.y})": f"{e.n} pairs < min_pairs={min_pairs}"
                for e in data.edges if e.n < min_pairs}
    try:
        return data.to_problem(min_pairs=min_pairs), excluded
    except ValueError:
        words = too_few_pairs_words({(e.x, e.y): e.n for e in data.edges}, min_pairs,
                                    "--min-pairs")
        kept = "" if run is None or not run.kept_words() else f"; {run.kept_words()}"
        raise NoSolution(words + kept) from None


def check_fingerprint(say: Printer, command: str, doc: dict, result: Path, data,
                      data_path: Path) -> None:
    """``BadInput`` naming both files when the result ``doc`` (read from ``result``) records
    the fingerprint of another data set than ``data`` (read from ``data_path``); a result
    without one (written before fingerprints existed) is accepted with a warning."""
    from ..data.fingerprint import FINGERPRINT_KEY, fingerprint_mismatch

    recorded = doc.get(FINGERPRINT_KEY)
    if not isinstance(recorded, dict):
        say.warning(command, f"{result} records no data set fingerprint (written by an older "
                    f"version): {data_path} is assumed to be the data set it was solved from")
        return
    words = fingerprint_mismatch(recorded, data)
    if words:
        raise BadInput(f"{result} was not solved from {data_path}: {words}; give the data set "
                       "of that result with --dataset, or solve this data set again with "
                       "rwhec-calibrate dataset")


def cmd_csv(args: argparse.Namespace, say: Printer) -> int:
    from ..data.dataset import Dataset
    from ..data.paper_csv import read_paper_csv
    from ..data.results import FrameNaming

    config = read_config(args)
    params: dict[str, Any] = {} if config is None else config.to_parameters()
    settings = SolveSettings.resolve(args, params)
    sigma, kappa, given = stated_noise(args, config)
    unknown_scale = bool(args.unknown_scale or (config and config.tags.unknown_scale))
    camera_carrier = args.camera_carrier or (config.camera_carrier.frame if config else "rig")
    tag_carrier = args.tag_carrier or (config.tag_carrier.frame if config else "world")
    check_carriers(camera_carrier, tag_carrier)
    # refuse early, before any work
    paths = output_paths(args, report=args.report, root=settings.output_root)
    run = Run("csv", say, paths, settings.output_root, force=args.force,
              resume_options=settings.resume_options(args.report))
    try:
        run.enter("reading")
        # all edges first (min_pairs=1), so that the edges left out can be reported
        everything = read_paper_csv(args.directory, sigma=sigma, kappa=kappa, min_pairs=1,
                                    unknown_scale=unknown_scale)
        naming = FrameNaming.from_carriers(
            everything.x_names, everything.y_names, camera_carrier=camera_carrier,
            tag_carrier=tag_carrier,
            suffix=config.output.frame_suffix if config else "_calibrated")
        source = {"type": "paper_csv", "path": str(args.directory)}
        carriers = {n: p for n, (p, _) in naming.frames.items()}
        dataset = Dataset.from_problem(everything, metadata={"source": source},
                                       carriers=carriers)
        run.keep(dataset)
        problem, excluded = _problem(dataset, settings.min_pairs, run)
        used = {
            "camera_carrier.frame": camera_carrier,
            "tag_carrier.frame": tag_carrier,
            "tags.unknown_scale": unknown_scale,
            "noise.sigma": float(sigma) if given == "stated" else 0.0,
            "noise.kappa": float(kappa) if given == "stated" else 0.0,
            **settings.parameters(),
        }
        return solve_and_write(say, problem, dataset, naming, run, settings,
                               excluded=excluded, config=used, source=source,
                               report=args.report, noise_given=given,
                               **verdict_settings(config))
    except KeyboardInterrupt as exc:
        raise run.interrupted(exc) from None


def cmd_dataset(args: argparse.Namespace, say: Printer) -> int:
    from ..data.dataset import Dataset
    from ..data.results import FrameNaming, load_result

    config = read_config(args)
    output_paths(args, report=args.report)  # refuse early, before any work
    data = Dataset.load(args.file)
    beside = Path(args.file).parent / "result.yaml"
    if beside.is_file() and beside != Path(args.file):
        try:
            doc = load_result(beside)
        except ValueError:
            doc = None
        if doc is not None and isinstance(doc.get("dataset_fingerprint"), dict):
            check_fingerprint(say, "dataset", doc, beside, data, Path(args.file))
    if config is None:
        config, params = recorded_config(data.metadata, f"{args.file}: metadata.config", say,
                                         "dataset")
    else:
        params = config.to_parameters()
    settings = SolveSettings.resolve(args, params)
    paths = output_paths(args, report=args.report, root=settings.output_root)
    if config is not None:
        naming = _with_carriers(FrameNaming.from_config(config), args)
    else:
        naming = _with_carriers(FrameNaming.from_carriers(
            data.x_names, data.y_names, camera_carrier="rig", tag_carrier="world",
            carriers=data.carriers), args)
        params = {"camera_carrier.frame": args.camera_carrier or "rig",
                  "tag_carrier.frame": args.tag_carrier or "world",
                  "tags.unknown_scale": data.unknown_scale}
    params.update(settings.parameters())
    cams = {naming.frames[n][0] for n in naming.y_names}
    tags = {naming.frames[n][0] for n in naming.x_names}
    for cam in cams:
        for tag in tags:
            check_carriers(cam, tag)
    carrier_options = [o for flag, v in (("--camera-carrier", args.camera_carrier),
                                         ("--tag-carrier", args.tag_carrier))
                       if v is not None for o in (flag, v)]
    run = Run("dataset", say, paths, settings.output_root, force=args.force,
              resume_options=settings.resume_options(args.report) + carrier_options)
    try:
        run.enter("reading")  # read already: the pause is for the tests of every phase
        run.keep(data)
        problem, excluded = _problem(data, settings.min_pairs, run)
        return solve_and_write(say, problem, data, naming, run, settings, excluded=excluded,
                               config=params, source={"type": "dataset", "path": str(args.file)},
                               report=args.report,
                               noise_given=config.noise.given if config is not None else "start",
                               **verdict_settings(config))
    except KeyboardInterrupt as exc:
        raise run.interrupted(exc) from None


def cmd_report(args: argparse.Namespace, say: Printer) -> int:
    from ..data.dataset import Dataset
    from ..data.results import load_result, output_paths, session_output_paths, solved_pairs

    doc = load_result(args.result)
    # beside the result: the session layout (.../result.yaml) or an explicit OUT.yaml layout
    beside = (session_output_paths(args.result.parent) if args.result.name == "result.yaml"
              else output_paths(args.result))
    data_path = args.dataset or beside.dataset
    if not data_path.exists():
        raise BadInput(f"{data_path}: no data set beside {args.result} (give it with "
                       "--dataset FILE)")
    out = output_dir(args)
    target = beside if out is None else session_output_paths(out)
    refuse_existing([target.report_png, target.report_html], args.force)
    check_output_room(target.report_png.parent, True, "-o/--output")
    data = Dataset.load(data_path)
    check_fingerprint(say, "report", doc, args.result, data, data_path)
    min_pairs = int((doc.get("config") or {}).get("solver.min_pairs", 1))
    try:
        problem = data.to_problem(min_pairs=min_pairs)
    except ValueError:
        raise BadInput(f"{args.result} does not fit the data set {data_path}: no edge has "
                       f"the result's solver.min_pairs={min_pairs} pairs") from None
    try:  # the pairs the result was solved on (without the outliers it rejected)
        problem = solved_pairs(doc, problem)
    except ValueError as exc:
        raise BadInput(f"{args.result} does not fit the data set {data_path}: {exc}") from None
    write_report(say, doc, problem, Path(target.report_png), Path(target.report_html))
    return EXIT_OK

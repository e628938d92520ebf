"""What every subcommand shares: exit codes, printing, options, the output directory (the solve
and its outputs: :mod:`.solving`).

One rule for outputs: ``-o DIR`` receives ``result.yaml``, ``static_transforms.launch.py``,
``dataset.yaml`` (+ ``dataset.npz``) and, with ``--report``, ``report.png``/``report.html``;
existing files are refused before any work unless ``--force``. Without ``-o`` the files go into a
new ``calibration_<UTC stamp>`` directory under the configuration's ``output.directory`` (else
:data:`DEFAULT_OUTPUT`), as the node writes them. Every written path is printed as
``<what>: <path>``.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from ..errors import describe_os_error

__all__ = [
    "EXIT_OK",
    "EXIT_BAD_INPUT",
    "EXIT_NO_SOLUTION",
    "EXIT_UNUSABLE",
    "EXIT_MOVED",
    "EXIT_UNDECIDED",
    "EXIT_INTERRUPTED",
    "EXIT_TERMINATED",
    "EXIT_PIPE_CLOSED",
    "Terminated",
    "exit_code",
    "Interrupted",
    "PROG",
    "MODES",
    "DEFAULT_OUTPUT",
    "BadInput",
    "NoSolution",
    "Printer",
    "Progress",
    "SolveSettings",
    "check_positive",
    "stated_noise",
    "solver_overrides",
    "prior_overrides",
    "config_from_parameters",
    "read_config",
    "output_paths",
    "refuse_existing",
    "write_report",
]

#: A usable result: the verdict is ``good`` or ``caution`` (files written).
EXIT_OK = 0
#: Bad input or output: unreadable or malformed files, invalid configuration, outputs that exist
#: (without ``--force``) or cannot be written.
EXIT_BAD_INPUT = 2
#: No solution: not enough data, or the solver stopped with an error (the data set is kept).
EXIT_NO_SOLUTION = 3
#: A solution was computed and written, but its verdict is ``unusable``: do not use it.
EXIT_UNUSABLE = 4
#: ``check``: a camera moved beyond the tolerance (the check's files are written).
EXIT_MOVED = 5
#: ``check``: not enough data yet to decide for some camera, none moved (record more).
EXIT_UNDECIDED = 6
#: Interrupted (Ctrl-C, SIGINT): 128 + 2; the pairs gathered are kept (``dataset.yaml``).
EXIT_INTERRUPTED = 130
#: Terminated (SIGTERM: ``timeout``, a closing terminal, systemd): 128 + 15; as Ctrl-C.
EXIT_TERMINATED = 143
#: The reader of the output went away (``| head``): 128 + SIGPIPE, as a shell reports it.
EXIT_PIPE_CLOSED = 141


def exit_code(verdict) -> int:
    """:data:`EXIT_OK` for a usable verdict (``good``, ``caution``), else :data:`EXIT_UNUSABLE`."""
    return EXIT_OK if verdict is not None and verdict.usable else EXIT_UNUSABLE

PROG = "rwhec-calibrate"
MODES = ("fast", "sdp", "local")
#: ``--sdp-backend`` values (``solver.sdp_backend``).
SDP_BACKENDS = ("auto", "structured", "cvxpy")
#: Output root when no configuration names one (its ``output.directory``): ``./rwhec_output``,
#: :data:`rwhec_ros.session.paths.DEFAULT_OUTPUT` (a literal here: the session package is slow
#: to import and ``--help`` should not wait for it).
DEFAULT_OUTPUT = "rwhec_output"


class BadInput(Exception):
    """Bad input for the CLI: printed without a traceback, exit code 2."""


class NoSolution(Exception):
    """No solution (e.g. not enough data): one line on stderr, exit code 3."""


class Interrupted(Exception):
    """Ctrl-C or SIGTERM after the command kept what it could (the message says where); exit
    ``code`` (130 or 143)."""

    def __init__(self, message: str, code: int = EXIT_INTERRUPTED) -> None:
        super().__init__(message)
        self.code = code


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread by the CLI's handler: a ``KeyboardInterrupt`` (every
    clean-up of Ctrl-C applies) that ends with exit code 143."""


class Printer:
    """Where the CLI talks: ``out`` for results, ``err`` for progress (unless quiet) and errors."""

    def __init__(self, out: TextIO, err: TextIO, *, quiet: bool = False) -> None:
        self.out, self.err, self.quiet = out, err, quiet

    def __call__(self, text: str = "") -> None:
        print(text, file=self.out)

    def summary(self, message: str) -> None:
        """The session's summary (one item per line; the verdict first)."""
        print(message, file=self.out)

    def files(self, files: Mapping[str, str | Path]) -> None:
        """Every written file as ``<what>: <path>``."""
        for key, path in files.items():
            print(f"{key}: {path}", file=self.out)

    def progress(self, text: str) -> None:
        """A progress line on stderr (not with ``-q``)."""
        if not self.quiet:
            print(text, file=self.err)

    def warning(self, command: str, text: str) -> None:
        print(f"{PROG} {command}: warning: {text}", file=self.err)


class Progress:
    """Progress bar on stderr (a terminal only; elsewhere one line at the end). ``status``, when
    given, is called for text shown after the bar and on the final line (e.g. the live
    estimate's convergence)."""

    def __init__(self, err: TextIO, label: str, *, enabled: bool = True,
                 status: Callable[[], str] | None = None) -> None:
        self.err, self.label, self.status = err, label, status
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
        extra = f" | {self.status()}" if self.status is not None else ""
        self.err.write(f"\r{self.label} [{bar:<30}] {100 * frac:5.1f}% {done}/{total} messages, "
                       f"{now - self.t0:.1f} s{extra}\x1b[K")
        self.err.flush()

    def close(self) -> None:
        if not self.enabled:
            return
        if self.tty:
            self.err.write("\n")
        extra = f"; {self.status()}" if self.status is not None else ""
        self.err.write(f"{self.label}: {self.done} messages in {time.monotonic() - self.t0:.1f} s"
                       f"{extra}\n")
        self.err.flush()


def check_positive(name: str, value: float) -> None:
    if not (np.isfinite(value) and value > 0):
        raise BadInput(f"{name}: must be finite and > 0, got {value!r}")


def stated_noise(args: argparse.Namespace, config) -> tuple[float, float, str]:
    """``(sigma, kappa, given)`` for the pairs of ``csv`` and ``poses``: ``--sigma``/``--kappa``,
    else the configuration's ``noise.sigma``/``noise.kappa`` (0: not stated); ``given`` is
    ``"stated"`` when both are stated (they then also check the estimate), else ``"start"`` with
    the start values (0.01 m, 125) for the unstated ones, which only start the estimate."""
    from ..config.sections import START_KAPPA, START_SIGMA

    sigma = args.sigma if args.sigma is not None else (config.noise.sigma if config else 0.0)
    kappa = args.kappa if args.kappa is not None else (config.noise.kappa if config else 0.0)
    if args.sigma is not None:
        check_positive("--sigma", sigma)
    if args.kappa is not None:
        check_positive("--kappa", kappa)
    given = "stated" if sigma > 0 and kappa > 0 else "start"
    return (sigma if sigma > 0 else START_SIGMA), (kappa if kappa > 0 else START_KAPPA), given


# ------------------------------------------------------------------------------------------------
# settings: command line over configuration over defaults


def solver_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """The flat parameters that ``--mode``, ``--sdp-backend``, ``--min-pairs``, ``--robust``,
    ``--folds``, ``--no-guidance``, ``--no-refine``, ``--no-noise-estimate``,
    ``--noise-groups`` and (``bag``, ``samples``) ``--unknown-scale`` set (those given)."""
    if args.min_pairs is not None and args.min_pairs < 1:
        raise BadInput(f"--min-pairs: must be >= 1, got {args.min_pairs}")
    out: dict[str, Any] = {}
    if args.mode is not None:
        out["solver.mode"] = args.mode
    if getattr(args, "sdp_backend", None) is not None:
        out["solver.sdp_backend"] = args.sdp_backend
    if args.min_pairs is not None:
        out["solver.min_pairs"] = int(args.min_pairs)
    if args.robust:
        out["solver.reject_outliers"] = True
    folds = getattr(args, "folds", None)
    if folds is not None:
        if folds < 0 or folds == 1:
            raise BadInput(f"--folds: must be 0 (off) or >= 2, got {folds}")
        out["accuracy.cross_validation_folds"] = int(folds)
    if getattr(args, "no_guidance", False):
        out["accuracy.guidance"] = False
    if getattr(args, "no_refine", False):
        out["solver.refine"] = False
    if getattr(args, "no_noise_estimate", False):
        out["noise.estimate"] = False
    if getattr(args, "noise_groups", None) is not None:
        out["noise.groups"] = args.noise_groups
    if getattr(args, "unknown_scale", False) and getattr(args, "command", "") in ("bag",
                                                                                   "samples"):
        out["tags.unknown_scale"] = True
    return out


def prior_overrides(args: argparse.Namespace, base: Mapping[str, Any]) -> dict[str, Any]:
    """``priors.*`` parameters: those of ``base`` with every ``--prior FRAME.AXIS=VALUE`` added
    or replacing the same frame and axis ({} without ``--prior``)."""
    given = getattr(args, "prior", None)
    if not given:
        return {}
    entries = dict(((f, a), float(x)) for f, a, x in zip(
        base.get("priors.frames", ()), base.get("priors.axes", ()),
        base.get("priors.values_m", ()), strict=False))
    for text in given:
        left, sep, value = str(text).partition("=")
        frame, dot, axis = left.strip().rpartition(".")
        try:
            number = float(value)
        except ValueError:
            number = float("nan")
        if not sep or not dot or not frame or axis not in ("x", "y", "z") or \
                not math.isfinite(number):
            raise BadInput(f"--prior: expected FRAME.AXIS=VALUE with AXIS x, y or z and a "
                           f"number in metres (e.g. cam0.z=0.45), got {text!r}")
        entries[(frame, axis)] = number
    return {"priors.frames": [f for f, _ in entries], "priors.axes": [a for _, a in entries],
            "priors.values_m": list(entries.values())}


@dataclass(frozen=True)
class SolveSettings:
    """Solver settings and output root of one run: the command line, else the (possibly partial)
    flat ``parameters`` of a configuration, else the schema's defaults."""

    mode: str
    min_pairs: int
    robust: bool
    output_root: str
    priors: tuple[tuple[str, str, float], ...] = ()
    unobservable_std_m: float = 1.0
    min_scale: float = 0.01
    folds: int = 5
    guidance: bool = True
    sdp_backend: str = "auto"
    refine: bool = True
    noise_estimate: bool = True
    noise_groups: str = "camera"

    @staticmethod
    def resolve(args: argparse.Namespace, parameters: Mapping[str, Any]) -> SolveSettings:
        p = {**dict(parameters), **solver_overrides(args)}
        p.update(prior_overrides(args, p))
        return SolveSettings.from_parameters(p)

    @staticmethod
    def from_parameters(p: Mapping[str, Any]) -> SolveSettings:
        """The settings of flat parameters (a configuration's, possibly partial)."""
        from ..session.paths import plain_output_root

        priors = tuple(zip(p.get("priors.frames", ()), p.get("priors.axes", ()),
                           (float(x) for x in p.get("priors.values_m", ())), strict=False))
        return SolveSettings(mode=str(p.get("solver.mode", "fast")),
                             min_pairs=int(p.get("solver.min_pairs", 3)),
                             robust=bool(p.get("solver.reject_outliers", False)),
                             output_root=str(plain_output_root(p.get("output.directory", ""))),
                             priors=priors,
                             unobservable_std_m=float(p.get("solver.unobservable_std_m", 1.0)),
                             min_scale=float(p.get("solver.min_scale", 0.01)),
                             folds=int(p.get("accuracy.cross_validation_folds", 5)),
                             guidance=bool(p.get("accuracy.guidance", True)),
                             sdp_backend=str(p.get("solver.sdp_backend", "auto")),
                             refine=bool(p.get("solver.refine", True)),
                             noise_estimate=bool(p.get("noise.estimate", True)),
                             noise_groups=str(p.get("noise.groups", "camera")))

    def resume_options(self, report: bool) -> list[str]:
        """The command-line options that give ``dataset`` these settings (for the resume
        command of :class:`~rwhec_ros.cli.run.Run`)."""
        out = ["--mode", self.mode, "--min-pairs", str(self.min_pairs)]
        if self.sdp_backend != "auto":
            out += ["--sdp-backend", self.sdp_backend]
        if self.robust:
            out.append("--robust")
        for f, a, x in self.priors:
            out += ["--prior", f"{f}.{a}={x!r}"]
        out += ["--folds", str(self.folds)]
        if not self.guidance:
            out.append("--no-guidance")
        if not self.refine:
            out.append("--no-refine")
        if not self.noise_estimate:
            out.append("--no-noise-estimate")
        if self.noise_groups != "camera":
            out += ["--noise-groups", self.noise_groups]
        if report:
            out.append("--report")
        return out

    def parameters(self) -> dict[str, Any]:
        """The ``solver.*``, ``priors.*`` and ``accuracy.*`` parameters of these settings."""
        return {"solver.mode": self.mode, "solver.min_pairs": self.min_pairs,
                "solver.reject_outliers": self.robust,
                "solver.unobservable_std_m": self.unobservable_std_m,
                "solver.min_scale": self.min_scale,
                "solver.sdp_backend": self.sdp_backend,
                "solver.refine": self.refine,
                "priors.frames": [f for f, _, _ in self.priors],
                "priors.axes": [a for _, a, _ in self.priors],
                "priors.values_m": [x for _, _, x in self.priors],
                "accuracy.cross_validation_folds": self.folds,
                "accuracy.guidance": self.guidance,
                "noise.estimate": self.noise_estimate, "noise.groups": self.noise_groups}

    def noise_options(self, given: str, kinds=()):
        """:class:`~rwhec_ros.core.noise.NoiseOptions` of these settings, the pairs' noise
        being ``given`` (``"stated"``, ``"reprojection"`` or ``"start"``), the targets' kinds
        ``kinds`` (:attr:`~rwhec_ros.config.CalibratorConfig.target_kinds`; empty: not
        known)."""
        from ..core.noise import NoiseOptions

        return NoiseOptions(estimate=self.noise_estimate, groups=self.noise_groups, given=given,
                            kinds=tuple(kinds))


def config_from_parameters(flat: Mapping[str, Any], where: str):
    """A validated :class:`~rwhec_ros.config.CalibratorConfig`; errors name ``where``."""
    from ..config import CalibratorConfig

    try:
        return CalibratorConfig.from_parameters(flat)
    except ValueError as exc:
        raise BadInput(f"{where}: {exc}") from None


def recorded_config(metadata: Mapping[str, Any], where: str, say: Printer, command: str,
                    overrides: Mapping[str, Any] | None = None):
    """``(config, flat)``: the configuration recorded in a data set (``metadata.config``, flat
    parameters ``flat``) with ``overrides``, validated (errors name ``where``); ``(None, {})``
    when none is recorded. A parameter retired since the data set was written
    (``RETIRED_PARAMETERS``) is left out with a warning naming it: a data set is a record of how
    it was gathered, and an older one must still load (a parameter file that sets it is
    refused, so that its author learns the replacement)."""
    from ..config.validation import RETIRED_PARAMETERS

    flat = dict(metadata.get("config") or {})
    if not flat:
        return None, {}
    for key in sorted(set(flat) & set(RETIRED_PARAMETERS)):
        say.warning(command, f"{where}: {key} (value {flat.pop(key)!r}) ignored: "
                             f"{RETIRED_PARAMETERS[key].split(';')[0]}")
    flat.update(overrides or {})
    return config_from_parameters(flat, where), flat


def read_config(args: argparse.Namespace, overrides: Mapping[str, Any] | None = None):
    """``--config FILE`` (section ``--node-name``) with ``overrides``, validated; None without
    ``--config``."""
    from ..config import read_parameter_file

    if args.config is None:
        return None
    flat = read_parameter_file(args.config, args.node_name)
    flat.update(overrides or {})
    flat.update(prior_overrides(args, flat))
    return config_from_parameters(flat, f"config file {str(args.config)!r}")


# ------------------------------------------------------------------------------------------------
# outputs


def refuse_existing(targets: Iterable[Path], force: bool) -> None:
    """``BadInput`` naming the existing ``targets`` unless ``force`` (the message of
    :func:`rwhec_ros.data.results.write_outputs`)."""
    existing = [str(p) for p in targets if p.exists()]
    if existing and not force:
        raise BadInput(f"refusing to overwrite existing file(s) {existing} "
                       "(use --force to overwrite)")


def output_dir(args: argparse.Namespace) -> Path | None:
    """``-o DIR`` checked to be usable as a directory, or None."""
    if args.output is None:
        return None
    d = Path(args.output)
    if d.exists() and not d.is_dir():
        raise BadInput(f"-o/--output: {str(d)!r} exists and is not a directory")
    if not d.exists() and d.suffix.lower() in (".yaml", ".yml"):
        raise BadInput(f"-o/--output: expects a directory (it receives result.yaml, the launch "
                       f"file, the data set and the report), got {str(d)!r}")
    return d


def output_paths(args: argparse.Namespace, *, report: bool, root: str | Path | None = None):
    """The files of ``-o DIR`` (None without ``-o``), checked before any work: existing ones
    (the report included, ``report`` or not) are refused unless ``--force``, and the
    directory (without ``-o``: ``root``, the output root, when given) must be writable with
    room for the outputs (:func:`check_output_room`)."""
    from ..data.results import session_output_paths

    d = output_dir(args)
    if d is None:
        if root is not None:
            check_output_room(Path(root), report, "output.directory (or -o DIR)")
        return None
    paths = session_output_paths(d)
    # the report files too, with or without --report: a new result must not sit beside an older
    # report (with --force they are removed with every other file of the earlier run)
    targets = [paths.result, paths.launch, paths.dataset, paths.dataset.with_suffix(".npz"),
               paths.report_png, paths.report_html, paths.urdf, paths.frames,
               paths.result.parent / "check.yaml"]  # a check's answer (run.run_files)
    refuse_existing(targets, args.force)
    check_output_room(d, report, "-o/--output")
    return paths


#: Bytes a run's outputs need at least (result, launch file, URDF, frames YAML of a small rig
#: and a few hundred pairs inline: ~200 KB measured on the demo bag), checked before any work.
BASE_OUTPUT_BYTES = 256 * 1024
#: The report's PNG and HTML page (~1-2 MB each on the paper's data), with ``--report``.
REPORT_BYTES = 4 * 1024 * 1024


def expected_output_bytes(report: bool) -> int:
    """What the free-space check before any work asks for (:data:`BASE_OUTPUT_BYTES`, plus
    :data:`REPORT_BYTES` with ``--report``)."""
    return BASE_OUTPUT_BYTES + (REPORT_BYTES if report else 0)


def check_output_room(directory: Path, report: bool, option: str) -> None:
    """``BadInput`` when ``directory`` cannot receive the outputs (not writable, or less free
    space than :func:`expected_output_bytes`), naming ``option``."""
    from ..data.atomic import check_room

    why = check_room(directory, expected_output_bytes(report))
    if why:
        fix = ("free some space or give another directory with -o" if "free on its" in why
               else "give a writable directory with -o")
        raise BadInput(f"{option}: cannot write the outputs into {directory}: {why}; {fix}")


def write_report(say: Printer, doc: dict, problem, png: Path, html: Path, ident=None) -> None:
    """The report PNG and HTML page (:mod:`rwhec_ros.report`), printed like the other files."""
    from ..report import write_report as _write

    try:
        png.parent.mkdir(parents=True, exist_ok=True)
        files = _write(doc, problem, png, html, identifiability=ident)
    except OSError as exc:
        raise BadInput(f"cannot write the report: {describe_os_error(exc)}") from None
    say.files({"report": files.png, "report page": files.html})


def remove_stale_reports(say: Printer, paths) -> None:
    """A new result never sits beside the report of an older one: without ``--report`` the
    report files of the output directory (only reached with ``--force``) are removed."""
    for path in (paths.report_png, paths.report_html):
        if path.exists():
            path.unlink()
            say.progress(f"removed the older report {path} (it described another result)")

"""One run of a solving subcommand: its phases, its output directory, and what it keeps however
it ends.

A run goes through the phases ``reading`` (the bag, the CSV files or the data set; ``demo``:
the simulation), ``solving``, ``analysing`` (identifiability, uncertainty, cross-validation,
verdict) and ``writing``. As soon as reading ends, the data set of the pairs gathered is
written into the output directory (:meth:`Run.keep`; atomically, :mod:`rwhec_ros.data.atomic`),
so that a failed or interrupted solve leaves it, with the exact ``rwhec-calibrate dataset ...``
command that resumes the run (:meth:`Run.resume_command`). With ``--force`` that first write
also removes every output file of an earlier run from the directory: a new data set never sits
beside an older result. Ctrl-C (SIGINT) and SIGTERM end the run with one line saying in which
phase and where the data set is (:meth:`Run.interrupted`; exit codes 130 and 143).

Test-only hook (documented in ``docs/robustness.md``): with the environment variables
``RWHEC_TEST_PAUSE_PHASE=<phase>`` and ``RWHEC_TEST_PAUSE_FILE=<path>``, the run creates
``<path>`` when it enters ``<phase>`` (``reading``: half-way through the messages of a bag, the
simulation of ``demo``, or before the files are read) and waits until that file is removed
(at most 120 s), so that a test can deliver a signal, or fill a disk, in that phase.
"""

from __future__ import annotations

import os
import shlex
import signal
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from ..errors import describe_os_error
from .common import PROG, BadInput, Interrupted, Printer, Terminated, expected_output_bytes

__all__ = ["PHASES", "PAUSE_PHASE_ENV", "PAUSE_FILE_ENV", "Run", "pause_for_test",
           "expected_output_bytes", "run_files", "CHECK_ANSWER"]

PHASES = ("reading", "solving", "analysing", "writing")
PAUSE_PHASE_ENV = "RWHEC_TEST_PAUSE_PHASE"
PAUSE_FILE_ENV = "RWHEC_TEST_PAUSE_FILE"
#: Longest test pause [s].
PAUSE_MAX_S = 120.0


def pause_for_test(phase: str) -> None:
    """The test-only pause (module docstring): nothing unless ``RWHEC_TEST_PAUSE_PHASE`` is
    ``phase``."""
    if os.environ.get(PAUSE_PHASE_ENV) != phase:
        return
    marker = os.environ.get(PAUSE_FILE_ENV)
    if not marker:
        return
    Path(marker).write_text(f"{os.getpid()} {phase}\n", encoding="utf-8")
    t0 = time.monotonic()
    while Path(marker).exists() and time.monotonic() - t0 < PAUSE_MAX_S:
        time.sleep(0.05)


#: A check's answer (``rwhec-calibrate check``), which shares the directory layout of a run.
CHECK_ANSWER = "check.yaml"


def run_files(paths) -> list[Path]:
    """Every output name of a run in the directory of ``paths`` (an ``OutputPaths``): the
    calibration's files, ``dataset.npz`` and a check's ``check.yaml``; what ``--force``
    removes and what is refused without it."""
    return [*paths.all(), paths.dataset.with_suffix(".npz"),
            paths.result.parent / CHECK_ANSWER]


class Run:
    """The state of one run (module docstring).

    Parameters
    ----------
    command : str
        The subcommand (``csv``, ``bag``, ``dataset``, ``demo``, ``samples``, ``poses``,
        ``check``).
    say : Printer
    paths : OutputPaths or None
        The files of ``-o DIR`` (checked); None: a new ``<kind>_<UTC stamp>`` directory under
        ``output_root``, made at the first write.
    output_root : str or Path
    force : bool
        ``--force``: the first write removes the earlier run's files from the directory.
    resume_options : sequence of str
        The options of this run that ``resume_subcommand`` needs to solve the kept data set the
        same way (mode, min pairs, robust, priors, folds, guidance, report, carriers; for
        ``check``: the reference and the test's options).
    kind : str
        The new directory's prefix: ``calibration``, or ``check`` (``rwhec-calibrate check``,
        which reads through ``bag`` and ``samples`` with this set).
    resume_subcommand : str
        The subcommand of :meth:`resume_command`: ``dataset``, or ``check`` (which takes the
        kept ``dataset.yaml`` as its input).
    """

    def __init__(self, command: str, say: Printer, paths, output_root, *, force: bool,
                 resume_options: Sequence[str] = (), kind: str = "calibration",
                 resume_subcommand: str = "dataset") -> None:
        self.command, self.say = command, say
        self.paths = paths
        self.output_root = output_root
        self.force = force
        self.resume_options = list(resume_options)
        self.kind = kind
        self.resume_subcommand = resume_subcommand
        self.phase = "starting"
        self.kept: Path | None = None
        self.kept_pairs = 0
        self.rescued = False

    # --- phases ------------------------------------------------------------------------------
    def enter(self, phase: str, *, pause: bool = True) -> None:
        """Enter ``phase`` (one of :data:`PHASES`); the test pause, if asked for (not with
        ``pause=False``: ``bag`` and ``demo`` pause half-way through their reading)."""
        self.phase = phase
        if pause:
            pause_for_test(phase)

    # --- outputs -----------------------------------------------------------------------------
    def output_paths(self):
        """The files of the output directory, which exists after this call: ``-o DIR``
        (created), else a new ``<kind>_<UTC stamp>`` directory under the output root."""
        from ..data.results import new_output_dir, session_output_paths

        if self.paths is None:
            self.paths = session_output_paths(new_output_dir(self.output_root, self.kind))
        else:
            self.paths.result.parent.mkdir(parents=True, exist_ok=True)
        return self.paths

    def _clear_earlier_run(self, paths) -> None:
        """``--force``: the earlier run's files (a calibration's or a check's,
        :func:`run_files`), removed before the first new one is written."""
        from ..data.atomic import remove_files

        if not self.force:
            return
        names = run_files(paths)
        removed = remove_files(p for p in names if p != paths.dataset)
        if removed:
            self.say.progress(f"--force: removed {len(removed)} file(s) of an earlier run from "
                              f"{paths.result.parent} ({', '.join(p.name for p in removed)})")

    def keep(self, dataset) -> Path | None:
        """Write ``dataset`` (the pairs gathered) into the output directory at once; when that
        fails (full disk, read-only file system), into a rescue directory
        (``./rwhec_output/rescue_<stamp>``, else the system's temporary directory). Returns the
        path, or None when there is nothing to keep; raises :class:`BadInput` when no place
        takes it."""
        if dataset is None or not dataset.n_pairs:
            return None
        errors = []
        try:
            paths = self.output_paths()
            self._clear_earlier_run(paths)
            self.kept = Path(dataset.save(paths.dataset))
        except OSError as exc:
            errors.append(describe_os_error(exc))
            self.kept = self._rescue(dataset, errors)
        self.kept_pairs = int(dataset.n_pairs)
        if self.rescued:
            self.say.warning(self.command, f"cannot write the data set into the output "
                             f"directory ({errors[0]}); the {self.kept_pairs} pairs are in "
                             f"{self.kept} instead")
        else:
            self.say.progress(f"kept: {self.kept_pairs} pairs in {self.kept} (before solving)")
        return self.kept

    def _rescue(self, dataset, errors: list[str]) -> Path:
        import tempfile

        from ..data.results import new_output_dir

        for root in (Path("rwhec_output"), Path(tempfile.gettempdir())):
            try:
                target = new_output_dir(root, "rescue") / "dataset.yaml"
                path = Path(dataset.save(target))
            except OSError as exc:
                errors.append(describe_os_error(exc))
                continue
            self.rescued = True
            return path
        raise BadInput(f"cannot write the data set of the {dataset.n_pairs} pairs anywhere: "
                       + "; ".join(errors) + "; free some space or give a writable -o DIR")

    def resume_command(self) -> str:
        """The ``rwhec-calibrate dataset ...`` (``check ...``) command that solves (checks) the
        kept data set into the directory it is in, as this run would have."""
        if self.kept is None:
            return ""
        argv = [PROG, self.resume_subcommand, str(self.kept), "-o", str(self.kept.parent),
                "--force", *self.resume_options]
        return shlex.join(argv)

    def kept_words(self) -> str:
        """``the 133 pairs read are in out/dataset.yaml; resume with: rwhec-calibrate ...``, or
        "" when nothing was kept."""
        if self.kept is None:
            return ""
        return (f"the {self.kept_pairs} pairs gathered are in {self.kept}; resume with: "
                f"{self.resume_command()}")

    # --- ending early ------------------------------------------------------------------------
    def interrupted(self, exc: BaseException,
                    gathered: Callable[[], object] | None = None) -> Interrupted:
        """The :class:`Interrupted` to raise for Ctrl-C or SIGTERM (``exc``) in the current
        phase: the pairs ``gathered()`` so far are kept first when nothing was kept yet
        (further signals are ignored while they are written)."""
        name, code = ("SIGTERM", 143) if isinstance(exc, Terminated) else ("SIGINT", 130)
        previous = _ignore_signals()
        try:
            note = ""
            if self.kept is None and gathered is not None:
                try:
                    self.keep(gathered())
                except (BadInput, OSError, ValueError) as err:
                    note = f"; nothing kept ({err})"
            words = f"interrupted ({name}) while {self.phase}"
            if self.kept is not None:
                words += f"; {self.kept_words()}"
            elif not note:
                words += "; nothing was gathered yet, nothing written"
            return Interrupted(words + note, code)
        finally:
            _restore_signals(previous)


def _ignore_signals() -> dict:
    previous = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            previous[sig] = signal.signal(sig, signal.SIG_IGN)
        except (ValueError, OSError):  # not the main thread
            pass
    return previous


def _restore_signals(previous: dict) -> None:
    for sig, handler in previous.items():
        try:
            signal.signal(sig, handler)
        except (ValueError, OSError):
            pass

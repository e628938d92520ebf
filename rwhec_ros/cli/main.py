"""``main``: parse, dispatch to the subcommand, turn every failure into words and an exit code."""

from __future__ import annotations

import argparse
import os
import signal
import sys
import warnings
from collections.abc import Callable, Sequence
from typing import TextIO

from ..errors import describe_os_error
from .check import cmd_check
from .common import (
    EXIT_BAD_INPUT,
    EXIT_INTERRUPTED,
    EXIT_NO_SOLUTION,
    EXIT_PIPE_CLOSED,
    EXIT_TERMINATED,
    PROG,
    BadInput,
    Interrupted,
    NoSolution,
    Printer,
    Terminated,
)
from .files import cmd_csv, cmd_dataset, cmd_report
from .parser import build_parser
from .pose_list import cmd_poses
from .replay import cmd_bag, cmd_demo
from .samples import cmd_samples

__all__ = ["main"]

_COMMANDS: dict[str, Callable[[argparse.Namespace, Printer], int]] = {
    "csv": cmd_csv,
    "bag": cmd_bag,
    "samples": cmd_samples,
    "poses": cmd_poses,
    "dataset": cmd_dataset,
    "demo": cmd_demo,
    "report": cmd_report,
    "check": cmd_check,
}


def main(argv: Sequence[str] | None = None, *, stdout: TextIO | None = None,
         stderr: TextIO | None = None) -> int:
    """Run ``rwhec-calibrate`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code.

    Bad input (unreadable or malformed files, invalid configuration, existing outputs without
    ``--force``, outputs that cannot be written) is reported on stderr as
    ``rwhec-calibrate <command>: error: <message>`` in words with exit code 2, never a
    traceback. Ctrl-C ends with one line naming the phase and the data set kept (exit code 130;
    :mod:`.run`), SIGTERM the same with exit code 143; a closed output pipe (``| head``) ends
    quietly (141). No solution (not enough data, a solver error) is one line on stderr (3).
    Python warnings of the libraries are printed once each as
    ``rwhec-calibrate <command>: note: <message>``.
    """
    from ..allocator import retain_freed_memory

    retain_freed_memory()  # bag/demo's live re-solves reuse their freed memory (see the module)
    out = stdout if stdout is not None else sys.stdout
    err = stderr if stderr is not None else sys.stderr
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, usage errors (argparse printed them)
        return int(exc.code or 0)
    say = Printer(out, err, quiet=bool(getattr(args, "quiet", False)))
    seen: set[str] = set()

    def note(message, category, filename, lineno, file=None, line=None) -> None:
        text = str(message).strip().splitlines()[0] if str(message).strip() else ""
        if text and text not in seen:
            seen.add(text)
            print(f"{PROG} {args.command}: note: {text}", file=err)

    previous = _terminate_as_interrupt()
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        # a library's deprecations are for its callers' developers, not for the user
        warnings.simplefilter("ignore", DeprecationWarning)
        warnings.simplefilter("ignore", PendingDeprecationWarning)
        warnings.showwarning = note
        try:
            return _COMMANDS[args.command](args, say)
        except NoSolution as exc:
            print(f"{PROG} {args.command}: no solution: {exc}", file=err)
            return EXIT_NO_SOLUTION
        except (BadInput, ValueError, FileExistsError) as exc:
            print(f"{PROG} {args.command}: error: {exc}", file=err)
            return EXIT_BAD_INPUT
        except BrokenPipeError:
            _quiet_stdout(out)
            return EXIT_PIPE_CLOSED
        except OSError as exc:
            print(f"{PROG} {args.command}: error: {describe_os_error(exc)}", file=err)
            return EXIT_BAD_INPUT
        except Interrupted as exc:
            print(f"{PROG} {args.command}: {exc}", file=err)
            return exc.code
        except KeyboardInterrupt as exc:  # before a run started: nothing gathered
            terminated = isinstance(exc, Terminated)
            print(f"{PROG} {args.command}: interrupted "
                  f"({'SIGTERM' if terminated else 'SIGINT'}) while starting; nothing was "
                  "gathered yet, nothing written", file=err)
            return EXIT_TERMINATED if terminated else EXIT_INTERRUPTED
        finally:
            _restore(previous)


def _terminate_as_interrupt():
    """SIGTERM (``timeout``, a closing terminal, systemd) handled like Ctrl-C: raised as
    :class:`~.common.Terminated` in the main thread; returns the handler it replaced (None when
    it cannot be set: not the main thread)."""
    def handler(signum, frame):
        raise Terminated()

    try:
        return signal.signal(signal.SIGTERM, handler)
    except (ValueError, OSError):
        return None


def _restore(previous) -> None:
    if previous is not None:
        try:
            signal.signal(signal.SIGTERM, previous)
        except (ValueError, OSError):
            pass


def _quiet_stdout(out: TextIO) -> None:
    """After a closed pipe: point stdout at /dev/null so that the interpreter's final flush
    does not print a second error (Python documentation, "Note on SIGPIPE")."""
    if out is sys.stdout:
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError):
            pass

"""``main``: parse, dispatch to the subcommand, turn every failure into words and an exit code."""

from __future__ import annotations

import argparse
import os
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
    PROG,
    BadInput,
    Interrupted,
    NoSolution,
    Printer,
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
    traceback. Ctrl-C ends with one line (exit code 130; ``bag`` first saves the data set
    collected so far); a closed output pipe (``| head``) ends quietly (141). Python warnings of
    the libraries are printed once each as ``rwhec-calibrate <command>: note: <message>``.
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

    with warnings.catch_warnings():
        warnings.simplefilter("default")
        warnings.showwarning = note
        try:
            return _COMMANDS[args.command](args, say)
        except NoSolution as exc:
            say(f"no solution: {exc}")
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
        except (KeyboardInterrupt, Interrupted) as exc:
            text = str(exc) if isinstance(exc, Interrupted) else ""
            print(f"{PROG} {args.command}: interrupted" + (f"; {text}" if text else ""),
                  file=err)
            return EXIT_INTERRUPTED


def _quiet_stdout(out: TextIO) -> None:
    """After a closed pipe: point stdout at /dev/null so that the interpreter's final flush
    does not print a second error (Python documentation, "Note on SIGPIPE")."""
    if out is sys.stdout:
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError):
            pass

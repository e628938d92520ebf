"""``main``: parse, dispatch to the subcommand, turn bad input into exit code 2."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from typing import TextIO

from .common import EXIT_BAD_INPUT, EXIT_NO_SOLUTION, PROG, BadInput, NoSolution, Printer
from .files import cmd_csv, cmd_dataset, cmd_report
from .parser import build_parser
from .replay import cmd_bag, cmd_demo

__all__ = ["main"]

_COMMANDS: dict[str, Callable[[argparse.Namespace, Printer], int]] = {
    "csv": cmd_csv,
    "bag": cmd_bag,
    "dataset": cmd_dataset,
    "demo": cmd_demo,
    "report": cmd_report,
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
    say = Printer(out, err, quiet=bool(getattr(args, "quiet", False)))
    try:
        return _COMMANDS[args.command](args, say)
    except NoSolution as exc:
        say(str(exc))
        return EXIT_NO_SOLUTION
    except (BadInput, ValueError, FileExistsError, FileNotFoundError, IsADirectoryError,
            NotADirectoryError, PermissionError) as exc:
        print(f"{PROG} {args.command}: error: {exc}", file=err)
        return EXIT_BAD_INPUT

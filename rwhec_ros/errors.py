"""Errors in words: operating-system and YAML errors as one line a user can act on.

No ``[Errno 2]``, no ``<unicode string>``: the file, the line, what is wrong. Imports nothing of
the package, so every layer (configuration, data, CLI, session) can use it.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["describe_os_error", "describe_yaml_error"]


def describe_os_error(exc: OSError) -> str:
    """An ``OSError`` in words, without Python's ``[Errno N]``: ``<file>: <reason>``, e.g.
    ``out/result.yaml: permission denied`` (the message itself for errors raised with one)."""
    if exc.strerror:
        reason = exc.strerror[:1].lower() + exc.strerror[1:]
        where = exc.filename if exc.filename is not None else ""
        return f"{where}: {reason}" if where else reason
    return str(exc)


def describe_yaml_error(path: str | Path, exc: Exception) -> str:
    """A YAML parse error as ``<file>:<line>: not valid YAML: <problem>`` (one line)."""
    mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
    where = f"{path}:{mark.line + 1}" if mark is not None else str(path)
    problem = getattr(exc, "problem", None) or getattr(exc, "context", None) or \
        str(exc).splitlines()[0]
    return f"{where}: not valid YAML: {problem}"

"""Files that are whole or absent: atomic writes, staged sets of files, a space check.

Every output file of the package goes through here. A file is written to a temporary file in
its own directory (``.<name>.<random>.tmp``), flushed and ``fsync``-ed, then renamed over its
name with :func:`os.replace` (atomic on POSIX file systems) and the directory ``fsync``-ed. A
full disk, a read-only file system or an interrupt (Ctrl-C, SIGTERM) at any point leaves either
the complete new file or the previous state, never a truncated file; the temporary file is
removed on every error. :class:`StagedFiles` extends this to a set of files: all are written
to temporary files first (an error leaves every earlier file untouched), then renamed one after
the other, the file that marks the set as complete (``result.yaml``) last.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterable
from pathlib import Path

__all__ = ["atomic_write_bytes", "atomic_write_text", "StagedFiles", "free_bytes",
           "existing_ancestor", "check_room", "remove_files"]


def _fsync_directory(directory: Path) -> None:
    """Make a rename in ``directory`` durable (best effort: not every file system allows it)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _write_temp(path: Path, data: bytes) -> Path:
    """``data`` in a new temporary file beside ``path``, flushed to disk; returns its path. On
    any error (or an interrupt) the temporary file is removed and the error propagates."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o644)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    return Path(tmp)


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (module docstring); returns ``path``.

    Raises ``OSError`` (e.g. ``ENOSPC``, ``EROFS``, ``EACCES``) with ``path`` unchanged."""
    path = Path(path)
    tmp = _write_temp(path, data)
    try:
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    _fsync_directory(path.parent)
    return path


def atomic_write_text(path: str | Path, text: str) -> Path:
    """:func:`atomic_write_bytes` of ``text`` in UTF-8."""
    return atomic_write_bytes(path, text.encode("utf-8"))


class StagedFiles:
    """A set of files written all or nothing as far as the file system allows.

    :meth:`stage` writes each file to a temporary file beside its target; :meth:`commit`
    renames them over their targets in the order staged; :meth:`discard` (also on leaving a
    ``with`` block without a commit) removes the temporary files. An error while staging
    (full disk, read-only file system, interrupt) therefore leaves every target as it was.
    """

    def __init__(self) -> None:
        self._staged: list[tuple[Path, Path]] = []

    def __enter__(self) -> StagedFiles:
        return self

    def __exit__(self, *exc) -> None:
        self.discard()

    def stage(self, path: str | Path, data: bytes | str) -> None:
        path = Path(path)
        payload = data.encode("utf-8") if isinstance(data, str) else bytes(data)
        self._staged.append((_write_temp(path, payload), path))

    def commit(self) -> list[Path]:
        """Rename every staged file over its target; returns the targets."""
        done = []
        while self._staged:
            tmp, path = self._staged[0]
            os.replace(tmp, path)
            self._staged.pop(0)
            done.append(path)
        for directory in {p.parent for p in done}:
            _fsync_directory(directory)
        return done

    def discard(self) -> None:
        for tmp, _ in self._staged:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        self._staged.clear()


def existing_ancestor(path: str | Path) -> Path:
    """``path`` or its nearest existing parent directory, relative when ``path`` is (``.`` for
    a relative path with none)."""
    p = Path(path)
    while not p.exists() and p != p.parent:
        p = p.parent
    return p if p.exists() else Path(".")


def free_bytes(path: str | Path) -> int:
    """Bytes free for an unprivileged writer on the file system of ``path`` (or of its nearest
    existing parent)."""
    return int(shutil.disk_usage(existing_ancestor(path)).free)


def check_room(directory: str | Path, need_bytes: int) -> str:
    """Why ``directory`` (existing or to be created) cannot receive ``need_bytes`` bytes of
    files, in words, or ``""`` when it can: it (or the parent it would be created in) must be
    a writable directory, proven by creating and removing a file there, with at least
    ``need_bytes`` free on its file system."""
    d = Path(directory)
    base = existing_ancestor(d)
    if not base.is_dir():
        return f"{base} is not a directory"
    try:
        fd, probe = tempfile.mkstemp(prefix=".rwhec_probe.", dir=base)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        reason = (exc.strerror or str(exc)).lower()
        return f"{base}: cannot write there ({reason})"
    free = free_bytes(base)
    if free < need_bytes:
        return (f"{base}: only {_size(free)} free on its file system, the outputs need about "
                f"{_size(need_bytes)}")
    return ""


def _size(n: int) -> str:
    return f"{n / 2**20:.1f} MiB" if n >= 2**20 else f"{n / 2**10:.0f} KiB"


def remove_files(paths: Iterable[str | Path]) -> list[Path]:
    """Remove the existing ``paths`` (files only); returns those removed."""
    removed = []
    for p in map(Path, paths):
        if p.is_file() or p.is_symlink():
            p.unlink()
            removed.append(p)
    return removed

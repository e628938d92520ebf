"""The text of the node's service answers (``std_srvs/Trigger``: ``success`` + ``message``).

Plain functions of the session's results, so that they are tested without ROS and can be
extended (a verdict line in front, more parts behind) without touching the node. A message is
``; ``-separated parts, the first saying what happened; every part that names a written file or
directory names it absolutely, so a user of ``ros2 service call`` knows where to look whatever the
node's working directory.
"""

from __future__ import annotations

import os
from pathlib import Path

from .outcomes import SolveOutcome

__all__ = [
    "output_directory",
    "should_publish_tf",
    "calibrate_message",
    "save_dataset_message",
    "save_on_shutdown",
    "RESET_MESSAGE",
]

#: Answer of ``~/reset``.
RESET_MESSAGE = "session reset: poses, pairs and counters cleared (camera intrinsics kept)"


def _absolute(path: str | Path) -> str:
    return os.path.abspath(os.fspath(path))


def output_directory(outcome: SolveOutcome) -> str | None:
    """The absolute directory that received the files of ``outcome`` (None if none were
    written)."""
    path = outcome.files.get("result") or next(iter(outcome.files.values()), None)
    return None if path is None else _absolute(Path(path).parent)


def should_publish_tf(outcome: SolveOutcome, output) -> bool:
    """Whether the estimates of ``outcome`` go on ``/tf_static``: ``output.publish_tf`` and a
    solution that is certified, or any solution with ``output.publish_uncertified``
    (``output`` is an :class:`~rwhec_ros.config.OutputConfig`)."""
    if not (outcome.success and outcome.result is not None and output.publish_tf):
        return False
    return bool(outcome.result.certified or output.publish_uncertified)


def calibrate_message(outcome: SolveOutcome, output, *, published: bool,
                      left_out: dict[str, str] | None = None) -> str:
    """The ``calibrate`` answer: the session's summary (the verdict first, or why there is no
    solution), then the frames left off ``/tf_static`` because the verdict finds them unusable,
    then whether the estimates were withheld from ``/tf_static``, then the absolute output
    directory (``files in <dir>``).

    Parameters
    ----------
    outcome : SolveOutcome
        What :meth:`CalibrationSession.calibrate` returned.
    output : OutputConfig
        The configuration's ``output`` section (``publish_tf``, ``publish_uncertified``).
    published : bool
        Whether the node sent the estimates to ``/tf_static``.
    left_out : dict of str to str, optional
        Frames not published because they are not usable, and why
        (:meth:`CalibrationSession.left_out`).
    """
    parts = [outcome.message]
    if published and left_out:
        parts.append("left off /tf_static (not usable): " + ", ".join(
            f"{name} ({why})" for name, why in left_out.items()))
    if outcome.success and output.publish_tf and not published:
        parts.append("not published on /tf_static (not certified; "
                     "output.publish_uncertified is false)")
    directory = output_directory(outcome)
    if directory is not None:
        parts.append(f"files in {directory}")
    return "; ".join(parts)


def save_dataset_message(path: str | Path) -> str:
    """The ``save_dataset`` answer naming the written data set absolutely."""
    return f"data set written: {_absolute(path)}"


def save_on_shutdown(session, logger) -> str | None:
    """At the node's shutdown (Ctrl-C, SIGTERM): write the pairs no ``~/save_dataset`` or
    ``calibrate`` wrote (:meth:`CalibrationSession.unsaved_pairs`) as a new data set under the
    output root (the ``~/save_dataset`` path), and log where with ``logger.info`` (a failure
    with ``logger.error``: the pairs are lost then, and the log says why). Returns the path
    written, or None. Never raises: a shutdown must go on."""
    try:
        n = session.unsaved_pairs()
        if not n:
            return None
        path = session.save_dataset()
    except Exception as exc:  # noqa: BLE001 - the shutdown goes on, the log says what was lost
        logger.error(f"shutdown: the unsaved pairs could not be written ({type(exc).__name__}: "
                     f"{exc})")
        return None
    logger.info(f"shutdown: {n} unsaved pairs written: {_absolute(path)} (solve them with "
                f"rwhec-calibrate dataset {_absolute(path)})")
    return str(path)

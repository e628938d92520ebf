"""Images lost for want of a pose, per camera and in all, for ``/diagnostics`` (plain Python).

Issue 39: on a real transport most images were rejected ``no_pose_at_stamp:after_buffer`` while
the session row stayed OK. Images now wait for late poses (:mod:`rwhec_ros.session.image_wait`),
and whatever still finally has no pose is counted by cause; :class:`NoPoseWindow` turns those
counts into a warning: a camera (or the session, all cameras together) whose images more than
``warn_fraction`` (5 %: "a few percent") had no pose over the last ``reports`` reports (10 s at
the node's 1 Hz) gets a WARN naming the share, the main cause and the parameter to look at
(:data:`~rwhec_ros.session.image_wait.NO_POSE_CAUSES`).
"""

from __future__ import annotations

import collections
from collections.abc import Mapping, Sequence
from typing import Any

from ..messages import LEVEL_WARN
from .image_wait import NO_POSE_CAUSES

__all__ = ["NoPoseWindow", "NO_POSE_WARN_FRACTION", "warn_row"]

#: Share of a camera's (or all) images without a pose above which its row is a WARN.
NO_POSE_WARN_FRACTION = 0.05


class NoPoseWindow:
    """Shares of images without a pose over the last ``reports`` calls of :meth:`update`.

    Parameters
    ----------
    cameras : sequence of str
    reports : int
        Reports the window spans (>= 1).
    warn_fraction : float
        Share above which :meth:`problem` answers.
    min_images : int
        Fewer images in the window say nothing (a share of 1 in 3 is no finding).
    """

    def __init__(self, cameras: Sequence[str], *, reports: int = 10,
                 warn_fraction: float = NO_POSE_WARN_FRACTION, min_images: int = 20) -> None:
        if not (isinstance(reports, int) and reports >= 1):
            raise ValueError(f"reports: expected an integer >= 1, got {reports!r}")
        if not 0.0 < warn_fraction < 1.0:
            raise ValueError(f"warn_fraction: expected a value in (0, 1), got {warn_fraction!r}")
        self.cameras = tuple(cameras)
        self.warn_fraction = float(warn_fraction)
        self.min_images = int(min_images)
        zero = {c: (0, collections.Counter()) for c in self.cameras}
        self._snapshots: collections.deque = collections.deque([zero], maxlen=reports + 1)

    def update(self, received: Mapping[str, int],
               no_pose: Mapping[str, Mapping[str, int]]) -> None:
        """The counts so far: images received per camera, and per camera the images that
        finally had no pose, by cause (:meth:`~rwhec_ros.session.CalibrationSession.
        no_pose_counts`)."""
        self._snapshots.append({c: (int(received.get(c, 0)),
                                    collections.Counter(dict(no_pose.get(c, {}))))
                                for c in self.cameras})

    def _window(self, cameras: Sequence[str]) -> tuple[int, collections.Counter]:
        """Images received and without a pose by cause, over the window, of ``cameras``."""
        first, last = self._snapshots[0], self._snapshots[-1]
        n, causes = 0, collections.Counter()
        for c in cameras:
            n += last[c][0] - first[c][0]
            causes.update({k: v - first[c][1].get(k, 0) for k, v in last[c][1].items()})
        return n, +causes

    def problem(self, camera: str | None = None) -> str:
        """Why ``camera`` (None: all cameras) is a WARN, or ``""``: e.g. ``12 % of the images
        (37 of 300 over the last 10 reports) had no pose at their stamp, mostly wait_timeout:
        the pose stream lagged the image by more than sync.max_pose_wait_s (see
        sync.max_pose_wait_s, docs/ros-transport.md)``."""
        n, causes = self._window(self.cameras if camera is None else [camera])
        lost = sum(causes.values())
        if n < self.min_images or lost <= self.warn_fraction * n:
            return ""
        cause, count = causes.most_common(1)[0]
        what, parameter = NO_POSE_CAUSES.get(cause, (cause, "sync.max_pose_wait_s"))
        others = ", ".join(f"{k} {v}" for k, v in causes.most_common()[1:])
        return (f"{100 * lost / n:.0f} % of the images ({lost} of {n} over the last "
                f"{len(self._snapshots) - 1} reports) had no pose at their stamp, mostly {cause} "
                f"({count}): {what} (see {parameter}, docs/ros-transport.md)"
                + (f"; also {others}" if others else ""))


def warn_row(row: dict[str, Any], problem: str) -> dict[str, Any]:
    """``row`` (a ``/diagnostics`` row dict) raised to at least WARN with ``problem`` first in its
    message (unchanged when ``problem`` is empty)."""
    if not problem:
        return row
    return {**row, "level": max(row["level"], LEVEL_WARN),
            "message": f"{problem}; {row['message']}"}

"""Images that arrive a little before their camera's first CameraInfo: held briefly, not dropped.

A recorder or a driver often publishes the first image a few milliseconds before the first
``CameraInfo`` of the same camera. Without intrinsics the session must reject that image; this
small buffer holds such images per camera (at most ``max_wait_ns`` of stamps and ``max_images``
images) and hands them back once the camera's intrinsics are there, or, when they wait too long,
so that the session rejects and counts them (never a silent loss).
"""

from __future__ import annotations

import collections
from collections.abc import Iterator
from typing import Any

__all__ = ["CameraInfoWait"]


class CameraInfoWait:
    """Per-camera queue of items waiting for a CameraInfo.

    Parameters
    ----------
    max_wait_ns : int
        An item older than this [ns] (by stamp, relative to the newest stamp seen) is released
        to be processed anyway (and rejected by the session without intrinsics).
    max_images : int
        At most this many items per camera; the oldest is released first.
    """

    def __init__(self, max_wait_ns: int = 500_000_000, max_images: int = 20) -> None:
        if max_wait_ns < 0 or max_images < 1:
            raise ValueError(f"max_wait_ns >= 0 and max_images >= 1 required, got "
                             f"{max_wait_ns!r} and {max_images!r}")
        self.max_wait_ns = int(max_wait_ns)
        self.max_images = int(max_images)
        self._queues: dict[str, collections.deque] = {}

    def __len__(self) -> int:
        return sum(len(q) for q in self._queues.values())

    def hold(self, camera: str, stamp_ns: int, item: Any) -> list[Any]:
        """Hold ``item``; returns the items that must be processed now (too old, too many)."""
        q = self._queues.setdefault(camera, collections.deque())
        q.append((int(stamp_ns), item))
        out = []
        while len(q) > self.max_images or q[0][0] < int(stamp_ns) - self.max_wait_ns:
            out.append(q.popleft()[1])
        return out

    def release(self, camera: str) -> list[Any]:
        """Every item held for ``camera`` (its CameraInfo arrived), oldest first."""
        q = self._queues.pop(camera, collections.deque())
        return [item for _, item in q]

    def drain(self) -> Iterator[tuple[str, Any]]:
        """``(camera, item)`` for every item still held (end of the data), oldest first per
        camera."""
        for camera in list(self._queues):
            for item in self.release(camera):
                yield camera, item

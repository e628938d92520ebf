"""Rejected data in words: what was thrown away wholesale, and why, with the numbers.

The session counts every rejection by reason (:meth:`CalibrationSession.counters`); a counter
alone does not tell a user that *every* image of a camera was rejected because the images are
1280x960 while the CameraInfo says 640x480. :class:`RejectionLog` keeps, per reason and camera
(or pose frame), how many items were rejected and one example of why, and
:meth:`RejectionLog.sentences` turns them into sentences such as
``all 599 images of cam0 rejected: 1280x960 images, CameraInfo says 640x480``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["RejectionLog"]

#: What each reason means, for the sentences.
_WHAT = {
    "image_size_mismatch": "images",
    "image_missing_camera_info": "images",
    "image_not_gray_uint8": "images",
    "pose_rejected_frame_id": "poses",
}


@dataclass
class RejectionLog:
    """Per-source counts of inputs and of rejections with an example reason (not thread-safe:
    the session calls it with its lock held).

    Attributes
    ----------
    seen : dict of (str, str) to int
        ``("images", camera)`` / ``("poses", "")`` -> items received.
    rejected : dict of (str, str) to list
        ``(reason, source)`` -> ``[count, text]``: the source is a camera name or a pose frame;
        ``text`` describes the first case in words.
    """

    seen: dict[tuple[str, str], int] = field(default_factory=dict)
    rejected: dict[tuple[str, str], list] = field(default_factory=dict)

    def saw(self, what: str, source: str = "") -> None:
        key = (what, source)
        self.seen[key] = self.seen.get(key, 0) + 1

    def reject(self, reason: str, source: str, text: str) -> None:
        entry = self.rejected.setdefault((reason, source), [0, text])
        entry[0] += 1

    def clear(self) -> None:
        self.seen.clear()
        self.rejected.clear()

    def sentences(self, *, min_share: float = 0.5) -> list[str]:
        """Every rejection that hit at least ``min_share`` of its source's inputs, in words:
        ``all 599 images of cam0 rejected: ...`` or ``412 of 599 images of cam0 ...``."""
        out = []
        for (reason, source), (count, text) in sorted(self.rejected.items()):
            what = _WHAT.get(reason, "items")
            total = self.seen.get((what, source if what == "images" else ""), 0)
            if total and count < min_share * total:
                continue
            share = f"all {count:,}" if total and count >= total else \
                f"{count:,} of {total:,}" if total else f"{count:,}"
            of = f" of {source}" if what == "images" else ""
            out.append(f"{share} {what}{of} rejected: {text}")
        return out

"""``--detections DIR``: the images searched, with what was detected drawn on them.

The CLI's counterpart of the node's ``~/detections`` topic (:func:`rwhec_ros.vision.annotate.
annotate_detections`: a target kept as a pair green with the corners used, anything refused
orange with the reason), written as ``DIR/<camera>_<name>.jpg`` where ``name`` is the view's
index and image file stem (``samples``) or the image stamp in nanoseconds (``bag``). Only
images the detector searched are drawn (an image the motion gate skipped, or refused before
its pixels were read, has nothing to show). Called from the detection threads: each call
writes its own file.
"""

from __future__ import annotations

import re
import threading
from pathlib import Path

import cv2

from ..vision.annotate import annotate_detections

__all__ = ["DetectionImages", "detection_images"]


class DetectionImages:
    """Write annotated images into ``directory`` (created); :attr:`written` counts them and
    :attr:`failed` holds the first write error (a full disk must not stop the calibration)."""

    def __init__(self, directory: Path) -> None:
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.written = 0
        self.failed = ""
        self._lock = threading.Lock()

    def __call__(self, camera: str, name: str | int, outcome) -> None:
        """Draw ``outcome`` (an :class:`~rwhec_ros.session.outcomes.ImageOutcome`) of an image of
        ``camera`` called ``name``; nothing when it holds no searched image."""
        if outcome is None or outcome.image is None or outcome.detection is None:
            return
        bgr = annotate_detections(outcome.image, outcome.detection, outcome.kept,
                                  title=f"{camera} {name}")
        safe = re.sub(r"[^A-Za-z0-9_.-]+", "_", f"{camera}_{name}")
        path = self.directory / f"{safe}.jpg"
        try:
            if not cv2.imwrite(str(path), bgr):
                raise OSError(f"cv2.imwrite could not write {path}")
            with self._lock:
                self.written += 1
        except (OSError, cv2.error) as exc:
            with self._lock:
                self.failed = self.failed or str(exc)

    def line(self) -> str:
        """The summary line: how many images were drawn where, or why not."""
        words = f"detections: {self.written} annotated image(s) in {self.directory}"
        return words + (f" (writing failed: {self.failed})" if self.failed else "")


def detection_images(args) -> DetectionImages | None:
    """The writer of ``args.detections`` (None when not asked for; ``check`` has no such
    option)."""
    directory = getattr(args, "detections", None)
    return None if directory is None else DetectionImages(directory)

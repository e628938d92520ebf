"""A second look, with the estimate's predicted pose, at the views the first search could not label.

Two detections are refused while nothing predicts the target's pose -- never a flipped or a
shifted view:

* a single tag whose two planar poses reproject alike (``ambiguous_pose``,
  :mod:`rwhec_ros.vision.planar_pose`: a small or distant tag, a compressed image);
* a part of a plain chessboard, ambiguous by whole squares (``partial_view``,
  :mod:`rwhec_ros.vision.grid_detection`: a large board on a real arm is often seen in part).

The detector resolves both with a predicted ``T_cam_target`` where it singles one solution out
(its own margins: the nearer IPPE pose at most ``flip_prediction_margin`` of the other's angle
from the prediction; the nearer labelling within a third of a square, the next twice as far).
The session holds the images of such refusals (the newest :data:`SECOND_LOOK_IMAGES` per camera,
as their undecoded sources) and, after a solve whose verdict is not unusable, looks at them again
with the prediction of that estimate,

    T_cam_target = Y_c^-1 A X_t   (the pair's ``A`` at the image stamp; paper eq. 1 read for
                                    ``B``), translation times the scale where it is unknown,

keeps the pairs the edges keep (the keyframe test as for any pair), and solves again: the
result and its certificate are those of the data with the recovered views, the summary says how
many were recovered. A view recovered this way moves its image from the counter of its first
search (``images_targets_rejected:<reason>``, ``images_no_new_pairs``) to ``images_used`` and
its tag rejection to ``tags_resolved_by_prediction``: each image counted once, by what it gave.
"""

from __future__ import annotations

import collections
from dataclasses import dataclass

import numpy as np

from ..core.lie import invert_transform
from ..vision.detection import RejectReason
from .image_input import no_pair_counter

__all__ = ["SECOND_LOOK_IMAGES", "RESOLVABLE", "SecondLookMixin", "predicted_poses",
           "second_look_lines",
           "new_held_views"]

#: Images held per camera for the second look (the newest): references to the undecoded
#: sources (a bag message, a file reader) or the arrays given.
SECOND_LOOK_IMAGES = 32
#: The refusals a predicted pose can resolve.
RESOLVABLE = frozenset({RejectReason.AMBIGUOUS_POSE.value, RejectReason.PARTIAL_VIEW.value})


@dataclass
class HeldView:
    """One image held for the second look: where it was, what it was counted as."""

    camera: str
    stamp: int
    A: np.ndarray
    image: object
    intrinsics: object
    targets: tuple[str, ...]
    reasons: tuple[str, ...]  # the refusals of ``targets``, in order
    counted: str  # the image counter of its first search


def new_held_views() -> collections.defaultdict:
    """The session's store of held views: camera -> deque of :class:`HeldView`."""
    return collections.defaultdict(lambda: collections.deque(maxlen=SECOND_LOOK_IMAGES))


def predicted_poses(result, camera: str, A: np.ndarray, targets) -> dict[str, np.ndarray]:
    """``T_cam_target`` (4, 4) predicted by ``result`` (a :class:`~rwhec_ros.core.result.
    CalibrationResult`, metric ``X``, ``Y``) for each of ``targets`` it has, seen by ``camera``
    at the pair pose ``A`` (``T_<camera carrier>_<tag carrier>``): ``Y^-1 A X`` with the
    translation times the scale (``B``'s translation is in the tags' units: a target
    ``1/scale`` of its configured size is seen at ``scale`` times the metric distance)."""
    if camera not in result.y_names:
        return {}
    alpha = float(result.scale) if np.isfinite(result.scale) and result.scale > 0 else 1.0
    Y_inv = invert_transform(result.transform(camera))
    out = {}
    for t in targets:
        if t in result.x_names:
            T = Y_inv @ np.asarray(A, dtype=float) @ result.transform(t)
            T[:3, 3] *= alpha
            out[t] = T
    return out


class SecondLookMixin:
    """The second look of the module docstring; mixed into
    :class:`~rwhec_ros.session.CalibrationSession` (its lock, counters, detector and
    accumulator). ``self._held_views`` is the store of :func:`new_held_views`."""

    def _hold_for_second_look(self, camera: str, stamp: int, image, intrinsics,
                              A: np.ndarray, detection, outcome) -> None:
        """Hold the image of a search whose configured targets were refused for a reason a
        predicted pose resolves, where their edges would keep a pair (lock NOT held)."""
        refused = [(r.name, r.reason) for r in detection.rejections
                   if r.reason in RESOLVABLE and r.name]
        if not refused:
            return
        counted = ("images_used" if outcome.status == "used" else
                   "images_no_new_pairs" if outcome.status == "no_new_pairs" else
                   no_pair_counter(detection))
        with self._lock:
            wanted = [(n, r) for n, r in refused
                      if self._acc.would_keep(n, camera, stamp, A)]
            if wanted:
                self._held_views[camera].append(HeldView(
                    camera, stamp, np.array(A, dtype=float), image, intrinsics,
                    tuple(n for n, _ in wanted), tuple(r for _, r in wanted), counted))

    def held_views(self) -> int:
        """How many images wait for the second look."""
        with self._lock:
            return sum(len(q) for q in self._held_views.values())

    def second_look(self, result) -> tuple[int, int]:
        """Look again at the held images with ``result``'s predicted poses (module docstring);
        ``(images looked at, pairs kept)``. The held images are let go either way."""
        with self._lock:
            items = [v for q in self._held_views.values() for v in q]
            self._held_views.clear()
        looked = kept_total = 0
        for v in items:
            predicted = predicted_poses(result, v.camera, v.A, v.targets)
            if not predicted:
                continue
            gray, *_ = self._decoded(v.image, v.intrinsics)
            if gray is None:
                continue
            with self._lock:
                history = tuple(self._corner_noise[v.camera])
            try:
                detection = self._detector().detect(gray, v.intrinsics, predicted,
                                                    only=list(predicted), noise_history=history)
            except Exception:  # noqa: BLE001 - the session never raises for bad data
                continue
            looked += 1
            obs = [o for o in detection.observations if o.name in predicted]
            with self._lock:
                self._count("second_look_images")
                names = self._offer(v.camera, v.stamp, v.A, obs)
                kept_total += len(names)
                self._recount(v, names)
        return looked, kept_total

    def _recount(self, view: HeldView, names: list[str]) -> None:
        """Move the counters of ``view``'s first search to what its second look gave (lock
        held; module docstring)."""
        if not names:
            return
        self._camera_count(view.camera, "pairs_kept", len(names))
        for name, reason in zip(view.targets, view.reasons, strict=True):
            if name in names and self._uncount(f"tag_rejected:{reason}"):
                self._count("tags_resolved_by_prediction")
                self._count("tags_detected")
        if view.counted != "images_used" and self._uncount(view.counted):
            self._count("images_used")
            self._camera_count(view.camera, "used")

    def _uncount(self, key: str) -> bool:
        """Take one off counter ``key`` (gone at zero); False when it was not counted."""
        if self._counters.get(key, 0) <= 0:
            return False
        self._counters[key] -= 1
        if not self._counters[key]:
            del self._counters[key]
        return True


def second_look_lines(looked: tuple[int, int] | None) -> list[str]:
    """The summary's line on the second look (none when it did not run)."""
    if not looked or not looked[0]:
        return []
    images, pairs = looked
    return [f"second look: {images} image(s) whose target was refused as ambiguous (a tag's "
            f"two poses, a part of a chessboard) looked at again with the estimate's predicted "
            f"pose: {pairs} pair(s) kept, solved again with them"]

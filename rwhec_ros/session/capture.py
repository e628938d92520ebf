"""Take a view now: the ``~/capture`` service of an arm driven through poses (no rclpy here).

``capture.mode`` chooses which images become candidate views:

* ``continuous`` (default): every image, kept by the keyframe test as it comes (``~/capture`` is
  refused with a hint);
* ``capture``: only the images a capture takes; the others are neither decoded nor searched
  (counted ``images_not_captured``);
* ``both``: every image, and a capture also takes one image per camera now.

The capture rule: a request (:meth:`CaptureGate.request`) takes, for every camera, the first of
its images that reaches the session's image path after the request and whose pose has been **at
rest for** ``capture.rest_s``: the poses at that camera's images agree with the pose of this
image (within ``sync.at_rest_translation_m`` and ``sync.at_rest_rotation_rad``,
:func:`~rwhec_ros.sync.at_rest.same_pose`) back to an image stamped at least ``rest_s`` before
it. The poses come from the pose source at each image stamp (the pose buffer, or tf), so the rule
needs no second look at the pose stream and holds for both ``pose_source.type`` values. A taken
image is searched for every target (the motion gate does not apply, so the answer says what the
camera saw) and its pairs are offered like any other: the keyframe test still applies, and a
view too close to an edge's last kept pair is not kept (the answer says so: move further).

:class:`CaptureResult` holds per camera the :class:`~rwhec_ros.session.outcomes.ImageOutcome`
of the taken image (or why none was taken) and the identifiability of every edge after it;
:func:`capture_message` is the service's answer. The session side is
:class:`~rwhec_ros.session.live.CalibrationSession.capture` (``request_capture`` /
``finish_capture`` for callers that feed the images themselves, e.g. tests).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..sync.at_rest import AtRestRule, same_pose
from .outcomes import ImageOutcome

__all__ = ["CaptureGate", "CaptureMixin", "CaptureRequest", "CaptureResult", "capture_message",
           "seen_words", "NOT_CAPTURED"]

_NS_PER_S = 1_000_000_000

#: :meth:`CaptureGate.decide`'s answer for an image that capture-only mode leaves out.
NOT_CAPTURED = "not_captured"


class CaptureRequest:
    """One capture: the cameras it waits for, what each delivered, an event when complete.

    Parameters
    ----------
    cameras : sequence of str
        The configuration's cameras.
    after_ns : int or None
        Only images stamped at or after this [ns] are taken (None: any image that reaches the
        image path after the request).
    """

    def __init__(self, cameras, after_ns: int | None = None) -> None:
        self.cameras = tuple(cameras)
        self.after_ns = None if after_ns is None else int(after_ns)
        self.claimed: set[str] = set()
        self.views: dict[str, ImageOutcome] = {}
        self.rest_ns: dict[str, int] = {}
        self._event = threading.Event()
        self._lock = threading.Lock()

    def wants(self, camera: str, stamp_ns: int) -> bool:
        """True while ``camera`` has not been taken and ``stamp_ns`` is recent enough."""
        return (camera in self.cameras and camera not in self.claimed
                and (self.after_ns is None or stamp_ns >= self.after_ns))

    def deliver(self, camera: str, outcome: ImageOutcome) -> None:
        """The outcome of the image taken for ``camera``."""
        with self._lock:
            self.views[camera] = outcome
            if len(self.views) == len(self.cameras):
                self._event.set()

    def wait(self, timeout_s: float | None) -> bool:
        """Wait until every camera delivered (True) or ``timeout_s`` passed (False)."""
        return self._event.wait(timeout_s)

    @property
    def complete(self) -> bool:
        return self._event.is_set()


@dataclass
class _Rest:
    """Per camera: the pose the current rest started at, its stamp, and the latest image."""

    A: np.ndarray | None = None
    since_ns: int = 0
    last_ns: int | None = None
    last_rest_ns: int = 0


class CaptureGate:
    """Which images are candidate views, and which a capture takes (module docstring).

    Not thread-safe: the session calls it under its lock.
    """

    def __init__(self) -> None:
        self._rest: dict[str, _Rest] = {}
        self._requests: list[CaptureRequest] = []

    def forget(self) -> None:
        """Forget the rest state (a session reset); pending requests stay."""
        self._rest.clear()

    def request(self, cameras, after_ns: int | None = None) -> CaptureRequest:
        req = CaptureRequest(cameras, after_ns)
        self._requests.append(req)
        return req

    def cancel(self, req: CaptureRequest) -> None:
        if req in self._requests:
            self._requests.remove(req)

    def _at_rest_ns(self, camera: str, stamp_ns: int, A: np.ndarray, rule: AtRestRule) -> int:
        """How long [ns] the poses of ``camera``'s images have agreed with ``A`` up to
        ``stamp_ns`` (0 at the first image of a new rest)."""
        r = self._rest.setdefault(camera, _Rest())
        if r.A is None or stamp_ns < (r.last_ns or 0) or not same_pose(r.A, A, rule):
            r.A, r.since_ns = np.array(A, dtype=float), stamp_ns
        r.last_ns = stamp_ns
        r.last_rest_ns = stamp_ns - r.since_ns
        return r.last_rest_ns

    def decide(self, camera: str, stamp_ns: int, A: np.ndarray, config
               ) -> list[CaptureRequest] | str | None:
        """What to do with an image of ``camera`` at ``stamp_ns`` whose pose is ``A``: the
        pending requests that take it (examine it without the motion gate and deliver the
        outcome to each), :data:`NOT_CAPTURED` (capture-only mode: leave it out) or None (the
        ordinary path)."""
        capture = config.capture
        if capture.mode == "continuous":  # the live path as it was: no rest tracking at all
            return None
        rest = self._at_rest_ns(camera, stamp_ns, A, AtRestRule.from_sync(config.sync))
        if rest >= int(round(capture.rest_s * _NS_PER_S)):
            takers = [req for req in self._requests if req.wants(camera, stamp_ns)]
            for req in takers:
                req.claimed.add(camera)
                req.rest_ns[camera] = rest
            if takers:
                return takers
        return NOT_CAPTURED if capture.mode == "capture" else None

    def why_not(self, camera: str, rest_s: float) -> str:
        """Why no image of ``camera`` was taken (for the answer), from its rest state."""
        r = self._rest.get(camera)
        if r is None or r.last_ns is None:
            return "no image with a pose reached the calibrator"
        return (f"its pose was not at rest for {rest_s:g} s (at rest "
                f"{r.last_rest_ns / _NS_PER_S:.2f} s at its latest image, stamp "
                f"{r.last_ns / _NS_PER_S:.3f} s)")


@dataclass
class CaptureResult:
    """What one capture took.

    Attributes
    ----------
    views : dict of str to ImageOutcome
        Per camera that delivered, the outcome of its taken image (``status``, ``kept``
        targets, ``detection`` with every observation and rejection).
    missing : dict of str to str
        Per camera that delivered nothing within the timeout, why.
    rest_s : dict of str to float
        Per taken camera, how long its pose had been at rest [s].
    edges : list of dict
        Every observed edge after the capture (:meth:`CalibrationSession.diagnostics`:
        ``x``, ``y``, ``pairs``, ``status``, ``identifiable``, ``reasons``).
    identifiable : bool or None
        The whole problem's identifiability after the capture (None before any pair).
    verdict : str
        The identifiability report's verdict in words (empty before any pair).
    refused : str
        Non-empty when no capture was made (e.g. ``capture.mode`` is ``continuous``).
    keyframe : tuple of float
        ``(keyframe.min_rotation_rad, keyframe.min_translation_m)`` for the answer.
    """

    views: dict[str, ImageOutcome] = field(default_factory=dict)
    missing: dict[str, str] = field(default_factory=dict)
    rest_s: dict[str, float] = field(default_factory=dict)
    edges: list[dict[str, Any]] = field(default_factory=list)
    identifiable: bool | None = None
    verdict: str = ""
    refused: str = ""
    keyframe: tuple[float, float] = (0.0, 0.0)

    @property
    def pairs_kept(self) -> int:
        return sum(len(o.kept) for o in self.views.values())

    @property
    def success(self) -> bool:
        """Every camera took an image (whether or not it gave pairs)."""
        return not self.refused and not self.missing and bool(self.views)


def seen_words(outcome: ImageOutcome, keyframe: tuple[float, float]) -> str:
    """What one camera saw in a searched image, in words: every target with its corners, RMS
    and whether its pair was kept (``keyframe``: the thresholds, for the words), every
    rejection with its reason; or why the image was not searched."""
    if outcome.status == "rejected":
        detail = f" ({outcome.detail})" if outcome.detail else ""
        return f"image rejected: {', '.join(outcome.reasons)}{detail}"
    if outcome.status in ("skipped", "pending"):
        return f"image {outcome.status} ({', '.join(outcome.reasons) or 'motion gate'})"
    det = outcome.detection
    parts = []
    if det is not None:
        for o in det.observations:
            corners = int(np.asarray(o.image_points).shape[0])
            fate = ("pair kept" if o.name in outcome.kept else
                    f"pair not kept (keyframe test: within {keyframe[0]:g} rad and "
                    f"{keyframe[1]:g} m of this edge's last kept pair, or the edge is full: "
                    "move further)")
            parts.append(f"{o.name} {corners} corners, {o.reprojection_rms_px:.2f} px rms: {fate}")
        for r in det.rejections:
            what = r.name or (f"marker {r.marker_id}" if r.marker_id >= 0 else "a marker")
            parts.append(f"{what} rejected ({r.reason}{': ' + r.detail if r.detail else ''})")
    if not parts:
        return "no target seen"
    return "; ".join(parts)


def capture_message(result: CaptureResult) -> str:
    """The ``~/capture`` answer: one line saying what happened, one per camera (what it saw:
    targets with their corners and whether the pair was kept, rejections with the reason), then
    the identifiability of every edge after the capture."""
    if result.refused:
        return result.refused
    n = len(result.views) + len(result.missing)
    lines = [f"capture: {len(result.views)} of {n} cameras took a view at rest, "
             f"{result.pairs_kept} pairs kept"]
    for cam, outcome in result.views.items():
        stamp = "" if outcome.stamp_ns is None else f"image at {outcome.stamp_ns / 1e9:.3f} s, "
        lines.append(f"{cam} ({stamp}at rest {result.rest_s.get(cam, 0.0):.2f} s): "
                     f"{seen_words(outcome, result.keyframe)}")
    for cam, why in result.missing.items():
        lines.append(f"{cam}: no view ({why})")
    if result.edges:
        head = ("identifiability: " + ("identifiable" if result.identifiable else
                                      "not yet identifiable")
                + (f" ({result.verdict})" if result.verdict else ""))
        lines.append(head)
        for e in result.edges:
            ident = {True: "identifiable", False: "not identifiable", None: "unknown"}[
                e["identifiable"]]
            why = f": {'; '.join(e['reasons'])}" if e["reasons"] else ""
            lines.append(f"  ({e['x']}, {e['y']}): {e['pairs']} pairs, {e['status']}, "
                         f"{ident}{why}")
    else:
        lines.append("identifiability: no pair yet")
    return "\n".join(lines)


class CaptureMixin:
    """Mixin of :class:`~rwhec_ros.session.CalibrationSession`: the capture requests (module
    docstring). Uses the session's ``_lock``, ``_capture`` (a :class:`CaptureGate`),
    ``config``, :meth:`diagnostics` and :meth:`report`."""

    def request_capture(self, after_ns: int | None = None) -> CaptureRequest:
        """Arm a capture: each camera's next image at rest is taken (module docstring).

        Raises ``ValueError`` when ``capture.mode`` is ``continuous`` (the message says how to
        change it). Finish it with :meth:`finish_capture`.
        """
        mode = self.config.capture.mode
        if mode == "continuous":
            raise ValueError(
                "capture.mode is 'continuous': every image is already a candidate view; set "
                "capture.mode to 'capture' (only captured views) or 'both', e.g. ros2 param set "
                "<node> capture.mode both")
        with self._lock:
            return self._capture.request(self.config.camera_names, after_ns)

    def finish_capture(self, request: CaptureRequest) -> CaptureResult:
        """Stop ``request`` and describe what it took (cameras without an image say why)."""
        with self._lock:
            self._capture.cancel(request)
            missing = {cam: self._capture.why_not(cam, self.config.capture.rest_s)
                       for cam in request.cameras if cam not in request.views}
            rest = {cam: ns / _NS_PER_S for cam, ns in request.rest_ns.items()}
        for cam in list(missing):  # claimed but still being searched: wait is over, say so
            if cam in request.claimed and cam not in request.views:
                missing[cam] = "its image was still being searched when the capture timed out"
        report = self.report()
        kf = self.config.keyframe
        return CaptureResult(
            views={c: request.views[c] for c in request.cameras if c in request.views},
            missing=missing, rest_s=rest, edges=self.diagnostics(),
            identifiable=None if report is None else bool(report.identifiable),
            verdict="" if report is None else str(report.verdict),
            keyframe=(kf.min_rotation_rad, kf.min_translation_m))

    def capture(self, timeout_s: float | None = None, *, after_ns: int | None = None
                ) -> CaptureResult:
        """Take one view now and wait for it (the ``~/capture`` service; blocks the caller up
        to ``timeout_s``, default ``capture.timeout_s``). Never raises: a refusal is
        :attr:`CaptureResult.refused`."""
        try:
            request = self.request_capture(after_ns)
        except ValueError as exc:
            return CaptureResult(refused=str(exc))
        request.wait(self.config.capture.timeout_s if timeout_s is None else timeout_s)
        return self.finish_capture(request)

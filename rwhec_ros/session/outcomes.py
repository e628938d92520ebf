"""What the session answers: per image, per solve, and per edge (for /diagnostics)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..core.result import CalibrationResult
from ..core.verdict import Verdict

__all__ = ["ImageOutcome", "SolveOutcome", "edge_statuses", "edge_rows", "no_pairs_words",
           "too_few_pairs_words"]


@dataclass
class ImageOutcome:
    """What happened to one image.

    Attributes
    ----------
    camera : str
    stamp_ns : int
        The image's time on the pose stream's clock (its stamp plus
        ``sync.time_offset.<camera>``; the camera's own: ``ImageInput.image_time``).
    status : str
        ``"used"`` (at least one pair kept), ``"no_new_pairs"`` (tags seen, pose found, but no
        pair passed the keyframe test), ``"no_tags"``, ``"skipped"`` (motion gate: no edge of
        the camera would keep a pair at this pose, so the image was neither decoded nor
        searched), ``"pending"`` (the image waits for a pose newer than its stamp) or
        ``"rejected"``.
    observations : int
        Accepted tag detections.
    pairs_kept : int
        Pairs the accumulator kept.
    reasons : list of str
        Counter keys of every rejection in this image.
    detail : str
        What was wrong, for a rejection with more to say than its key (e.g. why the data could
        not be decoded).
    detection : TargetDetectionResult or None
        What the detector found in the image (None when it was not searched): drawn by
        :func:`rwhec_ros.vision.annotate.annotate_detections`.
    kept : tuple of str
        Targets whose pair was kept.
    image : ndarray (H, W) uint8 or None
        The decoded image that was searched (not a copy; None when it was not searched).
    """

    camera: str
    stamp_ns: int | None
    status: str
    observations: int = 0
    pairs_kept: int = 0
    reasons: list[str] = field(default_factory=list)
    detail: str = ""
    detection: Any = None
    kept: tuple[str, ...] = ()
    image: Any = None


@dataclass
class SolveOutcome:
    """Answer of :meth:`CalibrationSession.calibrate`.

    Attributes
    ----------
    success : bool
        A solution was computed (certified or not: see ``result.certified``). False when there
        were not enough data or the solver failed; the session keeps all its data either way.
    message : str
        The summary, one item per line: the verdict first, then the certificate (``rho_hat``),
        each frame's estimate (or NOT CALIBRATED), edges excluded and why (or the reason of the
        failure).
    result : CalibrationResult or None
    excluded : dict of str to str
        Edge ``"(x, y)"`` -> reason it was left out of the problem.
    files : dict of str to str
        ``result``, ``dataset``, ``launch`` -> written paths (empty on failure).
    identifiability : dict or None
        The identifiability report at the time of the solve (``IdentifiabilityReport.to_dict()``).
    result_yaml : str
        The text of the result YAML (also written to ``files["result"]``); empty on failure.
    verdict : Verdict or None
        Use the result or not, and why (:func:`rwhec_ros.core.verdict.assess`); None on failure.
    accuracy : Accuracy or None
        Per-frame uncertainty, cross-validation and guidance
        (:class:`~rwhec_ros.session.accuracy.Accuracy`); None on failure.
    write_error : str
        Why the outputs could not be written (in words, also the end of ``message``); empty
        when they were (or nothing was to be written).
    time_offsets : TimeOffsetReport or None
        Each camera's time offset to the pose stream
        (:class:`~rwhec_ros.session.time_offsets.TimeOffsetReport`); None on failure.
    """

    success: bool
    message: str
    result: CalibrationResult | None = None
    excluded: dict[str, str] = field(default_factory=dict)
    files: dict[str, str] = field(default_factory=dict)
    identifiability: dict | None = None
    result_yaml: str = ""
    verdict: Verdict | None = None
    accuracy: Any = None
    write_error: str = ""
    time_offsets: Any = None

    @property
    def usable(self) -> bool:
        """A result whose verdict is ``good`` or ``caution``."""
        return bool(self.success and self.verdict is not None and self.verdict.usable)


def edge_statuses(report) -> dict[tuple[str, str], tuple[str, bool | None, list[str]]]:
    """Per-edge ``(status, identifiable, reasons)`` from an IdentifiabilityReport."""
    if report is None:
        return {}
    out = {}
    for e in getattr(report, "edges", ()):
        x, y = getattr(e, "x", None), getattr(e, "y", None)
        status = getattr(e, "status", "unknown")
        status = getattr(status, "value", status)
        ident = getattr(e, "identifiable", None)
        reasons = getattr(e, "reasons", None)
        if reasons is None:
            reason = getattr(e, "reason", "")
            reasons = [reason] if reason else []
        out[(x, y)] = (str(status), None if ident is None else bool(ident), list(reasons))
    return out


def edge_rows(counts: dict[tuple[str, str], int], report,
              min_pairs: int) -> list[dict[str, Any]]:
    """One dict per observed edge: ``x``, ``y``, ``pairs``, ``status``, ``identifiable`` (bool,
    or None when unknown) and ``reasons`` (list of str), from the kept-pair ``counts`` and the
    identifiability ``report`` (or None); edges below ``min_pairs`` say so."""
    per_edge = edge_statuses(report)
    rows = []
    for (x, y), n in counts.items():
        status, ident, reasons = per_edge.get((x, y), ("unknown", None, []))
        reasons = list(reasons)
        if n < min_pairs:
            reasons.append(f"{n} pairs < solver.min_pairs={min_pairs}")
        rows.append(
            {"x": x, "y": y, "pairs": int(n), "status": status, "identifiable": ident,
             "reasons": reasons}
        )
    return rows


def no_pairs_words(counters: dict[str, int], searched: int, config,
                   rejections: list[str]) -> str:
    """Why a session holds no measurement pair, in words with the numbers and the parameter to
    check: data rejected wholesale (``rejections``), no image searched, or no target found in
    the ``searched`` images (``tags.family`` / ``tags.ids`` and the board targets named)."""
    if rejections:
        return "no measurement pairs: " + "; ".join(rejections)
    images = counters.get("images", 0)
    if not images:
        return ("no measurement pairs: no image arrived (check cameras.<name>.image_topic and "
                "image_transport)")
    if not searched:
        return (f"no measurement pairs: none of the {images} images was searched for tags "
                "(no pose at their stamps, or no camera info: see the counters)")
    if counters.get("tags_detected", 0) == 0:
        tags = config.tags
        what = [f"tags.family={tags.family} (ids {list(tags.ids)})"] if tags.ids else []
        what += [f"target {t.name} ({_target_kind(t)})" for t in config.target_specs()
                 if t.board is not None]
        return (f"no measurement pairs: no target was found in the {searched} images searched "
                f"(looked for {', '.join(what) or 'nothing'}); check tags.family, tags.ids and "
                "targets.* against the printed targets")
    return (f"no measurement pairs: {counters.get('tags_detected', 0)} tags detected in "
            f"{searched} images searched, none with a pose at its stamp kept (see the counters)")


def _target_kind(spec) -> str:
    board = spec.board
    kind = type(board).__name__.replace("Spec", "").lower()
    family = getattr(board, "family", None) or getattr(board, "dictionary", None)
    return f"{kind} {family}" if family else kind


def too_few_pairs_words(counts: dict[tuple[str, str], int], min_pairs: int,
                        parameter: str) -> str:
    """Not enough data: no edge has ``min_pairs`` pairs; the pairs per edge and the fix
    (``parameter``: how the user sets ``min_pairs``, e.g. ``solver.min_pairs`` or
    ``--min-pairs``)."""
    n = sum(counts.values())
    most = max(counts.values(), default=0)
    per_edge = ", ".join(f"({x}, {y}): {k}" for (x, y), k in sorted(
        counts.items(), key=lambda kv: -kv[1])[:5])
    more = f" and {len(counts) - 5} more edges" if len(counts) > 5 else ""
    fix = (f"lower {parameter} to {most} or record more" if most >= 1 and most < min_pairs
           else "record more")
    return (f"not enough data: no edge has {min_pairs} pairs ({parameter}={min_pairs}); "
            f"{n} pairs on {len(counts)} edges: {per_edge}{more}; {fix}")

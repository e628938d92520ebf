"""What the session answers: per image, per solve, and per edge (for /diagnostics)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..core.result import CalibrationResult
from ..core.verdict import Verdict

__all__ = ["ImageOutcome", "SolveOutcome", "edge_statuses", "edge_rows"]


@dataclass
class ImageOutcome:
    """What happened to one image.

    Attributes
    ----------
    camera : str
    stamp_ns : int
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

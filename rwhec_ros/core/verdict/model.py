"""What a verdict is made of: :class:`Reason`, :class:`FrameVerdict`, :class:`Verdict`, and the
:class:`Builder` that collects reasons and per-frame levels (see :mod:`.verdict`)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import asdict, dataclass, field
from typing import Any

from .fit import FitStatistics
from .options import VerdictOptions, level_rank, worst_level
from .scale_check import ScaleCheck

__all__ = ["Reason", "FrameVerdict", "Verdict", "Builder", "PRIORITY"]

#: Order of the reasons of one level: the most specific cause first.
PRIORITY = ("inputs", "certificate_failed", "not_identifiable", "excluded", "not_calibrated", "tag",
            "camera", "reprojection", "intrinsics", "edge", "scale", "time_offset", "fit",
            "pair", "precision", "certificate", "unseen_tag", "check_failed")


@dataclass(frozen=True)
class Reason:
    """One reason of a verdict.

    Attributes
    ----------
    level : str
        ``caution`` or ``unusable``.
    code : str
        What kind: one of ``inputs`` (:mod:`.input_check`: the inputs fit far better read
        otherwise), ``certificate_failed``, ``not_identifiable``, ``excluded``
        (:mod:`.exclusion`), ``not_calibrated``, ``scale``, ``tag``, ``camera``,
        ``reprojection`` (:mod:`.reprojection_check`), ``intrinsics`` (:mod:`.focal_check`),
        ``edge``, ``time_offset`` (:mod:`.lag_check`, and the session's estimated offsets),
        ``fit``, ``pair`` (:mod:`.pair_check`), ``precision``, ``certificate``, ``unseen_tag``,
        ``check_failed``.
    message : str
        A sentence: the frame or edge, the number, the likely cause, what to do.
    frames : tuple of str
        Frames it concerns (empty: the whole result).
    edges : tuple of (str, str)
        Edges it names.
    """

    level: str
    code: str
    message: str
    frames: tuple[str, ...] = ()
    edges: tuple[tuple[str, str], ...] = ()

    def to_dict(self) -> dict:
        return {"level": self.level, "code": self.code, "message": self.message,
                "frames": list(self.frames), "edges": [list(e) for e in self.edges]}


@dataclass
class FrameVerdict:
    """The verdict of one frame.

    Attributes
    ----------
    name : str
    role : str
        ``X`` (tag) or ``Y`` (camera).
    level : str
    why : list of str
        Short reasons (empty for ``good``).
    calibrated : bool
        The result holds an estimate of it.
    std_translation_m, std_rotation_deg : float
        Its precision as the verdict used it (``nan`` if unknown).
    """

    name: str
    role: str
    level: str = "good"
    why: list[str] = field(default_factory=list)
    calibrated: bool = True
    std_translation_m: float = float("nan")
    std_rotation_deg: float = float("nan")

    @property
    def usable(self) -> bool:
        return self.calibrated and self.level != "unusable"

    def to_dict(self) -> dict:
        return {"role": self.role, "usable": self.usable, "level": self.level,
                "why": list(self.why),
                "calibrated": self.calibrated,
                "std_translation_m": float(self.std_translation_m),
                "std_rotation_deg": float(self.std_rotation_deg)}


@dataclass
class Verdict:
    """Use this calibration or not, and why (module docstring).

    Attributes
    ----------
    level : str
        ``good``, ``caution`` or ``unusable``.
    reasons : list of Reason
        Worst first, most specific cause first within a level.
    frames : dict of str to FrameVerdict
        Cameras first, then tags.
    fit : FitStatistics or None
    scale_check : ScaleCheck or None
    summary : str
        What a ``good`` verdict rests on (certificate, fit, precision), in words.
    options : VerdictOptions
    focal_check : dict of str to FocalCheck, or str
        Per camera, the focal check (:mod:`.focal_check`); a sentence when it was not made.
    exclusion : Exclusion or None
        What was excluded before the published solve, and how far the frames moved
        (:mod:`.exclusion`); None when the exclusion was not run. The result YAML holds it as
        its own key ``exclusion`` (not in ``to_dict``).
    noise : NoiseEstimate or None
        The noise per group estimated from the data that weighted the solve
        (:mod:`rwhec_ros.core.noise`); None: the stated noise weighted it.
    motion_lag : MotionLag or None
        How far the residuals follow the motion between neighbouring pairs
        (:mod:`.lag_check`); None when not measured.
    far_pairs : list of FarPair
        Single pairs far off that move a frame (:mod:`.pair_check`).
    input_check : InputCheck or None
        The inputs read otherwise (poses inverted, units, pairs shifted) and how well each fits
        (:mod:`.input_check`); None when not made.
    """

    level: str
    reasons: list[Reason]
    frames: dict[str, FrameVerdict]
    fit: FitStatistics | None = None
    scale_check: ScaleCheck | None = None
    summary: str = ""
    options: VerdictOptions = field(default_factory=VerdictOptions)
    focal_check: dict | str = ""
    exclusion: object = None
    noise: Any = None
    motion_lag: Any = None
    far_pairs: list = field(default_factory=list)
    input_check: Any = None

    @property
    def usable(self) -> bool:
        """``good`` or ``caution``."""
        return self.level != "unusable"

    def usable_frames(self) -> list[str]:
        return [n for n, f in self.frames.items() if f.usable]

    def headline(self) -> str:
        """The first line: ``GOOD: ...``, ``CAUTION: <top reason>`` or ``UNUSABLE: <top
        reason>`` (+ how many more reasons)."""
        if not self.reasons:
            return f"{self.level.upper()}: {self.summary}"
        more = len(self.reasons) - 1
        tail = f" (+{more} more reason{'s' if more > 1 else ''})" if more else ""
        return f"{self.level.upper()}: {self.reasons[0].message}{tail}"

    def messages(self) -> list[str]:
        """Every reason as ``LEVEL: message``."""
        return [f"{r.level.upper()}: {r.message}" for r in self.reasons]

    def to_dict(self) -> dict:
        return {
            "level": self.level,
            "usable": self.usable,
            "headline": self.headline(),
            "summary": self.summary,
            "reasons": [r.to_dict() for r in self.reasons],
            "frames": {n: f.to_dict() for n, f in self.frames.items()},
            "fit": None if self.fit is None else self.fit.to_dict(),
            "scale_check": None if self.scale_check is None else self.scale_check.to_dict(),
            "options": asdict(self.options),
            "focal_check": (self.focal_check if isinstance(self.focal_check, str) else
                            {cam: c.to_dict() for cam, c in self.focal_check.items()}),
            "noise": None if self.noise is None else self.noise.to_dict(),
            "motion_lag": None if self.motion_lag is None else self.motion_lag.to_dict(),
            "far_pairs": [p.to_dict() for p in self.far_pairs],
            "input_check": None if self.input_check is None else self.input_check.to_dict(),
        }


class Builder:
    """Collects reasons and per-frame levels."""

    def __init__(self, x_names: Iterable[str], y_names: Iterable[str]):
        self.frames = {n: FrameVerdict(n, "Y") for n in y_names}
        self.frames.update({n: FrameVerdict(n, "X") for n in x_names})
        self.reasons: list[Reason] = []
        self.global_why: list[tuple[str, str]] = []

    def add(self, level: str, code: str, message: str, frames: Iterable[str] = (),
            edges: Iterable[tuple[str, str]] = (), *, why: str = "",
            frame_level: str | None = None) -> None:
        frames = tuple(frames)
        if frames and all(self.frames[n].role == "X" for n in frames if n in self.frames):
            # about tags only: the tags are left out (their own level), the result is a caution
            reason_level = "caution" if level == "unusable" else level
        else:
            reason_level = level
        self.reasons.append(Reason(reason_level, code, message, frames, tuple(edges)))
        if not frames:
            self.global_why.append((level, why or code))
        for n in frames:
            self.mark(n, frame_level or level, why or code)

    def mark(self, name: str, level: str, why: str) -> None:
        f = self.frames.get(name)
        if f is None:
            return
        if level_rank(level) > level_rank(f.level):
            f.level = level
        if why and why not in f.why:
            f.why.append(why)

    def verdict(self, fit, scale, summary, options) -> Verdict:
        for f in self.frames.values():
            if not f.calibrated:
                continue
            for level, why in self.global_why:
                self.mark(f.name, level, why)
        reasons = sorted(self.reasons, key=lambda r: (-level_rank(r.level),
                                                      PRIORITY.index(r.code)))
        # the cameras decide; a tag that cannot be used makes the result a caution only
        frame_levels = ["caution" if f.role == "X" and f.level == "unusable" else f.level
                        for f in self.frames.values()]
        level = worst_level([r.level for r in reasons] + frame_levels)
        return Verdict(level, reasons, self.frames, fit, scale, summary, options)

"""The verdict a user can act on: use this calibration or not, and why (:func:`assess`).

It combines, for a solution of a :class:`~rwhec_ros.core.problem.Problem`:

* the certificate status (:class:`~rwhec_ros.core.result.Status`);
* identifiability at the solution: frames the data do not determine (``result.unobservable``,
  the numeric check's null directions, undetermined components) are **not calibrated**;
* the goodness of fit (:mod:`.fit`): the noise the residuals imply against the stated one,
  globally (chi-square test on the a-posteriori variance factor) and per edge (edges far beyond
  the median edge are named);
* the scale check of a known-scale problem (:mod:`.scale_check`);
* the precision of each frame (:mod:`.precision`);
* the frames the user asked for that got no estimate at all.

The result is a :class:`Verdict`: a level (``good``, ``caution``, ``unusable``), the reasons as
sentences (what, which frame or edge, the number, the likely cause, what to do), and a
:class:`FrameVerdict` per frame. ``good`` and ``caution`` are usable; a frame marked ``unusable``
must not be used (the node leaves it off ``/tf_static``). The cameras decide: the whole result
is ``unusable`` as soon as one camera is (or a reason about the whole result is, e.g. a fit far
beyond the stated noise); a tag that is not calibrated or not usable is named and left out, and
makes the result a ``caution`` only (spare tags, tags seen a few times, are common).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass, field

import numpy as np

from ..problem import Problem
from ..result import CalibrationResult, Status
from .fit import EdgeFit, FitStatistics, goodness_of_fit, rotation_std_deg
from .options import VerdictOptions, level_rank, worst_level
from .precision import frame_precisions
from .scale_check import ScaleCheck, check_scale

__all__ = ["Reason", "FrameVerdict", "Verdict", "assess"]

#: Order of the reasons of one level: the most specific cause first.
_PRIORITY = ("certificate_failed", "not_identifiable", "not_calibrated", "tag", "camera",
             "edge", "scale", "fit", "precision", "certificate", "unseen_tag", "check_failed")


@dataclass(frozen=True)
class Reason:
    """One reason of a verdict.

    Attributes
    ----------
    level : str
        ``caution`` or ``unusable``.
    code : str
        What kind: one of ``certificate_failed``, ``not_identifiable``, ``not_calibrated``,
        ``scale``, ``tag``, ``camera``, ``edge``, ``fit``, ``precision``, ``certificate``,
        ``unseen_tag``, ``check_failed``.
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
    """

    level: str
    reasons: list[Reason]
    frames: dict[str, FrameVerdict]
    fit: FitStatistics | None = None
    scale_check: ScaleCheck | None = None
    summary: str = ""
    options: VerdictOptions = field(default_factory=VerdictOptions)

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
        }


# ------------------------------------------------------------------------------------------------
# numbers in words


def mm(value_m: float) -> str:
    """``36 mm``, ``4.2 mm``, ``0.31 mm`` (``inf``: ``unbounded``)."""
    v = 1e3 * float(value_m)
    if not np.isfinite(v):
        return "unbounded"
    return f"{v:.0f} mm" if v >= 100 else f"{v:.1f} mm" if v >= 1 else f"{v:.2f} mm"


def deg(value_deg: float) -> str:
    v = float(value_deg)
    if not np.isfinite(v):
        return "unbounded"
    return f"{v:.0f} deg" if v >= 100 else f"{v:.1f} deg" if v >= 1 else f"{v:.2f} deg"


def _times(ratio: float) -> str:
    """``17x``, ``2.8x``."""
    return f"{ratio:.0f}x" if ratio >= 10 else f"{ratio:.1f}x"


def _names(names: Iterable[str]) -> str:
    names = list(names)
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


# ------------------------------------------------------------------------------------------------
# the assessment


class _Builder:
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
                                                      _PRIORITY.index(r.code)))
        # the cameras decide; a tag that cannot be used makes the result a caution only
        frame_levels = ["caution" if f.role == "X" and f.level == "unusable" else f.level
                        for f in self.frames.values()]
        level = worst_level([r.level for r in reasons] + frame_levels)
        return Verdict(level, reasons, self.frames, fit, scale, summary, options)


def assess(
    result: CalibrationResult,
    problem: Problem,
    *,
    identifiability=None,
    options: VerdictOptions | None = None,
    expected_x: Iterable[str] = (),
    expected_y: Iterable[str] = (),
    excluded: Mapping[str, str] | None = None,
    carriers: tuple[str, str] = ("the camera carrier", "the tag carrier"),
    scale_check: ScaleCheck | None = None,
) -> Verdict:
    """The verdict of ``result``, the solution of ``problem``.

    Parameters
    ----------
    result : CalibrationResult
    problem : Problem
        The pairs that were solved (for a robust solve: the inlier problem).
    identifiability : IdentifiabilityReport, optional
        At the solution, with the numeric check
        (``analyze(problem, solution=(X, Y, scale))``); computed here when None.
    options : VerdictOptions, optional
    expected_x, expected_y : iterable of str
        Every tag (X) and camera (Y) the user asked for; those without an estimate are reported
        as not calibrated (default: the problem's frames).
    excluded : mapping of str to str, optional
        Edges ``"(x, y)"`` left out of the problem, and why (to say why a frame is missing).
    carriers : (str, str)
        Names of the camera and tag carrier frames, for directions in words.
    scale_check : ScaleCheck, optional
        A scale check already made (known scale); made here when None and enabled.
    """
    opts = options or VerdictOptions()
    xs = list(dict.fromkeys([*expected_x, *problem.x_names]))
    ys = list(dict.fromkeys([*expected_y, *problem.y_names]))
    b = _Builder(xs, ys)
    _certificate(b, result)
    if identifiability is None:
        identifiability = _analyze(problem, result)
    _identifiability(b, result, problem, identifiability, carriers)
    _missing(b, problem, xs, ys, excluded or {})
    fit = None
    try:
        fit = goodness_of_fit(problem, result, opts)
    except (ValueError, FloatingPointError) as exc:
        b.add("caution", "check_failed", f"the goodness of fit could not be computed ({exc})",
              why="fit not checked")
    if (scale_check is None and opts.scale_check and not problem.unknown_scale
            and fit is not None and fit.testable and _all_determined(b, problem)):
        try:
            scale_check = check_scale(problem)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            scale_check = ScaleCheck(float("nan"), float("inf"), message=str(exc))
    if scale_check is not None:
        _scale(b, scale_check, opts, fit)
    if fit is not None:
        _edges(b, fit, problem, opts)
        _fit(b, fit, opts, scale_check)
    _precision(b, identifiability, fit, opts, problem, pinned_frames(result))
    summary = _summary(result, fit, b)
    return b.verdict(fit, scale_check, summary, opts)


def _analyze(problem: Problem, result: CalibrationResult):
    from ..identifiability import analyze

    try:
        return analyze(problem, solution=(result.X, result.Y, float(result.scale)))
    except (ValueError, ArithmeticError, np.linalg.LinAlgError):
        return None


def _all_determined(b: _Builder, problem: Problem) -> bool:
    return all(b.frames[n].level != "unusable" for n in problem.frame_names)


#: Certificate statuses that make a reason: (level, code, message template, short why).
_CERTIFICATE_REASONS = {
    Status.SOLVER_FAILED: (
        "unusable", "certificate_failed",
        "the solver failed ({message}): the estimate is not trustworthy; solve again with --mode "
        "sdp (solver.mode), look for outliers with --robust (solver.reject_outliers) and make "
        "sure the motion rotates about two axes", "the solver failed"),
    Status.ILL_CONDITIONED: (
        "unusable", "certificate_failed",
        "no bound can be proven ({message}): some translations are barely determined; record "
        "motion that rotates about two axes at several positions, or solve with --mode sdp",
        "no optimality bound"),
    Status.NOT_TIGHT: (
        "caution", "certificate",
        "not proven globally optimal: the certificate does not close ({rho}), so the estimate "
        "may be a local optimum; solve again with --mode sdp, and check the other reasons "
        "(outliers and poor motion make certification fail)", "not proven optimal"),
    Status.SOLVER_INACCURATE: (
        "caution", "certificate",
        "not proven globally optimal: the conic solver did not reach its tolerances ({rho}); "
        "solve again with --mode fast, or with more data", "not proven optimal"),
    Status.LOCAL_ONLY: (
        "caution", "certificate",
        "not proven globally optimal: mode local gives no certificate; solve with --mode fast "
        "to prove the optimum", "not certified (mode local)"),
}


def _certificate(b: _Builder, result: CalibrationResult) -> None:
    c = result.certificate
    if c.status in _CERTIFICATE_REASONS:
        level, code, text, why = _CERTIFICATE_REASONS[c.status]
        b.add(level, code, text.format(message=c.message,
                                       rho=f"rho_hat={c.suboptimality_bound:.2g}"), why=why)


def _identifiability(b: _Builder, result: CalibrationResult, problem: Problem, ident,
                     carriers: tuple[str, str]) -> None:
    # frames in a direction the user's priors fix: the numeric check (which knows no prior) sees
    # that direction as flat; it is determined by the prior, not a reason
    covered: set[str] = set(pinned_frames(result))
    groups: dict[tuple[str, ...], list] = {}
    for d in result.unobservable:
        if d.fixed_by == "prior" and not d.involves_scale:
            continue
        groups.setdefault(tuple(n for n in d.frames() if n in b.frames), []).append(d)
    for frames, dirs in groups.items():
        if len(dirs) == 1:
            text = (f"{_along(dirs[0], problem, carriers)} is not determined by the data "
                    f"(predicted std {dirs[0].std_m:.3g} m) and was set by default: the motion "
                    "rotated about one axis only (e.g. a ground robot that only turns); add "
                    "rotation about a second axis (tilt by >= 5 deg while the tags are in view) "
                    "or give the known component as a prior (--prior FRAME.AXIS=VALUE, priors.*)")
        else:
            std = max(d.std_m for d in dirs)
            text = (f"their translations are not determined in {len(dirs)} directions "
                    f"(predicted std up to {std:.2g} m), so they were set by default; the data "
                    "hold too few pairs or too little rotation: record more views of these "
                    "frames while rotating about two axes")
        who = ("every frame" if set(frames) == set(problem.frame_names) and len(frames) > 3
               else _names(frames))
        b.add("unusable", "not_identifiable", f"{who}: not calibrated: {text}",
              frames, why="translation not determined")
        covered.update(frames)
    if problem.unknown_scale and not (np.isfinite(result.scale) and result.scale > 0.01):
        frames = list(problem.frame_names)
        b.add("unusable", "not_identifiable",
              f"the scale is not determined (alpha = {result.scale:.3g}), so no translation is "
              "metric: vary the distance between the cameras and the tags (e.g. two spheres at "
              "1 m and 0.3 m), or give the tag sizes and solve with known scale", frames,
              why="scale not determined")
        covered.update(frames)
    numeric = getattr(ident, "numeric", None)
    if numeric is not None:
        bad = [n for n in numeric.undetermined_frames if n not in covered and n in b.frames]
        if bad:
            b.add("unusable", "not_identifiable",
                  f"{_names(bad)}: not calibrated: not determined by the data (a flat "
                  "direction of the cost: too few pairs, or rotations about one axis only); "
                  "record more views of these frames while rotating about two axes",
                  bad, why="not determined by the data")
            covered.update(bad)
    for comp in getattr(ident, "components", ()):
        if getattr(comp.status, "value", comp.status) != "insufficient":
            continue
        bad = [n for n in comp.frames if n not in covered and n in b.frames]
        if bad:
            b.add("unusable", "not_identifiable",
                  f"{_names(bad)}: not calibrated: no edge of their part of the graph is "
                  "identifiable (" + "; ".join(comp.reasons) + "); record views with rotation "
                  "about two axes that link them to the rest", bad,
                  why="component not identifiable")
            covered.update(bad)
    if result.certificate.status is Status.NOT_IDENTIFIABLE and not covered:
        frames = list(problem.frame_names)
        b.add("unusable", "not_identifiable",
              f"not identifiable: {result.certificate.message}", frames,
              why="not identifiable")
    if ident is None:
        b.add("caution", "check_failed",
              "the identifiability at the solution could not be checked, so the precision of "
              "the frames is unknown", why="precision unknown")


def pinned_frames(result: CalibrationResult) -> list[str]:
    """Frames with a translation direction that the user's priors fix (``result.unobservable``
    with ``fixed_by == "prior"``)."""
    return list(dict.fromkeys(n for d in result.unobservable
                              if d.fixed_by == "prior" and not d.involves_scale
                              for n in d.frames()))


def _along(d, problem: Problem, carriers: tuple[str, str]) -> str:
    """``the translation along world z (tags) and rig z (cameras)`` for a direction that is one
    axis per role, else the direction's own words."""
    from ..gauge import axis_words

    parts = []
    for names, carrier, role in ((problem.x_names, carriers[1], "tags"),
                                 (problem.y_names, carriers[0], "cameras")):
        axes = {axis_words(v) for n, v in d.components.items() if n in names}
        if len(axes) > 1:
            return d.describe(x_parent=carriers[1], y_parent=carriers[0],
                              x_names=problem.x_names).split(" not determined")[0]
        if axes:
            parts.append(f"{carrier} {axes.pop()} ({role})")
    return "the translation along " + " and ".join(parts)


def _missing(b: _Builder, problem: Problem, xs: list[str], ys: list[str],
             excluded: Mapping[str, str]) -> None:
    present = set(problem.frame_names)
    for name in ys + xs:
        if name in present:
            continue
        b.frames[name].calibrated = False
        why = [f"{k}: {v}" for k, v in excluded.items() if _edge_has(k, name)]
        role = "camera" if name in ys else "tag"
        if why:
            b.add("unusable", "not_calibrated",
                  f"{name}: not calibrated: every edge of this {role} was left out ("
                  + "; ".join(why) + "); record more views of it with rotation about two axes",
                  [name], why="no usable edge")
        elif role == "camera":
            b.add("unusable", "not_calibrated",
                  f"{name}: not calibrated: no tag was ever kept in its images; check its image "
                  "and camera_info topics, that tags are in view, and that poses exist at the "
                  "image stamps", [name], why="no data")
        else:
            b.add("caution", "unseen_tag",
                  f"{name}: never observed, not calibrated; remove it from tags.ids if it is "
                  "not needed", [name], why="never observed")


def _edge_has(key: str, name: str) -> bool:
    parts = [p.strip() for p in key.strip("()").split(",")]
    return name in parts


def _scale(b: _Builder, sc: ScaleCheck, opts: VerdictOptions, fit: FitStatistics | None) -> None:
    if not sc.available:
        return
    dev = abs(sc.deviation)
    if dev <= opts.scale_caution or sc.sigmas <= opts.scale_sigmas:
        return
    if not sc.noise_ratio_translation < opts.fit_caution_ratio:
        return  # a free scale does not make the data fit: not (only) a scale (see _fit)
    level = "unusable" if dev > opts.scale_unusable else "caution"
    pct = f"{100.0 * dev:.1f}" if dev < 0.1 else f"{100.0 * dev:.0f}"
    word = "large" if sc.alpha > 1 else "small"
    fits = ""
    if (fit is not None and fit.noise_ratio_translation > opts.fit_caution_ratio
            and np.isfinite(sc.noise_ratio_translation)):
        fits = (f"; with the scale free the translations fit {sc.noise_ratio_translation:.2g}x "
                "the stated noise")
    b.add(level, "scale",
          f"the camera-tag distances are {sc.alpha:.3f} times what the pose stream implies "
          f"(+-{sc.std:.3f}, {sc.sigmas:.0f} std from 1): the configured tag sizes are "
          f"~{pct} % too {word} (true size = configured / {sc.alpha:.3f}), or the focal "
          f"lengths ~{pct} % too {word}, or the pose stream is not in metres{fits}; "
          "measure the tags, check the intrinsics (or set tags.unknown_scale: true)",
          why=f"scale {sc.alpha:.3f}")


def _edges(b: _Builder, fit: FitStatistics, problem: Problem, opts: VerdictOptions) -> None:
    flagged = fit.flagged_edges()
    if not flagged:
        return
    med_t, med_r = fit.median_edge()
    med = f"median edge {mm(med_t)}, {deg(med_r)}"
    done: set[tuple[str, str]] = set()
    for role, key in (("tag", "x"), ("camera", "y")):
        by_frame: dict[str, list[EdgeFit]] = {}
        for e in fit.edges:
            by_frame.setdefault(getattr(e, key), []).append(e)
        for name, edges in by_frame.items():
            if len(edges) < 2 or not all(e.flagged for e in edges):
                continue
            worse = max(edges, key=lambda e: e.ratio).worse
            if role == "tag":
                cause = ("the tag moved during the recording, its id is used twice, or its pose "
                         "flips" if worse == "rotation" else
                         "its size is wrong (tags.sizes) or it moved during the recording")
                todo = f"check {name}, or remove it from tags.ids"
            else:
                cause = ("its intrinsics (focal length, distortion) are wrong or its images are "
                         "not in time with the pose stream")
                todo = f"check the camera_info of {name} and its time stamps"
            detail = ", ".join(f"{e.y if role == 'tag' else e.x} {_times(e.ratio)}"
                               for e in edges)
            b.add("unusable", role,
                  f"every edge of {name} fits far worse than the others ({detail}; RMS "
                  f"{mm(max(e.rms_translation_m for e in edges))}, "
                  f"{deg(max(e.rms_rotation_deg for e in edges))}; {med}): {cause}; {todo}",
                  [name], [(e.x, e.y) for e in edges], why="all its edges fit badly")
            for e in edges:
                other = e.y if role == "tag" else e.x
                b.mark(other, "caution", f"pulled by {e.name}")
            done.update((e.x, e.y) for e in edges)
    degree: dict[str, int] = {}
    for e in fit.edges:
        degree[e.x] = degree.get(e.x, 0) + 1
        degree[e.y] = degree.get(e.y, 0) + 1
    for e in flagged:
        if (e.x, e.y) in done:
            continue
        if e.worse == "rotation":
            what = f"rotation residuals RMS {deg(e.rms_rotation_deg)}"
            cause = "a wrong tag id, a flipped tag pose, or a tag that moved"
        else:
            what = f"translation residuals RMS {mm(e.rms_translation_m)}"
            cause = f"a wrong size of {e.x}, a tag that moved, or a time offset"
        alone = [n for n in (e.x, e.y) if degree[n] == 1]
        tail = (f"; {_names(alone)} rest{'s' if len(alone) == 1 else ''} on this edge alone "
                "and cannot be used") if alone else ""
        own = max(e.noise_ratio_translation, e.noise_ratio_rotation)
        beyond = f" and {own:.1f}x the stated noise" if own >= opts.fit_caution_ratio else ""
        b.add("unusable" if alone else "caution", "edge",
              f"edge {e.name} fits {'far ' if e.ratio >= opts.edge_ratio else ''}worse than "
              f"the others: {what} over {e.pairs} pairs, "
              f"{_times(e.ratio)} the noise of the median edge ({med}){beyond}: {cause}; solve "
              f"with --robust (solver.reject_outliers) or remove that edge's pairs{tail}",
              [e.x, e.y], [(e.x, e.y)], why=f"on outlier edge {e.name}", frame_level="caution")
        for n in alone:
            b.mark(n, "unusable", f"rests on outlier edge {e.name} alone")


def _fit(b: _Builder, fit: FitStatistics, opts: VerdictOptions, sc: ScaleCheck | None) -> None:
    if not fit.testable:
        return
    flagged = fit.flagged_edges()
    clean_ok = bool(flagged) and fit.clean_noise_ratio < opts.fit_caution_ratio
    scale_explains = (sc is not None and sc.available
                      and any(r.code == "scale" for r in b.reasons)
                      and sc.noise_ratio_translation < opts.fit_caution_ratio)
    for what, s, p in (("translation", fit.noise_ratio_translation, fit.p_translation),
                       ("rotation", fit.noise_ratio_rotation, fit.p_rotation)):
        if not (s > opts.fit_caution_ratio and p < opts.significance):
            continue
        level = "unusable" if s > opts.fit_unusable_ratio else "caution"
        if what == "translation":
            noise = (f"the translation residuals fit sigma = {mm(fit.sigma_estimated_m)}, "
                     f"configured {mm(fit.sigma_stated_m)} ({s:.1f}x)")
            todo = ("check the tag sizes, the camera intrinsics and the time sync of the "
                    "images with the pose stream (or state the true noise in noise.sigma)")
        else:
            noise = (f"the rotation residuals fit kappa = {fit.kappa_estimated:.3g} "
                     f"({deg(rotation_std_deg(fit.kappa_estimated))} per axis), configured "
                     f"{fit.kappa_stated:.3g} ({deg(rotation_std_deg(fit.kappa_stated))}, "
                     f"{s:.1f}x)")
            todo = ("check the time sync of the images with the pose stream, the camera "
                    "intrinsics and tag poses that flip (or state the true noise in "
                    "noise.kappa)")
        if clean_ok:
            level = "caution"
            todo = (f"{100 * fit.flagged_share:.0f} % of the misfit is on the edges named "
                    f"above; without them the data fit {fit.clean_noise_ratio:.1f}x the stated "
                    "noise")
        elif what == "translation" and scale_explains:
            todo = "the scale above explains it"
            level = next(r.level for r in b.reasons if r.code == "scale")
        elif (what == "translation" and sc is not None and sc.available
              and abs(sc.deviation) > opts.scale_caution):
            todo += (f"; a free scale (alpha = {sc.alpha:.3f}) does not explain it: with it the "
                     f"data still fit {sc.noise_ratio_translation:.1f}x the stated noise")
        b.add(level, "fit", f"{noise}: {todo}", why=f"{what} fit {s:.1f}x the stated noise")


def _precision(b: _Builder, ident, fit: FitStatistics | None, opts: VerdictOptions,
               problem: Problem, pinned: list[str]) -> None:
    s = fit.noise_ratio if fit is not None and fit.testable else 1.0
    prec = frame_precisions(ident, s, pinned=pinned)
    groups: dict[str, list[str]] = {"unusable": [], "caution": []}
    for name, p in prec.items():
        f = b.frames.get(name)
        if f is None:
            continue
        f.std_translation_m, f.std_rotation_deg = p.std_translation_m, p.std_rotation_deg
        if not p.determined or f.level == "unusable":
            continue  # already reported as not determined
        t, r = p.std_translation_m, p.std_rotation_deg
        if t > opts.unusable_std_translation_m or r > opts.unusable_std_rotation_deg:
            level = "unusable"
        elif t > opts.caution_std_translation_m or r > opts.caution_std_rotation_deg:
            level = "caution"
        else:
            continue
        groups[level].append(f"{name} (+-{mm(t)}, +-{deg(r)})")
        b.mark(name, level, f"predicted +-{mm(t)}, +-{deg(r)}")
    for level, items in groups.items():
        if not items:
            continue
        t_lim = opts.unusable_std_translation_m if level == "unusable" else \
            opts.caution_std_translation_m
        r_lim = opts.unusable_std_rotation_deg if level == "unusable" else \
            opts.caution_std_rotation_deg
        names = [i.split(" ")[0] for i in items]
        b.reasons.append(Reason(
            level, "precision",
            f"predicted precision beyond {mm(t_lim)} / {deg(r_lim)} (one standard deviation): "
            + ", ".join(items) + "; record more views of "
            + ("this frame" if len(items) == 1 else "these frames")
            + " with rotation about two axes and varied distances", tuple(names)))
    numeric = getattr(ident, "numeric", None)
    rel = getattr(numeric, "scale_rel_std", None)
    if problem.unknown_scale and rel is not None and np.isfinite(rel):
        rel = rel * max(1.0, s)
        if rel > opts.caution_scale_rel_std:
            level = "unusable" if rel > opts.unusable_scale_rel_std else "caution"
            b.add(level, "precision",
                  f"the scale is determined only to +-{100 * rel:.1f} %: vary the distance "
                  "between the cameras and the tags more (e.g. 1 m and 0.3 m)",
                  why="scale imprecise")


def _summary(result: CalibrationResult, fit: FitStatistics | None, b: _Builder) -> str:
    c = result.certificate
    parts = [f"certified globally optimal (rho_hat={c.suboptimality_bound:.2g})"
             if c.certified else f"not certified ({c.status.value})"]
    if fit is not None and fit.testable:
        parts.append(f"the data fit {fit.noise_ratio_translation:.2g}x the stated translation "
                     f"noise and {fit.noise_ratio_rotation:.2g}x the rotation noise")
    known = [f for f in b.frames.values() if f.calibrated and np.isfinite(f.std_translation_m)
             and np.isfinite(f.std_rotation_deg)]
    if known:
        wt = max(known, key=lambda f: f.std_translation_m)
        wr = max(known, key=lambda f: f.std_rotation_deg)
        parts.append(f"every frame within +-{mm(wt.std_translation_m)} ({wt.name}) and "
                     f"+-{deg(wr.std_rotation_deg)} ({wr.name})")
    return "; ".join(parts)

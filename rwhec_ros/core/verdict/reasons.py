"""The checks of a verdict, each adding its reasons to a :class:`~.model.Builder`: certificate,
identifiability, frames without an estimate, scale, edges, fit, precision (see :mod:`.verdict`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from ..problem import Problem
from ..result import CalibrationResult, Status
from .fit import EdgeFit, FitStatistics, rotation_std_deg
from .model import Builder, Reason
from .options import VerdictOptions
from .precision import frame_noise_ratios, frame_precisions, noise_factor, scale_rel_std
from .scale_check import ScaleCheck
from .words import deg, mm, names, times

__all__ = [
    "certificate_reasons",
    "identifiability_reasons",
    "missing_frames",
    "scale_reason",
    "edge_reasons",
    "fit_reasons",
    "precision_reasons",
    "pinned_frames",
    "all_determined",
]


def all_determined(b: Builder, problem: Problem) -> bool:
    return all(b.frames[n].level != "unusable" for n in problem.frame_names)


#: Certificate statuses that make a reason: (level, code, message template, short why).
_CERTIFICATE_REASONS = {
    Status.SOLVER_FAILED: (
        "unusable", "certificate_failed",
        "the solver failed ({message}): the estimate is not trustworthy; {left}",
        "the solver failed"),
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


def certificate_reasons(b: Builder, result: CalibrationResult) -> None:
    c = result.certificate
    if c.rounding_decides:  # not the optimisation: another solve mode would not help
        b.add("caution", "certificate",
              f"not proven globally optimal (rho_hat={c.suboptimality_bound:.2g}): the bound's "
              "rounding terms alone exceed what the tolerance allows, because the coordinates "
              "are large for the size of the residuals (e.g. a world or map frame far from the "
              "data); express the poses about an origin near the data and solve again",
              why="not proven optimal (large coordinates)")
        return
    if c.status in _CERTIFICATE_REASONS:
        level, code, text, why = _CERTIFICATE_REASONS[c.status]
        b.add(level, code, text.format(message=c.message, left=_left_to_try(result),
                                       rho=f"rho_hat={c.suboptimality_bound:.2g}"), why=why)


def _left_to_try(result: CalibrationResult) -> str:
    """After a solver failure: what is left to try, never what already ran (the SDP, as the
    mode or the fast mode's fallback; the outlier rejection)."""
    sdp_ran = result.mode == "sdp" or any(n.startswith("SDP form:") for n in result.notes)
    robust = any(n.startswith("outlier rejection:") for n in result.notes)
    if result.mode == "sdp":
        tries = ["solve with --mode fast (solver.mode; the local solver and its certificate)"]
    else:
        tries = [] if sdp_ran else ["solve again with --mode sdp (solver.mode)"]
    if not robust:
        tries.append("look for outliers with --robust (solver.reject_outliers)")
    tries.append("make sure the motion rotates about two axes (identical or nearly identical "
                 "pairs determine nothing)")
    return "left to try: " + "; ".join(tries)


def identifiability_reasons(b: Builder, result: CalibrationResult, problem: Problem, ident,
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
               else names(frames))
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
                  f"{names(bad)}: not calibrated: not determined by the data (a flat "
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
                  f"{names(bad)}: not calibrated: no edge of their part of the graph is "
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
    from ..model.gauge import axis_words

    parts = []
    for frames, carrier, role in ((problem.x_names, carriers[1], "tags"),
                                  (problem.y_names, carriers[0], "cameras")):
        axes = {axis_words(v) for n, v in d.components.items() if n in frames}
        if len(axes) > 1:
            return d.describe(x_parent=carriers[1], y_parent=carriers[0],
                              x_names=problem.x_names).split(" not determined")[0]
        if axes:
            parts.append(f"{carrier} {axes.pop()} ({role})")
    return "the translation along " + " and ".join(parts)


def missing_frames(b: Builder, problem: Problem, xs: list[str], ys: list[str],
             excluded: Mapping[str, str]) -> None:
    present = set(problem.frame_names)
    for name in ys + xs:
        if name in present or not b.frames[name].calibrated:  # excluded: its own reason
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
                  f"{name}: never observed, not calibrated; remove it from tags.ids (or "
                  "targets.names) if it is not needed", [name], why="never observed")


def _edge_has(key: str, name: str) -> bool:
    parts = [p.strip() for p in key.strip("()").split(",")]
    return name in parts


#: A scale between this share of ``verdict.scale_sigmas`` and ``scale_sigmas`` standard deviations
#: from 1 (3 to 4 at the defaults), and beyond ``verdict.scale_caution``, is a caution "may be":
#: without it the verdict jumped from GOOD to UNUSABLE on a real set's folds as the scale
#: crossed 4 std (1.048 +- 0.013 at 3.6 std: GOOD, not a word; 1.050 +- 0.0126: UNUSABLE).
SUGGESTIVE_SHARE = 0.75


def scale_reason(b: Builder, sc: ScaleCheck, opts: VerdictOptions,
                 fit: FitStatistics | None) -> None:
    if not sc.available:
        return
    dev = abs(sc.deviation)
    suggestive = SUGGESTIVE_SHARE * opts.scale_sigmas < sc.sigmas <= opts.scale_sigmas
    if dev <= opts.scale_caution or not (sc.sigmas > opts.scale_sigmas or suggestive):
        return
    if not sc.noise_ratio_translation < opts.fit_caution_ratio:
        return  # a free scale does not make the data fit: not (only) a scale (see _fit)
    level = "unusable" if dev > opts.scale_unusable and not suggestive else "caution"
    pct = f"{100.0 * dev:.1f}" if dev < 0.1 else f"{100.0 * dev:.0f}"
    word = "large" if sc.alpha > 1 else "small"
    fits = ""
    if (fit is not None and fit.noise_ratio_translation > opts.fit_caution_ratio
            and np.isfinite(sc.noise_ratio_translation)):
        fits = (f"; with the scale free the translations fit {sc.noise_ratio_translation:.2g}x "
                "the stated noise")
    are, std = (("may be", f"{sc.sigmas:.1f} std from 1: suggestive, not conclusive with "
                 f"these data") if suggestive else ("are", f"{sc.sigmas:.0f} std from 1"))
    b.add(level, "scale",
          f"the camera-tag distances {are} {sc.alpha:.3f} times what the pose stream implies "
          f"(+-{sc.std:.3f}, {std}): the configured tag sizes are "
          f"~{pct} % too {word} (true size = configured / {sc.alpha:.3f}), or the focal "
          f"lengths ~{pct} % too {word}, or the pose stream is not in metres{fits}; "
          "measure the tags, check the intrinsics (or set tags.unknown_scale: true, the CLI's "
          "--unknown-scale)",
          why=f"scale {sc.alpha:.3f}")


def edge_reasons(b: Builder, fit: FitStatistics, problem: Problem, opts: VerdictOptions,
                 strict: bool = False, *, noise_estimated: bool = False) -> None:
    """Edges (and tags, cameras with every edge) that fit far worse than the others. ``strict``
    (after :mod:`.exclusion` ran, which excludes what it can): a camera on such an edge or tag
    rests on data that do not fit and is not usable; otherwise it is a caution.
    ``noise_estimated``: the weights are the noise estimated per group, so an edge's own ratio
    is to its group's (camera's) estimated noise, not to a stated one."""
    on_misfit = "unusable" if strict else "caution"
    reference = "its camera's estimated noise" if noise_estimated else "the stated noise"
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
                         "its size is wrong (tags.sizes, a board's layout) or it moved during "
                         "the recording")
                todo = f"check {name}, or remove it from tags.ids (or targets.names)"
            else:
                cause = ("its intrinsics (focal length, distortion) are wrong or its images are "
                         "not in time with the pose stream")
                todo = f"check the camera_info of {name} and its time stamps"
            detail = ", ".join(f"{e.y if role == 'tag' else e.x} {times(e.ratio)}"
                               for e in edges)
            b.add("unusable", role,
                  f"every edge of {name} fits far worse than the others ({detail}; RMS "
                  f"{mm(max(e.rms_translation_m for e in edges))}, "
                  f"{deg(max(e.rms_rotation_deg for e in edges))}; {med}): {cause}; {todo}",
                  [name], [(e.x, e.y) for e in edges], why="all its edges fit badly")
            for e in edges:
                other = e.y if role == "tag" else e.x
                b.mark(other, on_misfit if role == "tag" else "caution", f"pulled by {e.name}")
            if role == "tag" and strict:  # its cameras are not usable: so is the reason
                b.reasons[-1] = replace(b.reasons[-1], level="unusable")
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
        tail = (f"; {names(alone)} rest{'s' if len(alone) == 1 else ''} on this edge alone "
                "and cannot be used") if alone else ""
        if strict:
            tail += f"; {e.y} rests on it and cannot be used (it could not be excluded)"
        # a tag that cannot be used makes the result a caution only; a camera an unusable one
        camera_out = strict or e.y in alone
        own = max(e.noise_ratio_translation, e.noise_ratio_rotation)
        beyond = f" and {own:.1f}x {reference}" if own >= opts.fit_caution_ratio else ""
        b.add("unusable" if camera_out else "caution", "edge",
              f"edge {e.name} fits {'far ' if e.ratio >= opts.edge_ratio else ''}worse than "
              f"the others: {what} over {e.pairs} pairs, "
              f"{times(e.ratio)} the noise of the median edge ({med}){beyond}: {cause}; solve "
              f"with --robust (solver.reject_outliers) or remove that edge's pairs{tail}",
              [e.x, e.y], [(e.x, e.y)], why=f"on outlier edge {e.name}", frame_level="caution")
        for n in alone:
            b.mark(n, "unusable", f"rests on outlier edge {e.name} alone")
        if strict:
            b.mark(e.y, "unusable", f"rests on misfitting edge {e.name}")


def fit_reasons(b: Builder, fit: FitStatistics, opts: VerdictOptions,
                sc: ScaleCheck | None) -> None:
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
                    "images with the pose stream (or state the true noise in noise.sigma, or "
                    "let the data give it: noise.estimate true)")
        else:
            noise = (f"the rotation residuals fit kappa = {fit.kappa_estimated:.3g} "
                     f"({deg(rotation_std_deg(fit.kappa_estimated))} per axis), configured "
                     f"{fit.kappa_stated:.3g} ({deg(rotation_std_deg(fit.kappa_stated))}, "
                     f"{s:.1f}x)")
            todo = ("check the time sync of the images with the pose stream, the camera "
                    "intrinsics and tag poses that flip (or state the true noise in "
                    "noise.kappa, or let the data give it: noise.estimate true)")
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


def precision_reasons(b: Builder, uncertainty, fit: FitStatistics | None, opts: VerdictOptions,
                      problem: Problem, pinned: list[str], scale: float = 1.0, *,
                      factors: Mapping[str, float] | None = None,
                      noise_estimated: bool = False) -> None:
    """Frames (and the scale) less precise than the thresholds, from ``uncertainty`` (an
    :class:`~rwhec_ros.core.analysis.uncertainty.Uncertainty` at the solution, or None: unknown).
    ``factors``: per frame the factor on its std (estimated noise: the estimate's upper
    confidence factor, :mod:`.noise_check`); ``noise_estimated``: the weights are the data's.
    When the weights are the stated noise and the data fit significantly less, the advice says
    that the stated noise, not the data, makes the frames imprecise."""
    s = fit.noise_ratio if fit is not None and fit.testable else 1.0
    own = frame_noise_ratios(fit, opts.significance) if fit is not None and fit.testable else {}
    prec = frame_precisions(uncertainty, s, pinned=pinned, frame_ratios=own, factors=factors)
    stated_too_large = (not noise_estimated and fit is not None and fit.testable
                        and s < 1.0 / opts.fit_caution_ratio)
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
        named = [i.split(" ")[0] for i in items]
        if stated_too_large:
            todo = (f"these stds rest on the stated noise, and the residuals fit {s:.2g}x of it: "
                    f"with the data's noise they would be {s:.2g}x as large; let the data give "
                    "the noise (noise.estimate true, the default) or state the noise you observe "
                    "(noise.sigma, noise.kappa)")
        else:
            todo = ("record more views of " + ("this frame" if len(items) == 1 else
                                               "these frames")
                    + " with rotation about two axes and varied distances")
        kind = (", with the noise estimated from the data at its upper confidence bound"
                if noise_estimated else "")
        b.reasons.append(Reason(
            level, "precision",
            f"predicted precision beyond {mm(t_lim)} / {deg(r_lim)} (one standard deviation"
            f"{kind}): " + ", ".join(items) + "; " + todo, tuple(named)))
    rel = scale_rel_std(uncertainty, scale)
    if problem.unknown_scale and rel is not None and np.isfinite(rel):
        rel = rel * noise_factor(s)
        if rel > opts.caution_scale_rel_std:
            level = "unusable" if rel > opts.unusable_scale_rel_std else "caution"
            b.add(level, "precision",
                  f"the scale is determined only to +-{100 * rel:.1f} %: vary the distance "
                  "between the cameras and the tags more (e.g. 1 m and 0.3 m)",
                  why="scale imprecise")

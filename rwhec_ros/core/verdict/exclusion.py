"""A target (or an edge) that does not fit must not move the cameras: exclude it, solve again.

The checks of the verdict find a misfit but, on their own, only name it: the frames it touches
were estimated *with* it, so a wrong tag size, a tag that moved or a tag whose pose flips pulls
the cameras (by 30 mm on a rendered 3-camera rig with one tag printed 33 % larger than configured)
while their predicted std stays a few millimetres. :func:`exclude_misfits` closes that loop, once,
between the solve and the verdict:

1. the **findings** of a solution (:func:`misfits`): from the goodness of fit (:mod:`.fit`), a
   tag with two or more bad edges (its size, a move, a flip: two cameras disagree with it) --
   edges that fit far worse than the others, or that the outlier rejection left out wholly, or
   that were excluded before -- and every other flagged edge; with outlier rejection, a tag (or
   an edge) most of whose pairs the rejection left out
   (``VerdictOptions.exclusion_rejected_share``), because what is left of it is the few pairs
   that happen to agree, not a measurement of it. A camera all of whose edges
   fit badly is *not* a candidate: its intrinsics or time stamps are wrong, and no target's
   exclusion mends that (the verdict names it). Two findings the edge statistics miss once the
   noise is estimated per camera (:mod:`.hidden_misfits`): a tag whose size disagrees with the
   other tags' (:mod:`.tag_scale_check`), and the shared tags of a camera whose estimated noise
   is far above the other cameras' (a tag that moved while that camera saw it pulls the camera
   and every edge of it), each excluded only when the re-solve without it brings that camera's
   noise back among the others';
2. the **choice** (:func:`choose`): each candidate is left out in turn and the rest solved again
   (mode ``fast``): the one whose exclusion makes the rest fit best (smallest a-posteriori noise
   ratio, :attr:`.fit.FitStatistics.noise_ratio`) is excluded. One at a time, because a bad
   target makes the edges of good ones look bad through the cameras it pulls;
3. the remaining data are **solved again** by the caller's solver (the same mode, priors and
   outlier rejection as the first solve), and the findings made again, up to
   ``VerdictOptions.exclusion_max_rounds`` exclusions and at most
   ``VerdictOptions.exclusion_max_share`` of the pairs (beyond that the misfit is not one
   target's: the verdict reports it and the cameras on it are not calibrated).

What is published is the last solve, and its certificate is for the problem actually solved:
the remaining pairs. The :class:`Exclusion` keeps what was excluded and why, how far every frame
moved when it was (``FrameShift``: "without tag_2, cam0 moves 31 mm / 1.1 deg" -- the number
that says the all-data answer was wrong), and the all-data solve's key numbers
(:class:`FirstSolve`). :func:`exclusion_reasons` puts it into the verdict: a ``caution`` naming
the excluded target or edge and the shifts; an excluded tag is not calibrated (and not
published).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from ..lie import rotation_distance, transform_to_quat_xyzw
from ..problem import Problem
from ..result import CalibrationResult, Status
from .fit import EdgeFit, FitStatistics, goodness_of_fit
from .hidden_misfits import camera_misfits, explained, judged_weights, size_misfits
from .misfit import Attempt, Misfit, edge_target
from .model import Builder
from .options import VerdictOptions
from .step_check import step_misfits
from .words import deg, mm, names, times

__all__ = ["Misfit", "FrameShift", "FirstSolve", "Exclusion", "Attempt", "misfits", "choose",
           "exclude_misfits", "frame_shifts", "exclusion_reasons"]

@dataclass(frozen=True)
class FrameShift:
    """How far a frame moved from the all-data solve to the published one (metric)."""

    name: str
    role: str
    translation_m: float
    rotation_deg: float

    def words(self) -> str:
        return f"{self.name} moves {mm(self.translation_m)} / {deg(self.rotation_deg)}"

    def to_dict(self) -> dict:
        return {"role": self.role, "translation_m": float(self.translation_m),
                "rotation_deg": float(self.rotation_deg)}


@dataclass(frozen=True)
class FirstSolve:
    """The all-data solve's key numbers, kept for reference (it is not published)."""

    status: str
    certified: bool
    suboptimality_bound: float
    pairs: int
    edges: int
    noise_ratio_translation: float
    noise_ratio_rotation: float
    flagged_edges: tuple[str, ...]
    frames: dict
    noise_estimated: bool = False

    def to_dict(self) -> dict:
        return {"status": self.status, "certified": bool(self.certified),
                "suboptimality_bound": float(self.suboptimality_bound),
                "pairs": int(self.pairs), "edges": int(self.edges),
                "noise_ratio_translation": float(self.noise_ratio_translation),
                "noise_ratio_rotation": float(self.noise_ratio_rotation),
                "flagged_edges": list(self.flagged_edges), "frames": dict(self.frames)}


@dataclass
class Exclusion:
    """What :func:`exclude_misfits` did (module docstring).

    Attributes
    ----------
    excluded : list of Misfit
        In the order they were excluded (empty: nothing was).
    shifts : list of FrameShift
        Cameras then tags: from the all-data solve to the published one (empty when nothing
        was excluded).
    first : FirstSolve
    pairs_total, pairs_kept : int
        Pairs given to the solve, and those the published solve had after the exclusion
        (before outlier rejection).
    stopped : str
        Why nothing more was excluded (``""``: nothing was left to exclude).
    remaining : tuple of str
        Candidates still found in the published solve (not excluded: see ``stopped``).
    """

    excluded: list[Misfit] = field(default_factory=list)
    shifts: list[FrameShift] = field(default_factory=list)
    first: FirstSolve | None = None
    pairs_total: int = 0
    pairs_kept: int = 0
    stopped: str = ""
    remaining: tuple[str, ...] = ()

    @property
    def excluded_tags(self) -> list[str]:
        return [m.name for m in self.excluded if m.kind == "tag"]

    def dropped(self) -> dict[str, str]:
        """Edge ``"(x, y)"`` -> why it was left out, for ``excluded_edges``."""
        out = {}
        for m in self.excluded:
            what = m.name if m.kind == "tag" else "this edge"
            for e in m.edges:
                out[e] = f"excluded: {what} does not fit (the verdict's reason 'excluded')"
        return out

    def summary_lines(self) -> list[str]:
        """The summary's lines: the all-data solve (not published) and every frame's shift."""
        if not self.excluded or self.first is None:
            return []
        f = self.first
        cert = (f"certified (rho_hat={f.suboptimality_bound:.2g})" if f.certified else
                f"not certified ({f.status})")
        fit = (f", the data fit {f.noise_ratio_translation:.2g}x / "
               f"{f.noise_ratio_rotation:.2g}x the "
               + ("estimated" if f.noise_estimated else "stated")
               + " translation / rotation noise"
               if np.isfinite(f.noise_ratio_translation) else "")
        lines = [f"all-data solve (not published): {f.pairs} pairs on {f.edges} edges, {cert}"
                 f"{fit}"]
        lines.append("without " + names([m.name for m in self.excluded]) + ": " + ", ".join(
            f"{s.name} {mm(s.translation_m)} / {deg(s.rotation_deg)}" for s in self.shifts))
        if self.stopped:
            lines.append(f"exclusion stopped: {self.stopped}")
        return lines

    def diagnostic_values(self) -> list[tuple[str, str]]:
        """``(key, value)`` pairs for the /diagnostics session row: ``excluded`` and ``shift
        <frame>`` per camera."""
        if not self.excluded:
            return []
        out = [("excluded", ", ".join(m.name for m in self.excluded))]
        out += [(f"shift {s.name}", f"{mm(s.translation_m)} / {deg(s.rotation_deg)}")
                for s in self.shifts if s.role == "Y"]
        return out

    def shift_words(self, role: str = "Y", most: int = 3) -> str:
        """``cam0 moves 31 mm / 1.1 deg, cam1 30 mm / 0.7 deg`` (largest first; beyond ``most``
        frames: ``the others at most 1.6 mm / 0.03 deg``)."""
        items = sorted((s for s in self.shifts if s.role == role),
                       key=lambda s: -s.translation_m)
        if not items:
            return ""
        first = items[0].words()
        rest = [f"{s.name} {mm(s.translation_m)} / {deg(s.rotation_deg)}"
                for s in items[1:most]]
        if len(items) > most:
            rest.append(f"the others at most {mm(max(s.translation_m for s in items[most:]))} / "
                        f"{deg(max(s.rotation_deg for s in items[most:]))}")
        return ", ".join([first, *rest])

    def to_dict(self) -> dict:
        """The result YAML's ``exclusion`` key."""
        return {"excluded": [m.to_dict() for m in self.excluded],
                "excluded_tags": self.excluded_tags,
                "shifts": {s.name: s.to_dict() for s in self.shifts},
                "pairs_total": int(self.pairs_total), "pairs_kept": int(self.pairs_kept),
                "stopped": self.stopped, "remaining": list(self.remaining),
                "certificate_note": self.certificate_note(),
                "first_solve": None if self.first is None else self.first.to_dict()}

    def certificate_note(self) -> str:
        if not self.excluded:
            return ""
        return (f"the published estimate is the solve of the remaining {self.pairs_kept} of "
                f"{self.pairs_total} pairs (without {names([m.name for m in self.excluded])}); "
                "its certificate is for that problem")


# ------------------------------------------------------------------------------------------------
# findings


def _edge_words(e: EdgeFit) -> str:
    if e.worse == "rotation":
        return f"rotation residuals RMS {deg(e.rms_rotation_deg)}"
    return f"translation residuals RMS {mm(e.rms_translation_m)}"


def misfits(fit: FitStatistics | None, given: Problem, *,
            rejected: Mapping[str, int] | None = None,
            excluded: Iterable[str] = (),
            options: VerdictOptions | None = None) -> list[Misfit]:
    """The candidates for exclusion of a solution (module docstring, step 1).

    Parameters
    ----------
    fit : FitStatistics or None
        Of the solution, on the problem it solved.
    given : Problem
        The problem given to the solve (before outlier rejection): an edge's and a tag's pairs
        are counted there.
    rejected : mapping of str to int, optional
        Outlier rejection: edge ``"(x, y)"`` -> pairs it rejected (an edge wholly rejected
        included).
    excluded : iterable of str
        Edges excluded before (no longer in ``given``).
    options : VerdictOptions, optional
        ``exclusion_rejected_share``.
    """
    opts = options or VerdictOptions()
    sizes = {e.name: e.n for e in given.edges}
    by_tag: dict[str, list[str]] = {}
    for e in given.edges:
        by_tag.setdefault(e.x, []).append(e.name)
    out: dict[str, Misfit] = {}
    flagged = [] if fit is None else fit.flagged_edges()
    cameras_bad = set()
    if fit is not None:
        per_cam: dict[str, list[EdgeFit]] = {}
        for e in fit.edges:
            per_cam.setdefault(e.y, []).append(e)
        cameras_bad = {c for c, es in per_cam.items() if len(es) >= 2 and all(e.flagged
                                                                             for e in es)}
    flagged = [e for e in flagged if e.y not in cameras_bad]
    tags: dict[str, list[EdgeFit]] = {}
    for e in flagged:
        tags.setdefault(e.x, []).append(e)
    # the other edges of a tag found bad: wholly rejected, or excluded before
    lost: dict[str, list[str]] = {}
    for n in excluded:
        lost.setdefault(edge_target(n), []).append(f"{n} excluded before")
    for n, k in (rejected or {}).items():
        if n in sizes and int(k) >= sizes[n]:
            lost.setdefault(edge_target(n), []).append(f"{n} wholly rejected")
    for tag, es in tags.items():
        if len(es) + len(lost.get(tag, ())) >= 2 and tag in by_tag:
            detail = ", ".join(f"{e.y} {times(e.ratio)}" for e in es)
            every = ("every edge" if len(es) == len(by_tag[tag]) else
                     f"{len(es)} edge{'s' if len(es) > 1 else ''}")
            also = "; " + ", ".join(lost[tag]) if tag in lost else ""
            out[tag] = Misfit("tag", tag, tuple(by_tag[tag]), sum(sizes[n] for n in by_tag[tag]),
                              f"{every} of {tag} fit{'s' if len(es) == 1 else ''} far worse "
                              f"than the others ({detail} the noise of the median edge{also})")
    for e in flagged:
        if e.name in sizes and e.x not in out:
            out[e.name] = Misfit("edge", e.name, (e.name,), sizes[e.name],
                                 f"edge {e.name} fits {times(e.ratio)} the noise of the median "
                                 f"edge ({_edge_words(e)} over {e.pairs} pairs)")
    for tag, edges in by_tag.items():
        total = sum(sizes[n] for n in edges)
        gone = sum(min(int((rejected or {}).get(n, 0)), sizes[n]) for n in edges)
        if total and gone / total > opts.exclusion_rejected_share and tag not in out:
            out[tag] = Misfit("tag", tag, tuple(edges), total,
                              f"the outlier rejection left out {gone} of its {total} pairs")
    for name, n in sizes.items():
        gone = int((rejected or {}).get(name, 0))
        if 0 < gone < n and gone / n > opts.exclusion_rejected_share and name not in out:
            if edge_target(name) not in out:
                out[name] = Misfit("edge", name, (name,), n,
                                   f"the outlier rejection left out {gone} of its {n} pairs")
    return list(out.values())


#: At most this many candidates are tried per exclusion (those with the largest share of the
#: misfit, :func:`_misfit_chi2`): each trial is a solve.
_MAX_TRIALS = 6


def _misfit_chi2(m: Misfit, fit: FitStatistics | None) -> float:
    """The ``2 p`` of the candidate's edges in ``fit`` (its share of the misfit)."""
    if fit is None:
        return 0.0
    edges = set(m.edges)
    return float(sum(e.noise_ratio_translation ** 2 * e.dof_translation
                     + e.noise_ratio_rotation ** 2 * e.dof_rotation
                     for e in fit.edges if e.name in edges
                     and np.isfinite(e.noise_ratio_translation)
                     and np.isfinite(e.noise_ratio_rotation)))


def _without(problem: Problem, edges) -> Problem | None:
    gone = set(edges)
    kept = [e for e in problem.edges if e.name not in gone]
    return problem.with_edges(kept) if kept else None


def choose(candidates: list[Misfit], solved: Problem, options: VerdictOptions,
           solve_options=None) -> list[Misfit]:
    """The candidates with ``noise_ratio_without`` filled in (each left out of ``solved`` in
    turn, the rest solved with ``solve_options``, default mode ``fast``), best first (module
    docstring, step 2). A candidate whose exclusion leaves nothing to solve, or whose solve
    fails, comes last."""
    from ..solve import SolveOptions, solve

    scored = []
    for m in candidates:
        rest = _without(solved, m.edges)
        ratio = float("inf")
        if rest is not None and rest.edges and len(rest.edges) < len(solved.edges):
            try:
                res = solve(rest, solve_options or SolveOptions(mode="fast"))
                if res.certificate.status is not Status.SOLVER_FAILED:
                    ratio = goodness_of_fit(rest, res, options).noise_ratio
            except (ValueError, ArithmeticError, np.linalg.LinAlgError):
                pass
        if not np.isfinite(ratio):
            ratio = float("inf")
        scored.append(replace(m, noise_ratio_without=ratio))
    scored.sort(key=lambda m: (m.noise_ratio_without, m.pairs))
    return scored


# ------------------------------------------------------------------------------------------------
# the loop


def frame_shifts(first: CalibrationResult, final: CalibrationResult) -> list[FrameShift]:
    """Per frame in both results (cameras first), the translation [m] and rotation [deg]
    between the two estimates."""
    out = []
    for role, names_ in (("Y", final.y_names), ("X", final.x_names)):
        for n in names_:
            try:
                a, b = first.transform(n), final.transform(n)
            except KeyError:
                continue
            out.append(FrameShift(n, role, float(np.linalg.norm(a[:3, 3] - b[:3, 3])),
                                  float(np.degrees(rotation_distance(a[:3, :3], b[:3, :3])))))
    return out


def _first_solve(attempt: Attempt, fit: FitStatistics | None, given: Problem) -> FirstSolve:
    r = attempt.result
    c = r.certificate
    frames = {}
    for n in (*r.y_names, *r.x_names):
        q, t = transform_to_quat_xyzw(r.transform(n))
        frames[n] = {"translation": [float(v) for v in t],
                     "quaternion_xyzw": [float(v) for v in q]}
    nan = float("nan")
    return FirstSolve(
        c.status.value, bool(r.certified), float(c.suboptimality_bound), given.n_measurements,
        len(given.edges), nan if fit is None else fit.noise_ratio_translation,
        nan if fit is None else fit.noise_ratio_rotation,
        () if fit is None else tuple(e.name for e in fit.flagged_edges()), frames,
        attempt.noise_estimated)


def _add(excluded: list[Misfit], m: Misfit) -> None:
    """Append ``m``; a tag takes in the edges of it excluded before (one entry per target)."""
    if m.kind == "tag":
        mine = [e for e in excluded if e.kind == "edge" and edge_target(e.name) == m.name]
        if mine:
            for e in mine:
                excluded.remove(e)
            m = Misfit("tag", m.name, tuple(n for e in mine for n in e.edges) + m.edges,
                       m.pairs + sum(e.pairs for e in mine),
                       m.finding + "; before: " + "; ".join(e.finding for e in mine),
                       m.noise_ratio_without)
    excluded.append(m)


def _fit(attempt: Attempt, options: VerdictOptions) -> FitStatistics | None:
    try:
        return goodness_of_fit(attempt.problem, attempt.result, options,
                               noise_estimated=attempt.noise_estimated)
    except (ValueError, FloatingPointError):
        return None


def exclude_misfits(
    problem: Problem,
    first: Attempt,
    solve_fn: Callable[[Problem], Attempt],
    *,
    options: VerdictOptions | None = None,
    solve_options=None,
) -> tuple[Exclusion, Attempt]:
    """Exclude the targets and edges that do not fit, one at a time, solving again after each
    (module docstring).

    Parameters
    ----------
    problem : Problem
        The data given to the solve.
    first : Attempt
        ``solve_fn(problem)``, already made.
    solve_fn : callable
        ``Problem -> Attempt``: the caller's solve (mode, priors, outlier rejection), used for
        every re-solve; when it raises (``ValueError``, ``ArithmeticError``, ``LinAlgError``,
        ``RuntimeError``) the exclusion stops there and the previous solve is published.
    options : VerdictOptions, optional
        ``exclusion_max_rounds``, ``exclusion_max_share``, ``exclusion_rejected_share`` and the
        thresholds of the fit.
    solve_options : SolveOptions, optional
        For the candidates' trial solves (default: mode ``fast``).

    Returns
    -------
    (Exclusion, Attempt)
        What was excluded, and the solve to publish (``first`` when nothing was).
    """
    opts = options or VerdictOptions()
    fit = _fit(first, opts)
    exclusion = Exclusion(first=_first_solve(first, fit, problem),
                          pairs_total=problem.n_measurements,
                          pairs_kept=problem.n_measurements)
    current, given, gone = first, problem, 0
    unexplained: set[str] = set()  # cameras whose misfit no tag's exclusion explained
    while True:
        if current.result.certificate.status is Status.SOLVER_FAILED:
            exclusion.stopped = "the solver failed"
            break
        cands = misfits(fit, given, rejected=current.rejected, options=opts,
                        excluded=[n for m in exclusion.excluded for n in m.edges])
        cands = size_misfits(current, given, cands, opts)
        named = {m.name for m in cands}
        cands += [m for m in camera_misfits(current, given, opts)
                  if m.camera not in unexplained and m.name not in named]
        named |= {m.name for m in cands}
        cands += [m for m in step_misfits(current, given, opts) if m.name not in named]
        if not cands:
            break
        if len(exclusion.excluded) >= opts.exclusion_max_rounds:
            exclusion.stopped = (f"at most {opts.exclusion_max_rounds} exclusions "
                                 "(verdict.exclusion_max_rounds)")
            exclusion.remaining = tuple(m.name for m in cands)
            break
        budget = opts.exclusion_max_share * problem.n_measurements
        fits = [m for m in cands if gone + m.pairs <= budget]
        if not fits:
            exclusion.stopped = (f"excluding {names([m.name for m in cands])} would leave out "
                                 f"more than {100 * opts.exclusion_max_share:.0f} % of the pairs "
                                 "(verdict.exclusion_max_share): the misfit is not one target's")
            exclusion.remaining = tuple(m.name for m in cands)
            break
        fits = sorted(fits, key=lambda m: -_misfit_chi2(m, fit))[:_MAX_TRIALS]
        best = choose(fits, judged_weights(current.problem, fits), opts, solve_options)[0]
        rest = _without(given, best.edges)
        if rest is None:
            exclusion.stopped = f"excluding {best.name} would leave no data"
            exclusion.remaining = tuple(m.name for m in cands)
            break
        try:
            attempt = solve_fn(rest)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError, RuntimeError) as exc:
            exclusion.stopped = (f"the solve without {best.name} failed ({type(exc).__name__}: "
                                 f"{exc})")
            exclusion.remaining = tuple(m.name for m in cands)
            break
        if best.camera:
            checked = explained(best, current, attempt, opts)
            if checked is None:  # not this tag's: the camera's own (intrinsics, stamps)
                unexplained.add(best.camera)
                continue
            best = checked
        _add(exclusion.excluded, best)
        gone += best.pairs
        given, current = rest, attempt
        fit = _fit(current, opts)
    if exclusion.excluded:
        exclusion.shifts = frame_shifts(first.result, current.result)
        exclusion.pairs_kept = given.n_measurements
    return exclusion, current


# ------------------------------------------------------------------------------------------------
# the verdict's reasons


def exclusion_reasons(b: Builder, exclusion: Exclusion | None) -> None:
    """A ``caution`` per excluded target or edge (what was found, how far the cameras moved when
    it was left out, that the certificate is for the remaining data); an excluded tag is not
    calibrated (not published)."""
    if exclusion is None or not exclusion.excluded:
        return
    shifts = exclusion.shift_words("Y")
    moved = (f"; without {'it' if len(exclusion.excluded) == 1 else 'them'} {shifts} against "
             "the all-data solve") if shifts else ""
    note = exclusion.certificate_note()
    for m in exclusion.excluded:
        if m.kind == "tag":
            f = b.frames.get(m.name)
            if f is not None:
                f.calibrated = False
            text = (f"{m.name}: excluded and not calibrated: {m.finding}: {m.causes}{moved}; "
                    f"{note}; check "
                    f"{m.name} (its size: tags.sizes, or targets.{m.name}.* for a named target "
                    "or board; that it is fixed) or remove it from tags.ids (or targets.names)")
            b.add("unusable", "excluded", text, [m.name], why="excluded: does not fit")
        else:
            x, y = (p.strip() for p in m.name.strip("()").split(","))
            text = (f"edge {m.name} excluded: {m.finding}: a flipped tag pose, a tag that moved "
                    f"or a wrong size of {x}{moved}; {note}")
            b.add("caution", "excluded", text, [x], [(x, y)], why=f"edge {m.name} excluded")
        moved = ""  # the shifts once, with the first

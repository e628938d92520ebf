"""Misfits the edge statistics miss once the noise is estimated per camera (candidates of the
exclusion, :mod:`.exclusion`).

The fit (:mod:`.fit`) names an edge by its noise against its camera's estimated noise; a bad
target raises the estimated noise of the cameras that see it and so hides among their edges:

* **a tag of the wrong size**: its camera-tag distances disagree with the other tags'
  (:mod:`.tag_scale_check`); on the rendered rig of ``benchmarks/verdict.md`` (section 4) a tag
  10 % too small was named in no run and pulled the cameras 8-15 of their std off;
* **a tag that moved while one camera saw it** (seen by the others before the move): that camera
  is pulled towards the moved tag, and every edge of it fits badly alike -- its estimated noise
  is far above the other cameras' (25-31x on the rendered rig), which the verdict names as a
  camera fault (intrinsics, a loose mount, stamps) and no edge stands out. The tags this camera
  shares with other cameras are then candidates; the exclusion's choice (the rest fits best
  without it) picks one, and it is excluded only when the re-solve without it brings the
  camera's noise back within ``VerdictOptions.noise_group_ratio`` of the other cameras'
  (:func:`explained`). A camera whose misfit is its own (wrong intrinsics, a time offset) keeps
  it with any one tag left out: nothing is excluded, and the verdict names the camera.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..problem import Edge, Problem
from .misfit import Attempt, Misfit
from .options import VerdictOptions
from .words import times

__all__ = ["size_misfits", "camera_misfits", "explained", "judged_weights"]


def size_misfits(attempt: Attempt, given: Problem, found: list[Misfit],
                 options: VerdictOptions) -> list[Misfit]:
    """``found`` and the tags whose size disagrees with the other tags'
    (:mod:`.tag_scale_check`): a tag ``found`` already (by its edges) gets the size in its
    finding and causes (the fix: its true size), any other is added as a candidate (an edge of
    it may be one: the choice tries both)."""
    from .tag_scale_check import scale_misfit_tags

    by_tag = _by_tag(given)
    sizes = {e.name: e.n for e in given.edges}
    off = {s.tag: s for s in scale_misfit_tags(attempt.problem, attempt.result, options)
           if s.tag in by_tag}
    causes = "its size is wrong (or it is another tag)"
    out = [replace(m, finding=f"{m.finding}; {off[m.name].words()}", causes=causes)
           if m.kind == "tag" and m.name in off else m for m in found]
    named = {m.name for m in found if m.kind == "tag"}
    return out + [Misfit("tag", t, tuple(by_tag[t]), sum(sizes[n] for n in by_tag[t]),
                         s.words(), causes=causes) for t, s in off.items() if t not in named]


def _by_tag(problem: Problem) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for e in problem.edges:
        out.setdefault(e.x, []).append(e.name)
    return out


def _far(noise, options: VerdictOptions) -> dict[str, tuple[str, float, object]]:
    """Camera -> (component, ratio to the other cameras, its group) of the cameras whose
    estimated noise (on one kind of target, where a camera's group is split by kind) is far
    above the others' (:meth:`~rwhec_ros.core.noise.NoiseEstimate.far_above`)."""
    if noise is None or not getattr(noise, "estimated", False) or noise.grouping != "camera":
        return {}
    out: dict[str, tuple[str, float, object]] = {}
    for g, what, q, _ in noise.far_above(options.noise_group_ratio, options.significance):
        out.setdefault(g.camera or g.name, (what, float(q), g))
    return out


def camera_misfits(attempt: Attempt, given: Problem, options: VerdictOptions) -> list[Misfit]:
    """Per camera whose estimated noise is far above the other cameras' (at least three
    cameras), the tags it shares with another camera, as candidates (module docstring)."""
    if len({e.y for e in given.edges}) < 3:
        return []
    far = _far(attempt.noise, options)
    by_tag = _by_tag(given)
    sizes = {e.name: e.n for e in given.edges}
    out = []
    for cam, (what, q, group) in far.items():
        for tag, edges in by_tag.items():
            if len(edges) >= 2 and f"({tag}, {cam})" in group.edges:
                out.append(Misfit("tag", tag, tuple(edges), sum(sizes[n] for n in edges),
                                  f"{cam}'s {what} noise is {times(q)} the other cameras'",
                                  camera=cam))
    return out


def explained(m: Misfit, before: Attempt, after: Attempt, options: VerdictOptions
              ) -> Misfit | None:
    """``m`` with its finding in words when the re-solve without it (``after``) brings its
    camera's noise back within ``options.noise_group_ratio`` of the other cameras'; None when
    the camera stays far above (its misfit is not this tag's)."""
    if m.camera in _far(after.noise, options):
        return None
    what, q, group = _far(before.noise, options).get(m.camera,
                                                     ("translation", float("nan"), None))
    kind = "" if group is None else group.kind
    q_after = _ratio(after.noise, m.camera, what, kind)
    split = group is not None and group.name != group.camera  # its targets of one kind
    on = f" on {kind} targets" if split else ""
    now = (f"{times(q_after)} without it" if np.isfinite(q_after)
           else f"{m.camera} has no other {kind} target" if split
           else "among the others' without it")
    was = f"{times(q)} the other cameras'" if np.isfinite(q) else "far above the other cameras'"
    return replace(m, finding=(
        f"{m.camera}'s {what} noise{on} is {was} with {m.name} and {now}: {m.name} "
        f"does not fit where {m.camera} saw it"),
        causes="it moved during the recording (or was bumped), its pose flips on "
               f"{m.camera}'s views, or its size is wrong")


def _ratio(noise, camera: str, what: str, kind: str = "") -> float:
    """The camera's estimated noise over the median of the other cameras' (``what``), its group
    of targets of ``kind`` against the others of that kind."""
    if noise is None:
        return float("nan")
    std = {(g.camera or g.name): (g.sigma_m if what == "translation" else g.rotation_std_deg)
           for g in noise.groups if g.kind == kind}
    others = [v for k, v in std.items() if k != camera]
    if camera not in std or not others:
        return float("nan")
    med = float(np.median(others))
    return std[camera] / med if med > 0 else float("nan")


def judged_weights(problem: Problem, candidates: list[Misfit]) -> Problem:
    """``problem`` with the pairs of the candidates' cameras weighted by the median noise of the
    other cameras' pairs: the yardstick of the exclusion's choice. With the camera's own
    estimated noise (25-31x the others' on the rendered rig) its misfit barely counts, and
    leaving out a tag the camera shares with another (its edges there flagged because the camera
    is pulled) looked as good as leaving out the tag that moved; ``problem`` itself when no
    candidate is a camera's."""
    cams = {m.camera for m in candidates if m.camera}
    if not cams:
        return problem
    others = [e for e in problem.edges if e.y not in cams]
    if not others:
        return problem
    sigma = float(np.median(np.concatenate([e.sigma for e in others])))
    kappa = float(np.median(np.concatenate([e.kappa for e in others])))
    return problem.with_edges([
        Edge.build(e.x, e.y, e.A, e.B, sigma=sigma, kappa=kappa) if e.y in cams else e
        for e in problem.edges])

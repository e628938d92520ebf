"""The noise the data fit, per noise group, in the verdict (with the noise estimated from the data,
:mod:`rwhec_ros.core.noise`).

* A **stated** noise is a check: a group whose residuals fit significantly more than the stated
  noise (``verdict.fit_caution_ratio``, ``verdict.fit_unusable_ratio``, std units) is a reason,
  as the global fit test was when the stated noise weighted the solve; a stated noise far *above*
  the data's is no fault (the estimate is used) and is only said
  (:func:`~rwhec_ros.core.noise.words.stated_comparisons`).
* A group far noisier than the others (``verdict.noise_group_ratio`` times their median,
  significantly: F-test) is named: a camera with wrong intrinsics, a loose mount, motion blur or a
  time offset of its own; a moved or flipped target shows on its edges instead (the edge check of
  :mod:`.reasons`, each edge against the noise of its camera).
* The precision check widens each frame's std by the upper confidence factor of the estimate
  (:func:`precision_factors`).
"""

from __future__ import annotations

import numpy as np

from ..noise.estimate import NoiseEstimate, std_upper_factor
from ..problem import Problem
from .model import Builder
from .options import VerdictOptions
from .words import deg, mm

__all__ = ["noise_reasons", "precision_factors", "stated_scale"]

_CAUSES = {
    "translation": "check the tag sizes, the camera intrinsics and the time sync of the images "
                   "with the pose stream",
    "rotation": "check the time sync of the images with the pose stream, the camera intrinsics "
                "and tag poses that flip",
}


def _value(g, what: str, stated: bool = False) -> str:
    if what == "translation":
        return mm(g.sigma_given_m if stated else g.sigma_m)
    return deg(g.rotation_std_given_deg if stated else g.rotation_std_deg) + " per axis"


def _frames(noise: NoiseEstimate, problem: Problem, groups) -> list[str]:
    """The frames a reason about ``groups`` concerns: their cameras (per-camera groups), their
    edges' frames (per-edge groups); none for the global group."""
    if noise.grouping == "camera":
        return list(dict.fromkeys(g.camera or g.name for g in groups))
    if noise.grouping == "camera_target":
        names = {g.name for g in groups}
        return list(dict.fromkeys(n for e in problem.edges if e.name in names
                                  for n in (e.x, e.y)))
    return []


def noise_reasons(b: Builder, noise: NoiseEstimate | None, problem: Problem,
                  opts: VerdictOptions) -> None:
    """The reasons of the module docstring, added to ``b``."""
    if noise is None or not noise.estimated:
        return
    if noise.given == "stated":
        for what in ("translation", "rotation"):
            bad = [(g, g.component(what).ratio) for g in noise.groups
                   if g.component(what).source in ("estimated", "pooled")
                   and g.component(what).ratio > opts.fit_caution_ratio
                   and g.component(what).p_stated() < opts.significance]
            if not bad:
                continue
            s = max(r for _, r in bad)
            level = "unusable" if s > opts.fit_unusable_ratio else "caution"
            fits = ", ".join(f"{g.name} {_value(g, what)} ({r:.1f}x)" for g, r in bad)
            stated = sorted({_value(g, what, stated=True) for g, _ in bad})
            frames = _frames(noise, problem, [g for g, _ in bad])
            if set(frames) >= set(problem.y_names):
                frames = []  # every camera: the whole result
            b.add(level, "fit",
                  f"the {what} residuals fit {fits}, stated {' / '.join(stated)}: the data are "
                  f"noisier than stated; the estimate weights the solve and gives the stds, but "
                  f"a noise this far above what the setup should give points at a fault: "
                  f"{_CAUSES[what]} (or leave the noise to the data: noise.sigma and "
                  "noise.kappa 0)", frames, why=f"{what} fit {s:.1f}x the stated noise")
    names = "cameras" if noise.grouping == "camera" else "groups"
    done: set[str] = set()
    for g, what, q, _ in noise.far_above(opts.noise_group_ratio, opts.significance):
        if g.name in done:
            continue
        done.add(g.name)
        own = _value(g, what)
        med = (mm(g.sigma_m / q) if what == "translation"
               else deg(g.rotation_std_deg / q) + " per axis")
        code = {"camera": "camera", "camera_target": "edge"}.get(noise.grouping, "fit")
        of = f" on {g.kind} targets" if g.camera and g.name != g.camera else ""
        b.add("caution", code,
              f"{g.name}: its {what} noise ({own}) is {q:.1f}x the median of the other "
              f"{names}{of} "
              f"({med}); its pairs are weighted down by it, but one camera this much noisier "
              "than the rest usually has a fault: wrong intrinsics (focal length, distortion), "
              f"a loose mount, motion blur or a time offset of its own; check {g.name}",
              _frames(noise, problem, [g]), why=f"{what} noise {q:.1f}x the other {names}'")


def precision_factors(noise: NoiseEstimate | None, problem: Problem, opts: VerdictOptions
                      ) -> dict[str, float]:
    """Per frame whose pairs' noise was estimated, the upper confidence factor of the estimate
    at ``opts.noise_confidence`` (the fewest degrees of freedom among the estimates that weight
    its pairs, :meth:`~rwhec_ros.core.noise.NoiseEstimate.frame_dof`); frames with a given
    (not estimated) noise are left out (the fit's factor applies)."""
    if noise is None or not noise.estimated:
        return {}
    return {name: std_upper_factor(dof, opts.noise_confidence)
            for name, dof in noise.frame_dof(problem).items() if np.isfinite(dof) and dof > 0}


def stated_scale(noise: NoiseEstimate | None) -> dict[str, tuple[float, float]] | None:
    """Per edge ``"(x, y)"``, the factors (std units: translation, rotation) from the stated
    noise to the weights the solve used (its group's ``sqrt(used)``), for the edge check's
    "clearly beyond the stated noise" rule; None unless the noise was estimated and stated."""
    if noise is None or not noise.estimated or noise.given != "stated":
        return None
    return {e: (float(np.sqrt(g.translation.used)), float(np.sqrt(g.rotation.used)))
            for g in noise.groups for e in g.edges}

"""A target that jumped during the recording: a step in its place, pair after pair (a candidate of
the exclusion, :mod:`.exclusion`), for the targets nothing else compares.

With the noise estimated per camera and kind of target (:mod:`rwhec_ros.core.noise.groups`), the
only target of its kind (a board among single tags) has a noise group of its own on every camera:
a fault of its own that raises all its residuals alike -- a board bumped during the recording and
seen before and after the move by every camera -- is absorbed into that noise, and no edge, tag
or camera stands out (a board 5 cm off for the second half of a synthetic recording was published
GOOD, 26 mm off its true place with a std of 4 mm). What tells a move from a noisier detector is
the order of the pairs: a fixed target's place ``X_i = A_i^-1 Y B_i`` (each pair's implied pose of
the target in the world, at the solution's ``Y`` and scale) scatters around one value, a moved
target's jumps from one value to another.

**The test**, per edge of such a target, pairs in recording order: for each split ``s`` (at least
:data:`MIN_SIDE` pairs on each side) and each component (the translation of ``X_i``, and its
rotation vector from the first pair's), the F statistic of two means against one,
``F = (n1 n2 / n |m1 - m2|^2 / 3) / (W / (3 (n - 2)))`` with ``W`` the scatter within the two
segments, ``F(3, 3 (n - 2))`` under "no step" for independent pairs of equal noise. The largest
over the splits and the two components is significant when its p-value, times the number of
splits and components tested (Bonferroni) and the number of edges tested (every target's), is
below ``VerdictOptions.significance``. A lone target with such an edge is a candidate, when no
other target has one (a drift common to all targets -- a robot's kinematic errors, a pose
stream that shifted -- is not one target's move): the exclusion leaves it out (it has no other
of its kind to be compared with, so the step is the evidence).
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from ..lie import invert_transform, so3_log
from ..problem import Problem
from .misfit import Attempt, Misfit, edge_target
from .options import VerdictOptions

__all__ = ["MIN_SIDE", "lone_targets", "step_statistic", "step_misfits"]

#: Fewest pairs on each side of a split.
MIN_SIDE = 3


def lone_targets(noise) -> set[str]:
    """The targets that are the only target of their kind, in a problem whose noise groups were
    split by kind (:attr:`~rwhec_ros.core.noise.GroupNoise.kind`); empty when no camera's group
    was split (then every target is compared with its camera's others)."""
    if noise is None or getattr(noise, "grouping", "") != "camera":
        return set()
    groups = list(getattr(noise, "groups", ()))
    if not any(g.camera and g.name != g.camera for g in groups):
        return set()
    by_kind: dict[str, set[str]] = {}
    for g in groups:
        for e in g.edges:
            by_kind.setdefault(g.kind, set()).add(edge_target(e))
    return {next(iter(xs)) for kind, xs in by_kind.items() if kind and len(xs) == 1}


def step_statistic(T: np.ndarray) -> tuple[float, int, tuple[float, float], tuple[float, float]]:
    """The largest step of the places ``T`` (N, 4, 4), in order (module docstring): ``(p-value
    of the largest F before the Bonferroni factor, split index s (the first pair after the
    step), (translation step [m], its p-value), (rotation step [deg], its p-value))``;
    ``(1.0, 0, (0, 1), (0, 1))`` with fewer than ``2 MIN_SIDE`` places."""
    n = T.shape[0]
    best = (1.0, 0, (0.0, 1.0), (0.0, 1.0))
    if n < 2 * MIN_SIDE:
        return best
    t = T[:, :3, 3]
    r = np.array([so3_log(T[0, :3, :3].T @ R) for R in T[:, :3, :3]])
    dof = 3 * (n - 2)
    s = np.arange(MIN_SIDE, n - MIN_SIDE + 1)  # every split at once, from cumulative sums
    steps, ps = [], []
    for comp in (t, r):
        c = comp - comp.mean(axis=0)  # centred: the sums of squares lose no digits
        S, Q = np.cumsum(c, axis=0), np.cumsum(np.sum(c * c, axis=1))
        m1 = S[s - 1] / s[:, None]
        m2 = (S[-1] - S[s - 1]) / (n - s)[:, None]
        between = s * (n - s) / n * np.sum((m1 - m2) ** 2, axis=1)
        within = (Q[s - 1] - s * np.sum(m1 * m1, axis=1)) \
            + (Q[-1] - Q[s - 1] - (n - s) * np.sum(m2 * m2, axis=1))
        with np.errstate(divide="ignore", invalid="ignore"):
            f = (between / 3) / (within / dof)
        p = np.where(within > 0, stats.f.sf(np.nan_to_num(f, posinf=np.inf), 3, dof),
                     np.where(between > 0, 0.0, 1.0))
        steps.append(np.linalg.norm(m1 - m2, axis=1))
        ps.append(p)
    p = np.minimum(ps[0], ps[1])
    i = int(np.argmin(p))
    if not p[i] < 1.0:
        return best
    return (float(p[i]), int(s[i]), (float(steps[0][i]), float(ps[0][i])),
            (float(np.degrees(steps[1][i])), float(ps[1][i])))


def _places(attempt: Attempt, name: str) -> dict[str, np.ndarray]:
    """Per edge ``"(x, y)"`` of target ``name`` in the solved problem, the places ``A_i^-1 Y B_i``
    of its pairs (N, 4, 4), B's translations in metres (over the scale)."""
    res, problem = attempt.result, attempt.problem
    out = {}
    for e in problem.edges:
        if e.x != name or e.y not in res.y_names:
            continue
        B = e.B.copy()
        B[:, :3, 3] = B[:, :3, 3] / float(res.scale or 1.0)
        out[e.name] = invert_transform(e.A) @ res.transform(e.y) @ B
    return out


def _stepping(places: dict[str, np.ndarray], tested: int, significance: float) -> list[str]:
    """The steps in words of the edges (``"(x, y)"`` -> places) whose step is significant
    (Bonferroni over the splits, the two components and ``tested`` edges)."""
    found = []
    for edge, T in places.items():
        p, s, (dt, pt), (dr, pr) = step_statistic(T)
        factor = 2 * (T.shape[0] - 2 * MIN_SIDE + 1) * tested
        if s and p * factor < significance:
            size = " / ".join(w for w, q in ((f"{1e3 * dt:.0f} mm", pt), (f"{dr:.1f} deg", pr))
                              if q * factor < significance)
            found.append(f"{size} on {edge} from its pair {s + 1} of {T.shape[0]}")
    return found


def step_misfits(attempt: Attempt, given: Problem, options: VerdictOptions) -> list[Misfit]:
    """The lone targets (:func:`lone_targets`) one of whose edges has a significant step (module
    docstring), as candidates of the exclusion -- provided no other target steps too: the
    places of all targets drifting alike between the two parts of a recording (a robot's
    kinematic errors, a pose stream that shifted) are not one target's move, and the other
    checks of the verdict see them."""
    lone = lone_targets(attempt.noise)
    if not lone:
        return []
    places = {x: _places(attempt, x) for x in sorted({e.x for e in attempt.problem.edges})}
    tested = sum(len(v) for v in places.values())
    others = [x for x in places if x not in lone]
    if any(_stepping(places[x], tested, options.significance) for x in others):
        return []
    out = []
    for x in sorted(lone):
        found = _stepping(places[x], tested, options.significance)
        if not found:
            continue
        mine = tuple(e.name for e in given.edges if e.x == x)
        pairs = sum(e.n for e in given.edges if e.x == x)
        out.append(Misfit(
            "tag", x, mine, pairs,
            f"{x}'s place (A^-1 Y B of each pair, in recording order) jumps: "
            + "; ".join(found) + " (the only target of its kind, while the other targets stay "
            "put)", causes="it moved during the recording (or was bumped)"))
    return out

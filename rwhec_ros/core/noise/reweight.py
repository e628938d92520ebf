"""The solve with the noise estimated from the data: :func:`solve_with_noise`.

Foerstner's iteration (:mod:`.estimate`): solve with the current weights, estimate each group's
variance factors at the solution, re-weight, and again, until the weights of the last solve fit
the data (every factor within :attr:`~.estimate.NoiseOptions.tolerance` of 1). Each solve after
the first starts the local solver from the previous estimate (the optimum moves a little when the
weights change). The last solve is a solve like any other: certified, or not, for the weighted
problem it returns (``result.certificate.weights`` is ``"estimated"``), and the uncertainty of
that problem is the one of the final weights.

*Warm weights*: the live re-solve passes the previous estimate's factors (``warm``); with a few
more pairs they still fit, so one solve and one estimate usually suffice.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..problem import Edge, Problem
from ..result import CalibrationResult, Status
from ..solve import SolveOptions, solve
from .estimate import NoiseEstimate, NoiseOptions, estimate_noise
from .groups import NoiseGroups, noise_groups

__all__ = ["NoiseSolve", "solve_with_noise", "weighted_problem", "weighted_as"]


@dataclass
class NoiseSolve:
    """A solve with estimated noise.

    Attributes
    ----------
    result : CalibrationResult
        The solve with the final weights.
    problem : Problem
        The problem it solves: the given pairs with the final weights.
    estimate : NoiseEstimate or None
        The noise per group at that solve (None when estimation is off or failed; ``notes``
        say why).
    changes : list of float
        After each solve, the largest ``|factor / used - 1|``: how far its weights were from the
        data's (the iteration's progress).
    seconds : float
        Wall time of all the solves and estimates.
    notes : list of str
    """

    result: CalibrationResult
    problem: Problem
    estimate: NoiseEstimate | None
    changes: list[float] = field(default_factory=list)
    seconds: float = 0.0
    notes: list[str] = field(default_factory=list)


def weighted_problem(problem: Problem, groups: NoiseGroups,
                     factors: dict[str, tuple[float, float]]) -> Problem:
    """``problem`` with each group's ``sigma`` times ``sqrt(f_t)`` and ``kappa`` over ``f_R``
    (``factors``: group name -> ``(f_t, f_R)``, missing groups 1). Its
    ``precomputed_blocks``, when set, are scaled along (translation and rotation part of each
    edge block, :func:`~rwhec_ros.core.model.cost.edge_blocks`): exact, no pair summed again.
    ``problem`` itself when every factor is 1."""
    ft = np.array([factors.get(n, (1.0, 1.0))[0] for n in groups.names])[groups.edge_group]
    fr = np.array([factors.get(n, (1.0, 1.0))[1] for n in groups.names])[groups.edge_group]
    if np.all(ft == 1.0) and np.all(fr == 1.0):
        return problem
    st, kr = np.sqrt(ft), 1.0 / fr
    edges = [Edge._of(e.x, e.y, e.A, e.B, e.sigma * st[i], e.kappa * kr[i])
             for i, e in enumerate(problem.edges)]
    out = Problem(problem.x_names, problem.y_names, edges, unknown_scale=problem.unknown_scale)
    pre = problem.precomputed_blocks
    if pre is not None:
        full, rot, idx = pre
        ct, cr = (1.0 / ft)[:, None, None], kr[:, None, None]
        out.precomputed_blocks = (ct * (full - rot) + cr * rot, cr * rot, idx)
    return out


def weighted_as(problem: Problem, grouping: str, factors: dict[str, tuple[float, float]],
                group_edges: Mapping[str, Sequence[str]] | None = None) -> Problem:
    """``problem`` (the given weights) with the weights of a solve whose noise groups were
    ``grouping`` and variance factors ``factors`` (group name -> ``(f_t, f_R)``, e.g. the
    ``used`` factors a result YAML's ``noise`` section keeps): what a report made later from
    the data set needs to show the fit the solve had. ``group_edges`` (group name -> its edges
    ``"(x, y)"``, the section's ``edges``): the groups as solved (a camera split by kind of
    target); an edge of none of them keeps the given weight."""
    if group_edges is None:
        return weighted_problem(problem, noise_groups(problem, grouping), factors)
    names = tuple(group_edges)
    of = {e: i for i, n in enumerate(names) for e in group_edges[n]}
    extra = len(names)
    groups = NoiseGroups(grouping, names + ("(none)",),
                         np.array([of.get(e.name, extra) for e in problem.edges], dtype=int))
    return weighted_problem(problem, groups, factors)


def _warm_factors(warm: dict | None, names) -> dict[str, tuple[float, float]]:
    """The start factors: ``warm``'s for the groups it has; a new group starts at the geometric
    mean of ``warm``'s (its camera is likely no different from the others), else 1."""
    if not warm:
        return {n: (1.0, 1.0) for n in names}
    vals = np.log(np.array(list(warm.values()), dtype=float))
    mean = tuple(float(v) for v in np.exp(vals.mean(axis=0)))
    return {n: tuple(warm.get(n, mean)) for n in names}


def solve_with_noise(
    problem: Problem,
    solve_options: SolveOptions | None = None,
    options: NoiseOptions | None = None,
    *,
    warm: dict[str, tuple[float, float]] | None = None,
) -> NoiseSolve:
    """Solve ``problem`` with its noise estimated from the data (module docstring).

    Parameters
    ----------
    problem : Problem
        The pairs with the given ``sigma``/``kappa`` (``options.given`` says what they are).
    solve_options : SolveOptions, optional
        Of every solve; in mode ``sdp`` the iterations solve ``fast`` and the final weights are
        solved once more in ``sdp``. ``initial`` starts the first solve.
    options : NoiseOptions, optional
        ``estimate`` False: one solve with the given noise (``estimate`` None).
    warm : dict of str to (float, float), optional
        Start factors per group (the previous estimate's :meth:`NoiseEstimate.factors`).

    Returns
    -------
    NoiseSolve
        Exceptions of the solver propagate; an estimate that cannot be computed (e.g. a
        singular information matrix) ends the iteration with the weights of the last solve and a
        note.
    """
    t0 = time.perf_counter()
    opts = options or NoiseOptions()
    so = copy.copy(solve_options or SolveOptions())
    if not opts.estimate:
        return NoiseSolve(solve(problem, so), problem, None, seconds=time.perf_counter() - t0)
    final_mode = so.mode
    if so.mode == "sdp":
        so.mode = "fast"
    groups = noise_groups(problem, opts.groups, dict(opts.kinds))
    factors = _warm_factors(warm, groups.names)
    changes: list[float] = []
    notes: list[str] = []
    est = None
    # a component found below the redundancy bound once stays at its given value: a component's
    # redundancy depends on the weights, and near the bound the estimate flipped between its own
    # value and the given one at every solve, leaving the weights of whichever solve came last
    # (5-pair folds of a real 6-view chessboard set: 8 solves, "139697 % off")
    kept: dict[str, tuple[bool, bool]] = {}
    for k in range(1, int(opts.max_solves) + 1):
        weighted = weighted_problem(problem, groups, factors)
        result = solve(weighted, so)
        if result.certificate.status is Status.SOLVER_FAILED:
            notes.append(f"noise estimation stopped after {k} solve(s): the solver failed")
            break
        try:
            est = estimate_noise(weighted, result, opts, gauge=so.gauge, given=problem,
                                 used=factors, groups=groups, keep_given=kept)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            notes.append(f"noise estimation stopped after {k} solve(s): {exc}")
            est = None
            break
        est.solves = k
        changes.append(est.largest_change)
        if est.converged or k == opts.max_solves:
            break
        factors = est.factors()
        kept = {g.name: (kept.get(g.name, (False, False))[0] or g.translation.source == "given",
                         kept.get(g.name, (False, False))[1] or g.rotation.source == "given")
                for g in est.groups}
        so.initial = (result.X, result.Y) if result.certified else None
    if est is not None and not est.converged:
        est.notes.append(f"not converged in {est.solves} solves (the last weights are "
                         f"{100 * est.largest_change:.1f} % off the data's in variance): they "
                         "are used")
    if final_mode == "sdp":
        so.mode, so.initial = "sdp", None
        result = solve(weighted, so)
    if est is not None and est.estimated:
        result.noise = est
        result.certificate.weights = "estimated"
        result.notes.append(
            f"weights: noise estimated from the data per {opts.groups.replace('_', '-')} "
            f"group in {est.solves} solve{'s' if est.solves > 1 else ''}; the certificate is "
            "for the problem with those weights")
    return NoiseSolve(result, weighted, est, changes, time.perf_counter() - t0, notes)

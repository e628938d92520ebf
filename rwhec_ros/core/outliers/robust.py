"""The robust solve: RANSAC (optional), GNC-TLS, and a certified solve on the inlier set.

After RANSAC (:mod:`.ransac`) and the GNC-TLS loop (:mod:`.gnc`) the weights are binarised
(``w > 0.5``) and the inlier problem is solved once more with the certifiable solver
(``SolveOptions(mode="fast")`` by default): that certified result is returned. Frames all of
whose pairs are rejected disappear from the result (listed in ``notes``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..problem import Problem
from ..result import CalibrationResult
from ..solve import solve
from .gnc import gnc_tls, initial_for, tls_threshold, update_frames
from .options import RobustOptions
from .pairs import residuals_by_name, restrict_problem
from .ransac import RansacReport, ransac_filter

__all__ = ["RobustResult", "robust_solve"]


@dataclass
class RobustResult:
    """Outcome of :func:`robust_solve`.

    Attributes
    ----------
    result : CalibrationResult
        Solution of the inlier problem, certified by the final solve (check ``result.certified``).
    inliers : dict of str to ndarray of bool
        Edge name -> mask (N,) over the ORIGINAL pairs of that edge (all edges of the input).
    rejected : list of (str, int, str)
        ``(edge, index, reason)`` for every rejected pair (RANSAC and GNC), original indices.
    iterations : int
        Weighted solves of the GNC loop.
    ransac : RansacReport or None
    threshold : float
        ``c^2`` used for the truncation.
    converged : bool
        GNC reached a binary fixed point before ``max_iterations``.
    weights : dict of str to ndarray
        Final GNC weights over the original pairs (0 for pairs RANSAC rejected).
    residuals : dict of str to ndarray
        ``J_i`` of every original pair at the final estimate (``nan`` if a frame of the edge was
        not estimated).
    inlier_problem : Problem
        The problem that ``result`` solves.
    """

    result: CalibrationResult
    inliers: dict[str, np.ndarray]
    rejected: list[tuple[str, int, str]]
    iterations: int
    ransac: RansacReport | None
    threshold: float
    converged: bool
    weights: dict[str, np.ndarray]
    residuals: dict[str, np.ndarray]
    inlier_problem: Problem

    @property
    def n_inliers(self) -> int:
        return int(sum(int(m.sum()) for m in self.inliers.values()))

    @property
    def n_rejected(self) -> int:
        return len(self.rejected)



def robust_solve(
    problem: Problem,
    *,
    options: RobustOptions | None = None,
    rng: np.random.Generator | None = None,
) -> RobustResult:
    """RANSAC (optional), GNC-TLS around the certifiable solver, and a certified final solve.

    Parameters
    ----------
    problem : Problem
    options : RobustOptions, optional
    rng : numpy.random.Generator, optional
        Randomness of the RANSAC stage; ``None`` uses ``np.random.default_rng(0)`` so that the
        result is reproducible.

    Returns
    -------
    RobustResult
        ``result`` is the solution of the binarised inlier problem from
        ``solve(inliers, options.solve)`` with its certificate; ``inliers``/``rejected`` refer to
        the pairs of the input ``problem``.
    """
    options = options or RobustOptions()
    if rng is None:
        rng = np.random.default_rng(0)
    c2 = options.gnc.threshold if options.gnc.threshold is not None else tls_threshold(
        options.gnc.quantile)
    report = ransac_filter(problem, options.ransac, rng=rng) if options.use_ransac else None
    work = report.filtered(problem) if report is not None else problem
    kept_idx = {
        e.name: (report.edges[e.name].kept if report is not None else np.arange(e.n))
        for e in problem.edges
    }
    gnc = gnc_tls(work, c2, options.gnc)
    masks = {name: w > 0.5 for name, w in gnc.weights.items()}
    inlier_problem = restrict_problem(work, masks, what="gnc")
    final_opts = options.solve
    if final_opts.initial is None:
        final_opts = dataclasses.replace(
            final_opts, initial=initial_for(inlier_problem, gnc.frames))
    result = solve(inlier_problem, final_opts)

    frames = dict(gnc.frames)
    update_frames(frames, result)
    alpha = result.scale if problem.unknown_scale else 1.0
    final_res = residuals_by_name(problem, frames, alpha)

    inliers: dict[str, np.ndarray] = {}
    weights: dict[str, np.ndarray] = {}
    residuals: dict[str, np.ndarray] = {}
    rejected: list[tuple[str, int, str]] = []
    ransac_reasons = {(n, i): why for n, i, why in report.rejected} if report else {}
    n_gnc = 0
    disagree = 0
    for e in problem.edges:
        mask = np.zeros(e.n, dtype=bool)
        w_full = np.zeros(e.n)
        idx = kept_idx[e.name]
        if e.name in gnc.weights:
            mask[idx] = masks[e.name]
            w_full[idx] = gnc.weights[e.name]
        inliers[e.name] = mask
        weights[e.name] = w_full
        pr = final_res[e.name]
        residuals[e.name] = pr.normalised if pr is not None else np.full(e.n, np.nan)
        in_gnc = np.zeros(e.n, dtype=bool)
        in_gnc[idx] = True
        for i in range(e.n):
            if mask[i]:
                if pr is not None and pr.normalised[i] > c2:
                    disagree += 1
                continue
            if not in_gnc[i]:
                rejected.append((e.name, i, f"RANSAC: {ransac_reasons[(e.name, i)]}"))
                continue
            n_gnc += 1
            if pr is None:
                why = "GNC-TLS: weight 0 for every pair of the edge; a frame is not estimated"
            else:
                why = (f"GNC-TLS: normalised residual {pr.normalised[i]:.3g} "
                       f"{'>' if pr.normalised[i] > c2 else '<='} c^2 = {c2:.3g} (translation "
                       f"{pr.translation[i]:.3g} m, rotation {np.rad2deg(pr.rotation[i]):.3g}°)")
                if pr.normalised[i] <= c2:
                    disagree += 1
            rejected.append((e.name, i, why))

    notes = result.notes
    if report is not None:
        notes.append(f"robust_solve: RANSAC kept {report.n_kept} of {problem.n_measurements} "
                     f"pairs, dropped edges {[n for n, _ in report.dropped]}")
    notes.append(
        f"robust_solve: GNC-TLS rejected {n_gnc} pairs in {gnc.iterations} weighted solves "
        f"(c^2 = {c2:.3g}, {'converged' if gnc.converged else 'NOT converged'}; "
        f"{gnc.inner_certified} inner solves certified)"
    )
    if disagree:
        notes.append(f"robust_solve: {disagree} pairs are classified differently by the final "
                     f"estimate's residual than by the GNC weights (borderline)")
    lost = [n for n in problem.frame_names if n not in inlier_problem.frame_names]
    if lost:
        notes.append(f"robust_solve: frames without any inlier pair, not estimated: {lost}")
    return RobustResult(
        result=result, inliers=inliers, rejected=rejected, iterations=gnc.iterations,
        ransac=report, threshold=c2, converged=gnc.converged, weights=weights,
        residuals=residuals, inlier_problem=inlier_problem,
    )

"""Per-edge RANSAC on the model of eq. (70) (paper Section 9.1) over a whole problem.

The paper knew ``Y_k`` from Kalibr and hypothesised ``X_j`` from one pair with eq. (70). We do not
know ``Y_k``, so each edge is first treated as its own 1X1Y problem (*stage 1*):

* minimal sample: 3 pairs whose relative A rotations ``R_A1^T R_A2`` and ``R_A1^T R_A3`` span two
  axes (second singular value of their stacked rotation vectors ``>= min_axis_span_deg``);
  ``(X, Y)`` solved in closed form (null vector of the stacked linear rotation equations
  ``(I (x) R_A) vec R_X - (R_B^T (x) I) vec R_Y = 0``, projected onto SO(3), then linear least
  squares for ``R_A t_X - t_Y = R_Y t_B - t_A``);
* a pair is an inlier iff its translation residual is ``<= translation_threshold`` (0.6 m) AND its
  rotation residual ``<= rotation_threshold_deg`` (60 deg), the paper's values;
* the best hypothesis (largest consensus set, ties broken by the truncated quadratic MSAC score) is
  refitted on its consensus set (weighted by ``kappa`` and ``1/sigma^2``) and re-scored until the
  set is stable (at most ``local_refinements`` rounds); the refined model's consensus set is the
  one reported. A minimal sample from noisy pairs can be off by decimetres, which lets an outlier
  with a 1 m error slip under the 0.6 m threshold; the refit removes that bias;
* the number of hypotheses adapts to the inlier ratio ``w``:
  ``ceil(log(1 - confidence) / log(1 - w^3))``, clamped to ``[min_iterations, max_iterations]``;
  when ``C(N, 3) <= max_iterations`` the triples are enumerated (in random order) instead of drawn;
* the edge is kept iff the consensus set holds at least ``min_inlier_fraction`` (one third, paper)
  of its pairs (and at least 3).

Edges that stage 1 cannot hypothesise -- 2 pairs, or A rotations that never span two axes (e.g.
planar motion) -- go to *stage 2*, which is the paper's scheme: once a frame of the edge has been
estimated by an accepted edge (``Y_k`` preferred, as in the paper, else ``X_j``), each pair gives a
hypothesis ``X_j = A_i^-1 Y_k B_i`` (or ``Y_k = A_i X_j B_i^-1``), scored the same way; the edge is
kept iff the consensus set holds at least one third of the pairs AND at least 2 pairs (a single
pair agrees with itself and validates nothing). Stage 2 is repeated while it validates new frames.

* **Single-pair edges** are dropped, as in the paper: they cannot be validated.
* **Two-pair edges** are kept (both pairs) only if, in stage 2, the two pairs agree under eq. (70)
  with a frame known from a validated edge; if they disagree neither can be blamed and the edge is
  dropped; if no validated edge shares a frame they are dropped as unvalidated.
* **Limitation**: when no edge is identifiable on its own (e.g. every edge saw only planar
  motion) stage 1 validates nothing, stage 2 has no
  frame to start from, and every edge is dropped; use ``RobustOptions(use_ransac=False)`` (GNC
  alone) for such data.
* **Unknown scale** (monocular, Problem 3): like the paper we assume the tag size known within 10 %,
  i.e. ``|alpha - 1| <= scale_tolerance``. RANSAC runs with ``alpha = 1`` and the translation
  threshold of pair ``i`` is widened to ``translation_threshold + scale_tolerance |t_B_i|``, about
  the largest translation residual a correct pair can get from the scale error alone
  (``|(1 - 1/alpha) t_B|`` at the true frames). It can let a translation outlier of
  ``~ translation_threshold + scale_tolerance |t_B|`` through; GNC then still has it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..problem import Edge, Problem
from .consensus import (
    MINIMAL_SAMPLE,
    Consensus,
    ransac_1x1y,
    ransac_given,
    translation_thresholds,
)
from .options import RansacOptions
from .pairs import restrict_problem

__all__ = ["EdgeRansacReport", "RansacReport", "ransac_filter"]


@dataclass
class EdgeRansacReport:
    """RANSAC outcome of one edge.

    Attributes
    ----------
    edge : str
        Edge name ``"(x, y)"``.
    n_pairs : int
    kept : ndarray of int
        Indices (into the edge's pairs) of the inliers; empty when the edge is dropped.
    rejected : list of (int, str)
        Every other pair with the reason, e.g. ``"translation residual 0.83 m > 0.6 m"``.
    dropped : bool
        The whole edge was dropped.
    reason : str
        Why the edge was dropped, or how it was validated.
    model : str
        ``"1X1Y"`` (stage 1), ``"eq. (70) given Y"`` / ``"eq. (70) given X"`` (stage 2) or
        ``"none"``.
    iterations : int
        Hypotheses scored.
    X, Y : ndarray (4, 4) or None
        The refitted hypothesis (``T_<tag carrier>_tag``, ``T_<camera carrier>_cam``).
    translation_residual : ndarray (N,) or None
        Residuals of every pair at that hypothesis [m] (with ``alpha = 1``).
    rotation_residual_deg : ndarray (N,) or None
        [deg].
    """

    edge: str
    n_pairs: int
    kept: np.ndarray
    rejected: list[tuple[int, str]]
    dropped: bool
    reason: str
    model: str = "none"
    iterations: int = 0
    X: np.ndarray | None = None
    Y: np.ndarray | None = None
    translation_residual: np.ndarray | None = None
    rotation_residual_deg: np.ndarray | None = None

    @property
    def inliers(self) -> np.ndarray:
        """Boolean mask (N,) of the kept pairs."""
        mask = np.zeros(self.n_pairs, dtype=bool)
        mask[self.kept] = True
        return mask


@dataclass
class RansacReport:
    """Outcome of :func:`ransac_filter` for every edge of a problem.

    Attributes
    ----------
    edges : dict of str to EdgeRansacReport
        Keyed by edge name, in the problem's edge order.
    options : RansacOptions
    unknown_scale : bool
    """

    edges: dict[str, EdgeRansacReport]
    options: RansacOptions
    unknown_scale: bool = False

    @property
    def inliers(self) -> dict[str, np.ndarray]:
        """Edge name -> boolean mask (N,) of kept pairs."""
        return {name: rep.inliers for name, rep in self.edges.items()}

    @property
    def rejected(self) -> list[tuple[str, int, str]]:
        """Every rejected pair as ``(edge, index, reason)``."""
        return [(name, i, why) for name, rep in self.edges.items() for i, why in rep.rejected]

    @property
    def dropped(self) -> list[tuple[str, str]]:
        """Every dropped edge as ``(edge, reason)``."""
        return [(name, rep.reason) for name, rep in self.edges.items() if rep.dropped]

    @property
    def n_kept(self) -> int:
        return int(sum(rep.kept.size for rep in self.edges.values()))

    @property
    def n_rejected(self) -> int:
        return int(sum(len(rep.rejected) for rep in self.edges.values()))

    def filtered(self, problem: Problem) -> Problem:
        """The problem restricted to the kept pairs (dropped edges and orphaned frames removed).

        Raises ``ValueError`` when ``problem`` does not match the report or nothing is kept.
        """
        return restrict_problem(problem, self.inliers, what="ransac")

    def summary(self) -> str:
        """One line per edge: kept/total, model, reason."""
        lines = []
        for name, rep in self.edges.items():
            lines.append(
                f"{name}: kept {rep.kept.size}/{rep.n_pairs} ({rep.model}, "
                f"{rep.iterations} hypotheses) - {rep.reason}"
            )
        return "\n".join(lines)



def _pair_reason(t: float, t_thr: float, r: float, opts: RansacOptions) -> str:
    parts = []
    if t > t_thr:
        parts.append(f"translation residual {t:.3g} m > {t_thr:.3g} m")
    if np.rad2deg(r) > opts.rotation_threshold_deg:
        parts.append(
            f"rotation residual {np.rad2deg(r):.3g}° > {opts.rotation_threshold_deg:.3g}°"
        )
    return "; ".join(parts) or "outside the consensus set"


def _accepted_report(
    edge: Edge, best: Consensus, t_thr: np.ndarray, opts: RansacOptions, model: str,
    iterations: int, how: str,
) -> EdgeRansacReport:
    kept = np.flatnonzero(best.inliers)
    rejected = [
        (int(i), _pair_reason(float(best.t_res[i]), float(t_thr[i]), float(best.r_res[i]), opts))
        for i in np.flatnonzero(~best.inliers)
    ]
    return EdgeRansacReport(
        edge=edge.name, n_pairs=edge.n, kept=kept, rejected=rejected, dropped=False,
        reason=f"{how}: consensus {best.count} of {edge.n} pairs", model=model,
        iterations=iterations, X=best.X, Y=best.Y, translation_residual=best.t_res,
        rotation_residual_deg=np.rad2deg(best.r_res),
    )


def _dropped_report(
    edge: Edge, reason: str, model: str = "none", iterations: int = 0,
    best: Consensus | None = None,
) -> EdgeRansacReport:
    return EdgeRansacReport(
        edge=edge.name, n_pairs=edge.n, kept=np.zeros(0, dtype=int),
        rejected=[(i, f"edge dropped: {reason}") for i in range(edge.n)], dropped=True,
        reason=reason, model=model, iterations=iterations,
        X=None if best is None else best.X, Y=None if best is None else best.Y,
        translation_residual=None if best is None else best.t_res,
        rotation_residual_deg=None if best is None else np.rad2deg(best.r_res),
    )


def _min_consensus(n: int, opts: RansacOptions, floor: int) -> int:
    return max(floor, math.ceil(opts.min_inlier_fraction * n - 1e-9))


def ransac_filter(
    problem: Problem, options: RansacOptions | None = None, *, rng: np.random.Generator
) -> RansacReport:
    """Per-edge RANSAC on the model of eq. (70) (paper Section 9.1); see the module docstring.

    Parameters
    ----------
    problem : Problem
    options : RansacOptions, optional
    rng : numpy.random.Generator
        The only source of randomness (sample order / draws).

    Returns
    -------
    RansacReport
        Kept pair indices, every rejected pair with its reason and every dropped edge with why;
        :meth:`RansacReport.filtered` gives the cleaned problem.
    """
    opts = options or RansacOptions()
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng: expected a numpy.random.Generator, got {type(rng).__name__}")
    reports: dict[str, EdgeRansacReport] = {}
    # frame name -> (estimate, support) from accepted edges, for stage 2
    known: dict[str, tuple[np.ndarray, int]] = {}
    pending: dict[str, str] = {}  # edge name -> why stage 1 could not hypothesise
    thresholds = {e.name: translation_thresholds(e, opts, problem.unknown_scale)
                  for e in problem.edges}

    def remember(name: str, T: np.ndarray, support: int) -> None:
        if name not in known or known[name][1] < support:
            known[name] = (T, support)

    for e in problem.edges:
        if e.n == 1:
            reports[e.name] = _dropped_report(
                e, "single pair: cannot be validated (paper Section 9.1)")
            continue
        if e.n == 2:
            pending[e.name] = "2 pairs (the 1X1Y model needs 3)"
            continue
        best, iters = ransac_1x1y(e, opts, rng, thresholds[e.name])
        if best is None:
            pending[e.name] = (f"degenerate: no 3 pairs whose relative A rotations span two axes "
                               f"by >= {opts.min_axis_span_deg:g}°")
            continue
        need = _min_consensus(e.n, opts, MINIMAL_SAMPLE)
        if best.count < need:
            reports[e.name] = _dropped_report(
                e, f"largest consensus set {best.count} of {e.n} pairs < {need} "
                   f"(min_inlier_fraction {opts.min_inlier_fraction:.3g})", "1X1Y", iters, best)
            continue
        reports[e.name] = _accepted_report(e, best, thresholds[e.name], opts, "1X1Y", iters,
                                           "1X1Y RANSAC")
        remember(e.x, best.X, best.count)
        remember(e.y, best.Y, best.count)

    by_name = {e.name: e for e in problem.edges}
    progress = True
    while pending and progress:
        progress = False
        for name in list(pending):
            e = by_name[name]
            if e.y in known:
                side, T = "Y", known[e.y][0]
            elif e.x in known:
                side, T = "X", known[e.x][0]
            else:
                continue
            why = pending.pop(name)
            progress = True
            best = ransac_given(e, opts, side, T, thresholds[name])
            model = f"eq. (70) given {side}"
            need = _min_consensus(e.n, opts, 2)
            if best.count < need:
                reason = (f"{why}; {model}: largest consensus set {best.count} of {e.n} pairs "
                          f"< {need}")
                if e.n == 2:
                    reason += " (the two pairs disagree; neither can be blamed)"
                reports[name] = _dropped_report(e, reason, model, e.n, best)
                continue
            reports[name] = _accepted_report(e, best, thresholds[name], opts, model, e.n,
                                             f"{why}; validated by {model}")
            if side == "Y":
                remember(e.x, best.X, best.count)
            else:
                remember(e.y, best.Y, best.count)
    for name, why in pending.items():
        reports[name] = _dropped_report(
            by_name[name], f"{why}, and no validated edge shares a frame (eq. (70) needs one)")
    ordered = {e.name: reports[e.name] for e in problem.edges}
    return RansacReport(edges=ordered, options=opts, unknown_scale=problem.unknown_scale)


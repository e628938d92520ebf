"""The verdict's check for single pairs that do not fit and move the result.

The edge check (:mod:`.fit`) compares whole edges; a tag moved near the end of a recording, a
wrong detection or a glitch of the pose source can leave one pair far off in an edge whose other
pairs fit. With the noise estimated from the data such a pair only raises its camera's noise a
little, and every check passes (``benchmarks/verdict.md`` section 2: a tag moved 5 cm halfway,
seen once after the move, 33-42 mm off against a noise of ~8 mm per pair).

Per pair (eq. (33)): the translation and rotation terms ``|r_t|^2 / sigma^2`` and
``2 kappa (3 - tr D)``, each ~chi-square with 3 degrees of freedom, over the mean of the same term
over the camera's other pairs (its noise without the pair: robust to the pair itself and to a
stated noise that is off), ~``F(3, 3 (n_k - 1))`` for a camera of ``n_k`` pairs (the fit's own
degrees of freedom neglected: the residuals are a little smaller than the noise, by the share of
the camera's residuals the frames absorb, a few per cent at the benchmark's 17-31 pairs per
camera). A pair is **far** when either ratio's upper tail is below ``verdict.significance`` split
over all ``2 N`` terms (Bonferroni). Such a pair is a caution only when it also **moves the
result**: leaving it out moves the frames by ``(H - H_i)^+ g_i`` (one Gauss-Newton step from the
estimate, ``g_i = J_i^T e_i`` its share of the gradient, ``H_i`` its share of the information), and
the largest change of a frame coordinate is at least ``verdict.pair_shift_std`` of its std (1: a
pair that moves nothing by its std leaves the result within its stated precision, however far it
is: heavy-tailed real data have such pairs). Pairs of edges the edge check already names are left
to it. The caution names the pair (its edge, its index in the edge's recording order), its size and
the frame it moves, and the fix (remove it, or ``--robust``: ``solver.reject_outliers`` leaves such
pairs out). Its code, ``pair``, comes after the causes that concern all the data (a scale, a time
offset, the fit) in the order of the reasons: one pair is rarely the main thing wrong.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from ..analysis.information import frame_of_coordinate, information_matrix
from ..analysis.time_offset import offset_terms
from ..numerics.pinv import pinv_solve
from ..outliers.pairs import pair_residuals
from ..problem import Edge, Problem
from .fit import FitStatistics
from .model import Builder
from .options import VerdictOptions
from .words import deg, mm

__all__ = ["FarPair", "pair_reasons"]

#: At most this many pairs are named.
MAX_NAMED = 3


@dataclass(frozen=True)
class FarPair:
    """A pair that does not fit and moves the result (module docstring)."""

    edge: tuple[str, str]
    index: int
    of: int
    std_units: float
    translation_m: float
    rotation_deg: float
    shift_std: float
    frame: str

    def to_dict(self) -> dict:
        return {"edge": list(self.edge), "index": self.index, "pairs": self.of,
                "std_units": float(self.std_units), "translation_m": float(self.translation_m),
                "rotation_deg": float(self.rotation_deg), "frame_shift_std": float(self.shift_std),
                "frame": self.frame}


def far_pairs(problem: Problem, result, fit: FitStatistics | None,
              opts: VerdictOptions) -> list[FarPair]:
    """The pairs of the module docstring, worst first."""
    alpha = float(result.scale) if problem.unknown_scale else 1.0
    res = pair_residuals(problem, result.X, result.Y, alpha)
    N = problem.n_measurements
    camera = np.repeat(problem.edge_y, [e.n for e in problem.edges])
    ct = np.concatenate([res[e.name].normalised_translation for e in problem.edges])
    cr = np.concatenate([res[e.name].normalised_rotation for e in problem.edges])
    p = np.ones(N)
    ratio = np.zeros(N)
    for k in range(problem.P):
        mine = np.flatnonzero(camera == k)
        n = mine.size
        if n < 3:
            continue
        for c in (ct[mine], cr[mine]):
            others = (c.sum() - c) / (3.0 * (n - 1))  # the camera's noise without the pair
            with np.errstate(divide="ignore", invalid="ignore"):
                f = np.where(others > 0, (c / 3.0) / others, np.inf)
            p[mine] = np.minimum(p[mine], stats.f.sf(f, 3, 3 * (n - 1)))
            ratio[mine] = np.maximum(ratio[mine], f)
    limit = opts.significance / (2 * N)
    named = {e.name for e in fit.flagged_edges()} if fit is not None else set()
    edge_of = np.repeat(np.arange(len(problem.edges)), [e.n for e in problem.edges])
    candidates = [i for i in np.flatnonzero(p < limit)
                  if problem.edges[edge_of[i]].name not in named]
    if not candidates:
        return []
    H = information_matrix(problem, result.X, result.Y, alpha).H
    # each pair's share of the gradient, J_i^T e_i, on its tangent coordinates (the offsets'
    # terms compute it per pair; with zero rates their offset parts are zero and unused)
    terms = offset_terms(problem, result.X, result.Y, alpha, np.zeros((N, 6)))
    s0 = max(1.0, float(2.0 * terms.cost / max(1, 6 * N - H.shape[0])))
    std = np.sqrt(np.clip(np.diag(pinv_solve(H, np.eye(H.shape[0]))) * s0, 0.0, None))
    starts = np.r_[0, np.cumsum([e.n for e in problem.edges])]
    out = []
    for i in candidates:
        g = np.zeros(H.shape[0])
        np.add.at(g, terms.pair_tangent[i], terms.pair_score_t[i])
        shift = np.abs(pinv_solve(_without_pair(problem, result, alpha, H, edge_of[i],
                                                 int(i - starts[edge_of[i]])), g))
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(std > 0, shift / std, 0.0)
        worst = int(np.argmax(z))
        if z[worst] < opts.pair_shift_std:
            continue
        e = problem.edges[edge_of[i]]
        j = int(i - starts[edge_of[i]])
        r = res[e.name]
        out.append(FarPair((e.x, e.y), j, e.n, float(np.sqrt(ratio[i])),
                           float(r.translation[j]) / alpha, float(np.degrees(r.rotation[j])),
                           float(z[worst]), frame_of_coordinate(problem, worst)))
    return sorted(out, key=lambda p: -p.shift_std)


def _without_pair(problem: Problem, result, alpha: float, H: np.ndarray, edge: int,
                  index: int) -> np.ndarray:
    """The information of ``problem`` without pair ``index`` of edge ``edge``, at the same
    estimate (the deletion's exact Gauss-Newton step uses it: a pair of a short edge pulls its
    frames more than ``H^+ g`` says); ``H`` itself when the pair is its edge's only one."""
    e = problem.edges[edge]
    if e.n < 2:
        return H
    keep = np.arange(e.n) != index
    edges = list(problem.edges)
    edges[edge] = Edge._of(e.x, e.y, e.A[keep], e.B[keep], e.sigma[keep], e.kappa[keep])
    return information_matrix(problem.with_edges(edges), result.X, result.Y, alpha).H


def pair_reasons(b: Builder, problem: Problem, result, fit: FitStatistics | None,
                 opts: VerdictOptions) -> list[FarPair]:
    """Find the far pairs (``[]`` when the check is off or fails) and add a caution for them."""
    if not opts.pair_check:
        return []
    try:
        found = far_pairs(problem, result, fit, opts)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError):
        return []
    if not found:
        return []
    words = "; ".join(
        f"pair {p.index + 1} of {p.of} of edge ({p.edge[0]}, {p.edge[1]}) is "
        f"{mm(p.translation_m)} / {deg(p.rotation_deg)} off ({p.std_units:.1f}x its camera's "
        f"typical pair) and moves {p.frame} by {p.shift_std:.1f} of its std"
        for p in found[:MAX_NAMED])
    more = f" (+{len(found) - MAX_NAMED} more)" if len(found) > MAX_NAMED else ""
    frames = list(dict.fromkeys(f for p in found[:MAX_NAMED] for f in (p.edge[0], p.frame)
                                if f != "the scale"))
    b.add("caution", "pair",
          f"{'a pair does' if len(found) == 1 else 'pairs do'} not fit: {words}{more}: a target "
          "that moved, a wrong detection or a glitch of the poses; it is kept in the solve. "
          "Leave it out, or calibrate with --robust (solver.reject_outliers), which rejects "
          "such pairs", frames, [p.edge for p in found[:MAX_NAMED]],
          why="a pair does not fit")
    return found

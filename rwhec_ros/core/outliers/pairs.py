"""Pairs of a problem: residuals at an estimate and the problem restricted to chosen pairs.

Residuals of one pair
---------------------
For a pair ``(A_i, B_i)`` of edge ``(j, k)`` and estimates ``X_j, Y_k`` (and ``alpha``) the residual
of ``A_i X_j = Y_k B_i`` (eq. (7)) has a translation part and a rotation part::

    r_t = alpha (R_A t_X + t_A - t_Y) - R_Y t_B        (metres; alpha = 1 for known scale)
    r_R = R_A R_X - R_Y R_B,   angle = |log((R_A R_X)^T R_Y R_B)|

``|r_t|`` equals the translation distance between ``X_j`` and ``A_i^-1 Y_k B_i`` of eq. (70) and the
angle the rotation distance between them, so scoring "A X = Y B" and scoring eq. (70) is the same.
The normalised residual is the summand of eq. (33), ``J_i = |r_t|^2 / sigma_i^2 +
kappa_i |r_R|_F^2`` (:func:`pair_residuals`; ``direct_cost = 1/2 sum J_i``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..problem import Edge, Problem

__all__ = ["PairResiduals", "pair_residuals", "edge_residuals", "residuals_by_name",
           "restrict_problem"]


@dataclass
class PairResiduals:
    """Residuals of every pair of one edge at given ``X_j, Y_k, alpha``.

    Attributes
    ----------
    translation : ndarray (N,)
        ``|alpha (R_A t_X + t_A - t_Y) - R_Y t_B|`` [m].
    rotation : ndarray (N,)
        Geodesic angle between ``R_A R_X`` and ``R_Y R_B`` [rad].
    normalised : ndarray (N,)
        ``J_i`` of eq. (33): ``|r_t|^2 / sigma_i^2 + kappa_i |R_A R_X - R_Y R_B|_F^2``.
    normalised_translation, normalised_rotation : ndarray (N,)
        Its two terms, ``|r_t|^2 / sigma_i^2`` and ``kappa_i |R_A R_X - R_Y R_B|_F^2`` (each
        ~ chi-square with 3 degrees of freedom under the paper's noise model).
    """

    translation: np.ndarray
    rotation: np.ndarray
    normalised: np.ndarray
    normalised_translation: np.ndarray
    normalised_rotation: np.ndarray


def pair_residuals(
    problem: Problem, X: np.ndarray, Y: np.ndarray, alpha: float = 1.0
) -> dict[str, PairResiduals]:
    """Residuals of every pair at ``X`` (M, 4, 4), ``Y`` (P, 4, 4) (problem order) and ``alpha``.

    Returns edge name -> :class:`PairResiduals`; ``0.5 * sum(normalised)`` over all edges equals
    :func:`rwhec_ros.core.model.cost.direct_cost` (eq. (33)).
    """
    X = np.asarray(X, float)
    Y = np.asarray(Y, float)
    if X.shape != (problem.M, 4, 4) or Y.shape != (problem.P, 4, 4):
        raise ValueError(
            f"X, Y: expected shapes ({problem.M}, 4, 4) and ({problem.P}, 4, 4), got {X.shape} "
            f"and {Y.shape}"
        )
    out = {}
    for e, j, k in zip(problem.edges, problem.edge_x, problem.edge_y, strict=True):
        out[e.name] = edge_residuals(e, X[j], Y[k], alpha)
    return out


def edge_residuals(e: Edge, X: np.ndarray, Y: np.ndarray, alpha: float) -> PairResiduals:
    RA, tA = e.A[:, :3, :3], e.A[:, :3, 3]
    RB, tB = e.B[:, :3, :3], e.B[:, :3, 3]
    RX, tX = X[:3, :3], X[:3, 3]
    RY, tY = Y[:3, :3], Y[:3, 3]
    rt = alpha * (RA @ tX + tA - tY) - tB @ RY.T
    RARX = RA @ RX
    RYRB = RY @ RB
    rR = RARX - RYRB
    fro2 = (rR**2).sum(axis=(1, 2))
    # |R1 - R2|_F^2 = 4 (1 - cos theta): the half-angle form is accurate near theta = 0.
    rot = 2.0 * np.arcsin(np.clip(0.5 * np.sqrt(fro2 / 2.0), 0.0, 1.0))
    t2 = (rt**2).sum(axis=1)
    nt, nr = t2 / e.sigma**2, e.kappa * fro2
    return PairResiduals(translation=np.sqrt(t2), rotation=rot, normalised=nt + nr,
                         normalised_translation=nt, normalised_rotation=nr)



def residuals_by_name(
    problem: Problem, frames: dict[str, np.ndarray], alpha: float
) -> dict[str, PairResiduals | None]:
    out: dict[str, PairResiduals | None] = {}
    for e in problem.edges:
        if e.x in frames and e.y in frames:
            out[e.name] = edge_residuals(e, frames[e.x], frames[e.y], alpha)
        else:
            out[e.name] = None
    return out



def restrict_problem(
    problem: Problem,
    masks: dict[str, np.ndarray],
    *,
    what: str,
    weights: dict[str, np.ndarray] | None = None,
) -> Problem:
    """Problem on the pairs selected by ``masks`` (optionally re-weighted by ``weights``)."""
    edges = []
    for e in problem.edges:
        if e.name not in masks:
            raise ValueError(f"{what}: no mask for edge {e.name}")
        m = np.asarray(masks[e.name], dtype=bool)
        if m.shape != (e.n,):
            raise ValueError(f"{what}: mask of edge {e.name} has shape {m.shape}, expected "
                             f"({e.n},)")
        if not m.any():
            continue
        sigma, kappa = e.sigma[m], e.kappa[m]
        if weights is not None:
            w = weights[e.name][m]
            sigma, kappa = sigma / np.sqrt(w), kappa * w
        edges.append(Edge.build(e.x, e.y, e.A[m], e.B[m], sigma=sigma, kappa=kappa))
    if not edges:
        raise ValueError(f"{what}: every pair of every edge was rejected")
    return problem.with_edges(edges)


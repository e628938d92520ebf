"""Wang et al. (2022): the generalized closed form (any connected graph, known scale; ours also
solves the translation stage for ``alpha`` with unknown scale)."""

from __future__ import annotations

import numpy as np

from ..lie import make_transform, project_to_so3, unvec
from ..problem import Problem
from .opencv import BaselineOutput

__all__ = ["wang2022", "wang2022_rotations", "translations_given_rotations"]


def wang2022_rotations(problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    """Rotation stage of Wang et al. (2022): null vector of the stacked Kronecker system.

    For every pair ``i`` of edge ``(j, k)`` the rotation constraint (8a)
    ``R_A R_Xj - R_Yk R_B = 0`` is, with column-major ``vec`` (eq. (26)),

    .. math:: (I \\otimes R_A)\\,\\mathrm{vec} R_{X_j} - (R_B^\\top \\otimes I)\\,\\mathrm{vec}
              R_{Y_k} = 0 .

    All 9-row blocks are stacked (unweighted) into a ``(9 N, 9 (M + P))`` matrix whose right
    singular vector of smallest singular value is ``c [vec R_X1 .. vec R_YP]`` for an unknown
    common ``c``. The sign of ``c`` is fixed so that the sum of the cube-rooted block
    determinants is positive (its magnitude does not matter for the projection), and every
    block is projected onto SO(3).

    Returns
    -------
    RX : ndarray, shape (M, 3, 3)
    RY : ndarray, shape (P, 3, 3)
    """
    M, n = problem.M, problem.n_frames
    rows = []
    I3 = np.eye(3)
    for e, j, k in zip(problem.edges, problem.edge_x, problem.edge_y, strict=True):
        N = e.n
        blk = np.zeros((N, 9, 9 * n))
        RA = e.A[:, :3, :3]
        RB = e.B[:, :3, :3]
        cx = 9 * int(j)
        cy = 9 * (M + int(k))
        blk[:, :, cx : cx + 9] = np.einsum("ab,nij->naibj", I3, RA).reshape(N, 9, 9)
        blk[:, :, cy : cy + 9] = -np.einsum("nba,ij->naibj", RB, I3).reshape(N, 9, 9)
        rows.append(blk.reshape(9 * N, 9 * n))
    K = np.concatenate(rows)
    _, _, Vt = np.linalg.svd(K, full_matrices=False)
    v = Vt[-1]
    blocks = unvec(v.reshape(n, 9))
    if np.sum(np.cbrt(np.linalg.det(blocks))) < 0:
        blocks = -blocks
    R = project_to_so3(blocks)
    return R[:M], R[M:]


def translations_given_rotations(
    problem: Problem, RX: np.ndarray, RY: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float]:
    """Linear least-squares translations (and ``alpha``) with the rotations held fixed.

    Stacks eq. (8b), ``R_A t_Xj - t_Yk = R_Yk t_B - t_A`` for every pair (unweighted). For
    ``problem.unknown_scale`` the unknowns are the scaled ``alpha t_X, alpha t_Y`` and ``alpha``
    (eq. (22): ``R_A (alpha t_X) + alpha t_A - alpha t_Y = R_Y t_B``); the metric translations
    are returned. Minimum-norm solution when the translations are not identifiable.

    Returns
    -------
    tX : ndarray, shape (M, 3)
    tY : ndarray, shape (P, 3)
    alpha : float
    """
    M, n = problem.M, problem.n_frames
    scale = problem.unknown_scale
    ncol = 3 * n + (1 if scale else 0)
    blocks, rhs = [], []
    for e, j, k in zip(problem.edges, problem.edge_x, problem.edge_y, strict=True):
        N = e.n
        blk = np.zeros((N, 3, ncol))
        cx = 3 * int(j)
        cy = 3 * (M + int(k))
        blk[:, :, cx : cx + 3] = e.A[:, :3, :3]
        blk[:, :, cy : cy + 3] = -np.eye(3)
        b = e.B[:, :3, 3] @ RY[k].T
        if scale:
            blk[:, :, -1] = e.A[:, :3, 3]
        else:
            b = b - e.A[:, :3, 3]
        blocks.append(blk.reshape(3 * N, ncol))
        rhs.append(b.reshape(3 * N))
    sol = np.linalg.lstsq(np.concatenate(blocks), np.concatenate(rhs), rcond=None)[0]
    alpha = float(sol[-1]) if scale else 1.0
    t = sol[: 3 * n].reshape(n, 3)
    if scale and abs(alpha) > 1e-12:
        t = t / alpha
    return t[:M], t[M:], alpha


def wang2022(problem: Problem) -> BaselineOutput:
    """Closed-form generalized RWHEC of Wang et al. (2022) for any connected graph.

    Rotations from :func:`wang2022_rotations`, then translations (and ``alpha`` for unknown
    scale, our linear extension) from :func:`translations_given_rotations`. The paper's
    "Shah" and "Wang" rows coincide on 1X1Y problems (Table 2).

    Returns
    -------
    X : ndarray, shape (M, 4, 4)
    Y : ndarray, shape (P, 4, 4)
    alpha : float
    """
    if not isinstance(problem, Problem):
        raise ValueError(f"wang: problem must be a Problem, got {type(problem).__name__}")
    if len(problem.components()) != 1:
        raise ValueError(
            f"wang: the problem graph must be connected, got components {problem.components()}"
        )
    RX, RY = wang2022_rotations(problem)
    tX, tY, alpha = translations_given_rotations(problem, RX, RY)
    return make_transform(RX, tX), make_transform(RY, tY), alpha


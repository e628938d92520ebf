"""Closed-form hypotheses of RANSAC: the 1X1Y fit of a sample and the one-pair eq. (70).

All functions are vectorised over hypotheses (leading axis ``H``) or pairs (``N``).
"""

from __future__ import annotations

import numpy as np

from ..lie import make_transform, project_to_so3, so3_log, unvec
from ..problem import Edge

__all__ = ["score_hypotheses", "fit_1x1y", "x_from_y", "y_from_x", "refit_given", "axis_span"]


def score_hypotheses(
    A: np.ndarray, B: np.ndarray, X: np.ndarray, Y: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Residuals of ``A_i X = Y B_i`` (alpha = 1) of N pairs under H hypotheses.

    ``A, B`` (N, 4, 4), ``X, Y`` (H, 4, 4). Returns translation [m] and rotation [rad] residuals,
    each (H, N). The angle comes from the trace (accurate to ~1e-8 rad, ample for thresholds).
    """
    RA, tA = A[:, :3, :3], A[:, :3, 3]
    RB, tB = B[:, :3, :3], B[:, :3, 3]
    RX, tX = X[:, :3, :3], X[:, :3, 3]
    RY, tY = Y[:, :3, :3], Y[:, :3, 3]
    RARX = np.einsum("nij,hjk->hnik", RA, RX)
    RYRB = np.einsum("hij,njk->hnik", RY, RB)
    cos = 0.5 * (np.einsum("hnij,hnij->hn", RARX, RYRB) - 1.0)
    rot = np.arccos(np.clip(cos, -1.0, 1.0))
    rt = (
        np.einsum("nij,hj->hni", RA, tX)
        + tA[None]
        - tY[:, None]
        - np.einsum("hij,nj->hni", RY, tB)
    )
    return np.linalg.norm(rt, axis=-1), rot


def fit_1x1y(
    A: np.ndarray, B: np.ndarray, kappa: np.ndarray | None = None, sigma: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form ``(X, Y)`` of the 1X1Y problem for H samples of k pairs each.

    ``A, B`` (H, k, 4, 4); optional weights ``kappa, sigma`` (H, k). Rotations: null vector of
    the stacked ``[(I (x) R_A), -(R_B^T (x) I)] [vec R_X; vec R_Y] = 0`` (rows scaled by
    ``sqrt(kappa)``), scaled to a mean unit cube-root determinant and projected onto SO(3);
    translations: least squares of ``R_A t_X - t_Y = R_Y t_B - t_A`` (rows scaled by
    ``1/sigma``). Returns ``X, Y`` (H, 4, 4).
    """
    H, k = A.shape[:2]
    RA, tA = A[..., :3, :3], A[..., :3, 3]
    RB, tB = B[..., :3, :3], B[..., :3, 3]
    I3 = np.eye(3)
    C = np.empty((H, k, 9, 18))
    C[..., :9] = np.einsum("ab,hnij->hnaibj", I3, RA).reshape(H, k, 9, 9)
    C[..., 9:] = -np.einsum("hnba,ij->hnaibj", RB, I3).reshape(H, k, 9, 9)
    if kappa is not None:
        C *= np.sqrt(kappa)[..., None, None]
    _, _, Vt = np.linalg.svd(C.reshape(H, 9 * k, 18), full_matrices=False)
    blocks = unvec(Vt[:, -1, :].reshape(H, 2, 9))
    eta = np.mean(np.cbrt(np.linalg.det(blocks)), axis=1)
    eta = np.where(np.abs(eta) < 1e-300, 1.0, eta)
    R = project_to_so3(blocks / eta[:, None, None, None])
    RX, RY = R[:, 0], R[:, 1]
    L = np.empty((H, k, 3, 6))
    L[..., :3] = RA
    L[..., 3:] = -I3
    rhs = np.einsum("hij,hnj->hni", RY, tB) - tA
    if sigma is not None:
        L = L / sigma[..., None, None]
        rhs = rhs / sigma[..., None]
    t = np.einsum(
        "hij,hj->hi", np.linalg.pinv(L.reshape(H, 3 * k, 6)), rhs.reshape(H, 3 * k)
    )
    return make_transform(RX, t[:, :3]), make_transform(RY, t[:, 3:])


def x_from_y(A: np.ndarray, B: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """Eq. (70): ``X = A_i^-1 Y B_i`` for every pair, (N, 4, 4)."""
    RA, tA = A[:, :3, :3], A[:, :3, 3]
    RAt = np.swapaxes(RA, 1, 2)
    Tyb = Y[None] @ B
    R = RAt @ Tyb[:, :3, :3]
    t = np.einsum("nij,nj->ni", RAt, Tyb[:, :3, 3] - tA)
    return make_transform(R, t)


def y_from_x(A: np.ndarray, B: np.ndarray, X: np.ndarray) -> np.ndarray:
    """``Y = A_i X B_i^-1`` for every pair, (N, 4, 4)."""
    RB, tB = B[:, :3, :3], B[:, :3, 3]
    Tax = A @ X[None]
    R = Tax[:, :3, :3] @ np.swapaxes(RB, 1, 2)
    t = Tax[:, :3, 3] - np.einsum("nij,nj->ni", R, tB)
    return make_transform(R, t)


def refit_given(edge: Edge, idx: np.ndarray, known: str, T_known: np.ndarray) -> np.ndarray:
    """Weighted chordal mean of the one-pair hypotheses of ``idx`` (the unknown frame)."""
    A, B = edge.A[idx], edge.B[idx]
    hyp = x_from_y(A, B, T_known) if known == "Y" else y_from_x(A, B, T_known)
    kap, wt = edge.kappa[idx], 1.0 / edge.sigma[idx] ** 2
    R = project_to_so3(np.einsum("n,nij->ij", kap, hyp[:, :3, :3]))
    # Translation: minimise sum_i wt_i |R_A t_X - (..)|^2 == weighted mean of the per-pair t_X
    # (R_A is orthonormal) for X; for Y the residual is t_Y - (R_A t_X + t_A - R_Y t_B).
    if known == "Y":
        t = np.einsum("n,ni->i", wt, hyp[:, :3, 3]) / wt.sum()
    else:
        tY = A[:, :3, 3] + np.einsum("nij,j->ni", A[:, :3, :3], T_known[:3, 3])
        tY = tY - np.einsum("ij,nj->ni", R, B[:, :3, 3])
        t = np.einsum("n,ni->i", wt, tY) / wt.sum()
    return make_transform(R, t)


def axis_span(RA: np.ndarray) -> np.ndarray:
    """Second singular value [rad] of the rotation vectors of ``R_A1^T R_A2``, ``R_A1^T R_A3``.

    ``RA`` (H, 3, 3, 3) -> (H,): zero when the relative rotations share an axis (or vanish).
    """
    rel = np.swapaxes(RA[:, :1], -1, -2) @ RA[:, 1:]
    phi = so3_log(rel)  # (H, 2, 3)
    return np.linalg.svd(phi, compute_uv=False)[:, 1]



"""Gauss-Newton on the block structure of the corner model: the pose-group errors eliminated.

The unknowns of :mod:`.model` are the global tangent vector ``theta`` (6 per frame, [+1 scale]:
``p`` columns) and six per pose group (``E_g``). Each corner touches the 12 (13) columns of its
view and the six of its group, so the normal matrix is ::

    N = [[H, B], [B^T, D]],     D = blockdiag(D_g) (6x6 each, with the prior on E_g)

and the groups are eliminated exactly (Schur complement, one 6x6 inverse per group)::

    S = H - sum_g B_g D_g^-1 B_g^T,    S dtheta = -(g_theta - sum_g B_g D_g^-1 g_g)

``S`` is dense ``p x p`` (p = 6 (M + P) [+1]: 145 for the paper's 16 x 8, ~700 for 100 cameras
among 15 targets) and every ``B_g`` touches only the frames seen at that pose sample, so one
iteration costs a pass over the corners plus ``sum_g |frames of g|^2`` and one ``p^3``
factorisation. Everything is whitened by the current noise (:mod:`.model`) and weighted by the
robust (Huber) weights of the corners.

:func:`traces` gives ``tr(N^-1 H_c)`` for each variance component ``c`` (each camera's corners,
the pose errors' translations and rotations): the part of the data that component spends on the
unknowns, whose complement is its redundancy in the variance-component estimate
(:mod:`.solver`). With ``K_g = S^-1 B_g D_g^-1`` and ``F_g = D_g^-1 B_g^T S^-1 B_g D_g^-1``::

    tr(N^-1 H_c) = sum_views [ <S^-1, H_vv> - 2 <K_g, H_va> + <D_g^-1 + F_g, H_aa> ]

summed over the views (and groups) of component ``c``; the traces of all components add up to
``p + 6 G`` (a test checks it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse

from .model import Linearization
from .views import CornerViews

__all__ = ["Groups", "Normal", "huber", "normal_equations", "inverse", "solve_step", "traces"]

#: Corners per block of the per-view Gram sums (bounds the (chunk, L+6, L+6) temporary).
_CHUNK = 4096
#: Entries of the padded (groups, support, support) temporaries per block of groups.
_GROUP_BLOCK = 1 << 22


def huber(s: np.ndarray, c: float) -> tuple[np.ndarray, np.ndarray]:
    """Cost ``rho(s)`` (``s^2`` up to ``c``, ``2 c s - c^2`` beyond) and IRLS weight
    ``min(1, c / s)`` of whitened corner distances ``s``."""
    s = np.asarray(s, float)
    big = s > c
    rho = np.where(big, 2.0 * c * s - c * c, s * s)
    w = np.where(big, c / np.maximum(s, 1e-300), 1.0)
    return rho, w


@dataclass(frozen=True)
class Groups:
    """Which global columns each pose group touches (fixed for a problem; built once).

    Attributes
    ----------
    support : ndarray of int, shape (G, s)
        Each group's global columns, padded with ``p`` (a dummy column dropped at the end).
    position : ndarray of int, shape (V, L)
        Row of each view's global column in its group's ``support``.
    p : int
        Global columns.
    """

    support: np.ndarray
    position: np.ndarray
    p: int
    view_rows: np.ndarray
    view_cols: np.ndarray
    block_rows: tuple
    block_cols: tuple

    @staticmethod
    def build(views: CornerViews, index: np.ndarray, p: int) -> Groups:
        G = views.n_groups
        sups = [np.unique(index[views.view_group == g]) for g in range(G)]
        width = max((s.size for s in sups), default=0)
        support = np.full((G, width), p, dtype=np.intp)
        for g, s in enumerate(sups):
            support[g, :s.size] = s
        position = np.empty_like(index)
        for v in range(index.shape[0]):
            g = views.view_group[v]
            position[v] = np.searchsorted(sups[g], index[v])
        L = index.shape[1]
        blocks = _blocks(G, width)
        return Groups(support, position, p,
                      view_rows=np.repeat(index, L, axis=1).ravel(),
                      view_cols=np.tile(index, (1, L)).ravel(),
                      block_rows=tuple(np.repeat(support[b], width, axis=1).ravel()
                                       for b in blocks),
                      block_cols=tuple(np.tile(support[b], (1, width)).ravel() for b in blocks))

    def blocks(self):
        """Slices of groups whose padded (s x s) temporaries stay small."""
        return _blocks(*self.support.shape)


def _blocks(G: int, width: int) -> list[slice]:
    step = max(1, _GROUP_BLOCK // max(width * width, 1))
    return [slice(a, min(a + step, G)) for a in range(0, G, step)]


@dataclass
class Normal:
    """The reduced normal equations at one point (module docstring).

    Attributes
    ----------
    S : ndarray, shape (p, p)
    H : ndarray, shape (p, p)
        The global block before the groups are eliminated (``sum J^T W J`` of the global
        columns): the normal matrix of the fit with the pose errors held at zero.
    b : ndarray, shape (p,)
        Reduced gradient ``g_theta - sum_g B_g D_g^-1 g_g``.
    grams : ndarray, shape (V, L + 6, L + 6)
        Per view ``sum w J^T J`` over its corners (global columns first, then the group's six).
    B : ndarray, shape (G, s, 6)
        ``B_g`` on each group's padded support.
    Dinv : ndarray, shape (G, 6, 6)
    ga : ndarray, shape (G, 6)
        The groups' gradients ``g_g``.
    """

    S: np.ndarray
    H: np.ndarray
    b: np.ndarray
    grams: np.ndarray
    B: np.ndarray
    Dinv: np.ndarray
    ga: np.ndarray


def _sum_by(index: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """``out[i] = sum of values[k] with index[k] == i`` for ``values`` (K, ...) -> (n, ...)
    (``np.add.at`` through one ``bincount``, much faster)."""
    shape = values.shape[1:]
    m = int(np.prod(shape)) if shape else 1
    flat = (np.asarray(index)[:, None] * m + np.arange(m)).ravel()
    return np.bincount(flat, weights=values.reshape(-1), minlength=n * m).reshape((n,) + shape)


def _view_sums(J: np.ndarray, r: np.ndarray, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per view ``sum J^T J`` (V, C, C) and ``sum J^T r`` (V, C) over its corners' rows."""
    n_views = start.size - 1
    C = J.shape[2]
    grams = np.zeros((n_views, C, C))
    grads = np.zeros((n_views, C))
    v0 = 0
    while v0 < n_views:
        v1 = int(np.searchsorted(start, start[v0] + _CHUNK, side="right")) - 1
        v1 = min(max(v1, v0 + 1), n_views)
        a, b = start[v0], start[v1]
        Jc, rc = J[a:b], r[a:b]
        starts = start[v0:v1] - a
        grams[v0:v1] = np.add.reduceat(np.einsum("nki,nkj->nij", Jc, Jc), starts, axis=0)
        grads[v0:v1] = np.add.reduceat(np.einsum("nki,nk->ni", Jc, rc), starts, axis=0)
        v0 = v1
    return grams, grads


def normal_equations(views: CornerViews, lin: Linearization, groups: Groups,
                     weights: np.ndarray, prior_w: np.ndarray, group_vectors: np.ndarray
                     ) -> Normal:
    """The reduced normal equations (module docstring) for the corner ``weights`` (N,), the
    prior weights ``1 / sigma^2`` of the six group coordinates and the groups' current error
    vectors (G, 6)."""
    p = groups.p
    sw = np.sqrt(weights)[:, None, None]
    J = np.concatenate([lin.J_global, lin.J_group], axis=2) * sw
    r = lin.residual * sw[:, :, 0]
    grams, grads = _view_sums(J, r, views.start)
    L = lin.index.shape[1]
    idx = lin.index
    H0 = scipy.sparse.coo_matrix((grams[:, :L, :L].ravel(),
                                  (groups.view_rows, groups.view_cols)), shape=(p, p)).toarray()
    H0 = 0.5 * (H0 + H0.T)
    vals, rr, cc = [], [], []
    g = np.bincount(idx.ravel(), weights=grads[:, :L].ravel(), minlength=p + 1)
    n_groups, width = groups.support.shape
    D = _sum_by(views.view_group, grams[:, L:, L:], n_groups) + np.diag(prior_w)
    Dinv = np.linalg.inv(D)
    Dinv = 0.5 * (Dinv + np.transpose(Dinv, (0, 2, 1)))
    ga = _sum_by(views.view_group, grads[:, L:], n_groups) + prior_w * group_vectors
    slot = (views.view_group[:, None] * width + groups.position).ravel()
    B = _sum_by(slot, grams[:, :L, L:].reshape(-1, 6), n_groups * width).reshape(
        n_groups, width, 6)
    K = B @ Dinv  # (G, s, 6)
    g -= np.bincount(groups.support.ravel(), weights=np.einsum("gsi,gi->gs", K, ga).ravel(),
                     minlength=p + 1)
    for i, blk in enumerate(groups.blocks()):
        vals.append(-(K[blk] @ np.transpose(B[blk], (0, 2, 1))).ravel())
        rr.append(groups.block_rows[i])
        cc.append(groups.block_cols[i])
    schur = scipy.sparse.coo_matrix((np.concatenate(vals), (np.concatenate(rr),
                                                            np.concatenate(cc))),
                                    shape=(p + 1, p + 1)).toarray()[:p, :p]
    S = H0 + 0.5 * (schur + schur.T)
    return Normal(S=S, H=H0, b=g[:p], grams=grams, B=B, Dinv=Dinv, ga=ga)


def _cholesky(S: np.ndarray):
    """Cholesky factor of the Jacobi-scaled ``S`` and the scale, or None when ``S`` is not
    positive definite to working precision (a direction the corners do not determine)."""
    d = np.diag(S)
    if not np.all(np.isfinite(S)) or np.any(d <= 0):
        return None
    s = 1.0 / np.sqrt(d)
    Sn = S * s[:, None] * s[None, :]
    try:
        c = scipy.linalg.cho_factor(Sn, lower=True, check_finite=False)
    except np.linalg.LinAlgError:
        return None
    piv = np.abs(np.diag(c[0]))
    if piv.min() < 1e-7 * piv.max():  # condition of the scaled matrix beyond ~1e14
        return None
    return c, s


def inverse(S: np.ndarray) -> np.ndarray | None:
    """``S^-1`` through the Jacobi-scaled Cholesky factor (None: singular)."""
    fac = _cholesky(S)
    if fac is None:
        return None
    c, s = fac
    out = s[:, None] * scipy.linalg.cho_solve(c, np.diag(s), check_finite=False)
    return 0.5 * (out + out.T)


def solve_step(normal: Normal, groups: Groups):
    """The Gauss-Newton step ``(dtheta (p,), d_groups (G, 6))``, or None when ``S`` is
    singular."""
    fac = _cholesky(normal.S)
    if fac is None:
        return None
    c, s = fac
    dtheta = -s * scipy.linalg.cho_solve(c, s * normal.b, check_finite=False)
    dt = np.append(dtheta, 0.0)[groups.support]  # (G, s), the dummy column 0
    dg = -np.einsum("gij,gj->gi", normal.Dinv,
                    normal.ga + np.einsum("gsi,gs->gi", normal.B, dt))
    return dtheta, dg


def traces(views: CornerViews, lin: Linearization, groups: Groups, normal: Normal,
           Sinv: np.ndarray, prior_w: np.ndarray) -> tuple[np.ndarray, float, float]:
    """``tr(N^-1 H_c)`` per camera (P,), for the groups' translations and for their rotations
    (module docstring)."""
    L = lin.index.shape[1]
    idx = lin.index
    G = normal.grams
    per_view = np.einsum("vij,vij->v", Sinv[idx[:, :, None], idx[:, None, :]], G[:, :L, :L])
    Sp = np.zeros((groups.p + 1, groups.p + 1))
    Sp[:groups.p, :groups.p] = Sinv
    n_groups = groups.support.shape[0]
    KB = np.zeros((n_groups, groups.support.shape[1], 6))
    for blk in groups.blocks():
        sup = groups.support[blk]
        KB[blk] = Sp[sup[:, :, None], sup[:, None, :]] @ normal.B[blk] @ normal.Dinv[blk]
    F = normal.Dinv @ np.transpose(normal.B, (0, 2, 1)) @ KB  # (G, 6, 6)
    g = views.view_group
    per_view -= 2.0 * np.einsum("vij,vij->v", KB[g[:, None], groups.position], G[:, :L, L:])
    per_view += np.einsum("vij,vij->v", (normal.Dinv + F)[g], G[:, L:, L:])
    dd = np.einsum("gii->gi", normal.Dinv + F) * prior_w
    per_camera = np.bincount(views.view_y, weights=per_view, minlength=len(views.y_names))
    return per_camera, float(dd[:, :3].sum()), float(dd[:, 3:].sum())

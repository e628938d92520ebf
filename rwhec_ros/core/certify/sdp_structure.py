"""The block structure of Problem 7 on the reduced variable: every constraint on one frame's block.

On ``z = [vec R_1; ...; vec R_n; s]`` (``d = 9 n + 1``, the reduced form of eq. (48)) every
constraint of eq. (50) is a quadratic form on ONE frame's block ``z[I_f]`` with ``I_f = (9 f,
..., 9 f + 8, d - 1)`` (``vec R_f`` and ``s``), and all frames share the same 21 local matrices
(:func:`rwhec_ros.core.relaxation.so3_constraint_matrices` builds them once and shifts them);
``s^2 = 1`` is the ``(s, s)`` entry alone. An interior-point method on the standard pair::

    primal:  min <Q', X>  s.t.  <A_i, X> = b_i,  X >= 0        (the moment relaxation)
    dual:    max b^T y    s.t.  S = Q' - sum_i y_i A_i >= 0   (Problem 7, y = lambda, S = Z)

with ``b = e_{s^2 = 1}`` then needs three operations, all of which reduce to ``10 x 10`` blocks:

* ``A(X)``: the local traces ``<A_k, X[I_f, I_f]>`` (:meth:`FrameBlocks.apply`);
* ``A^T(y) = sum_i y_i A_i``: per-frame ``10 x 10`` blocks added into ``d x d``
  (:meth:`FrameBlocks.adjoint`, the ``K(lambda)`` of :mod:`rwhec_ros.core.certificate`);
* the Schur complement of the Newton system, ``M_ij = <A_i, W A_j W>`` (the Nesterov-Todd
  direction), whose ``(f, g)`` block of ``20 x 20`` entries needs only ``W[I_f, I_g]``
  (:meth:`FrameBlocks.schur`): ``O(n^2)`` small products instead of ``O(m^2 d^2)``.

One of the 21 local constraints is linearly dependent on the others (the traces of (50a) and of
(50b) are both ``|R|^2 - 3 s^2``); the interior-point method needs independent constraints, so
the last diagonal one of (50b) is left out (its multiplier is 0).
:meth:`FrameBlocks.full_multipliers` puts the multipliers back in the order of
:class:`~rwhec_ros.core.relaxation.ConstraintSet`, so the certificate evaluates exactly the same
``Z(lambda) = Q' - K(lambda)`` as for any other solver.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from .relaxation import _PATTERN

__all__ = ["BLOCK", "LOCAL_CONSTRAINTS", "DROPPED", "local_constraint_matrices", "FrameBlocks",
           "frame_blocks"]

#: Size of a frame's block: ``vec R`` (9) and ``s``.
BLOCK = 10
#: Constraints of one rotation in :func:`~rwhec_ros.core.relaxation.so3_constraint_matrices`.
LOCAL_CONSTRAINTS = 21
#: The dependent one left out: (50b), the diagonal entry ``(R^T R)_{22} = s^2`` (local index 11:
#: six of (50a) first, then (50b) in the order (0,0), (0,1), (0,2), (1,1), (1,2), (2,2)).
DROPPED = 11


@functools.lru_cache(maxsize=1)
def local_constraint_matrices() -> np.ndarray:
    """(21, 10, 10) symmetric matrices of one rotation's constraints (50a)-(50c) on ``[vec R;
    s]`` in the order of :func:`~rwhec_ros.core.relaxation.so3_constraint_matrices` (read-only)."""
    P, Qi, V, Ci = _PATTERN
    A = np.zeros((LOCAL_CONSTRAINTS, BLOCK, BLOCK))
    np.add.at(A, (Ci, P, Qi), V)
    A.flags.writeable = False
    return A


@dataclass(frozen=True)
class FrameBlocks:
    """The constraint operators of Problem 7 on the reduced ``z`` of ``n`` frames.

    Attributes
    ----------
    n : int
        Number of rotations (frames).
    index : ndarray of int, shape (n, 10)
        ``I_f``: the indices of ``vec R_f`` and of ``s`` in ``z``.
    A : ndarray, shape (20, 10, 10)
        The independent local constraint matrices (:data:`DROPPED` left out).
    """

    n: int
    index: np.ndarray
    A: np.ndarray

    @property
    def d(self) -> int:
        """Size of ``z``."""
        return 9 * self.n + 1

    @property
    def k(self) -> int:
        """Constraints kept per frame (20)."""
        return self.A.shape[0]

    @property
    def m(self) -> int:
        """Number of constraints of the interior-point method: ``k n`` and ``s^2 = 1`` last."""
        return self.k * self.n + 1

    def b(self) -> np.ndarray:
        """Right-hand side: 0 for the SO(3) constraints, 1 for ``s^2 = 1``."""
        out = np.zeros(self.m)
        out[-1] = 1.0
        return out

    def full_multipliers(self, y: np.ndarray) -> np.ndarray:
        """``lambda`` (21 n + 1,) in the order of :class:`~rwhec_ros.core.relaxation.
        ConstraintSet` from ``y`` (m,): the left-out constraint's multiplier is 0."""
        y = np.asarray(y, float)
        lam = np.zeros((self.n, LOCAL_CONSTRAINTS))
        lam[:, _KEPT] = y[:-1].reshape(self.n, self.k)
        return np.concatenate([lam.ravel(), y[-1:]])

    def blocks(self, X: np.ndarray) -> np.ndarray:
        """(n, 10, n, 10): ``X[I_f, I_g]`` for every pair of frames (``s`` in every block)."""
        ix = self.index
        return X[ix[:, :, None, None], ix[None, None, :, :]]

    def apply(self, X: np.ndarray) -> np.ndarray:
        """``A(X)``: ``(<A_i, X>)_i`` (m,) for a symmetric ``X`` (d, d)."""
        ix = self.index
        diag = X[ix[:, :, None], ix[:, None, :]].reshape(self.n, BLOCK * BLOCK)
        out = np.empty(self.m)
        out[:-1] = (diag @ self.A.reshape(self.k, -1).T).ravel()
        out[-1] = X[-1, -1]
        return out

    def adjoint(self, y: np.ndarray) -> np.ndarray:
        """``A^T(y) = sum_i y_i A_i`` (d, d), dense and symmetric."""
        y = np.asarray(y, float)
        d, n = self.d, self.n
        B = (y[:-1].reshape(n, self.k) @ self.A.reshape(self.k, -1)).reshape(n, BLOCK, BLOCK)
        K = np.zeros((d, d))
        r = self.index[:, :9]
        K[r[:, :, None], r[:, None, :]] = B[:, :9, :9]
        K[: 9 * n, -1] = B[:, :9, 9].ravel()
        K[-1, : 9 * n] = B[:, 9, :9].ravel()
        K[-1, -1] = B[:, 9, 9].sum() + y[-1]
        return K

    def jacobian(self, z: np.ndarray) -> np.ndarray:
        """``J`` (d, m) with columns ``A_i z``: ``A^T(delta) z = J delta`` (the normal space of
        the constraints at ``z``)."""
        z = np.asarray(z, float)
        n, k = self.n, self.k
        local = np.einsum("kpq,fq->fpk", self.A, z[self.index])  # (n, 10, k)
        J = np.zeros((self.d, self.m))
        cols = np.arange(n * k).reshape(n, k)
        J[self.index[:, :9, None], cols[:, None, :]] = local[:, :9, :]
        J[-1, :-1] = local[:, 9, :].ravel()
        J[-1, -1] = z[-1]
        return J

    def schur(self, W: np.ndarray) -> np.ndarray:
        """The Schur complement of the Nesterov-Todd direction, ``M_ij = <A_i, W A_j W>``
        (m, m), for a symmetric scaling matrix ``W`` (d, d).

        Block ``(f, g)``: ``M[(f, k), (g, l)] = <A_k, W_fg A_l W_fg^T>`` with ``W_fg = W[I_f,
        I_g]``; block ``(g, f)`` is its transpose, so only ``f <= g`` is computed: ``n (n + 1) /
        2`` stacks of ``20`` products of ``10 x 10`` matrices and one ``(20 n (n + 1) / 2, 100)
        x (100, 20)`` product. The row of ``s^2 = 1``: ``<A_l, w_g w_g^T>`` with ``w_g =
        W[I_g, s]``.
        """
        n, k = self.n, self.k
        Wb = self.blocks(W)                              # [f, q, g, r] = W[I_f q, I_g r]
        f, g = np.triu_indices(n)
        Wp = Wb[f, :, g, :]                              # (P, 10, 10): W_fg, f <= g
        Y = np.matmul(np.matmul(Wp[:, None], self.A[None]), Wp.transpose(0, 2, 1)[:, None])
        Mp = (Y.reshape(-1, BLOCK * BLOCK) @ self.A.reshape(k, -1).T).reshape(-1, k, k)
        M = np.empty((self.m, self.m))
        Mr = M[:-1, :-1].reshape(n, k, n, k)             # a view: [f, k', g, l]
        Mr[g, :, f, :] = Mp
        Mr[f, :, g, :] = Mp.transpose(0, 2, 1)
        ws = Wb[0, 9]                                    # W[s, I_g]: (n, 10)
        row = np.einsum("gr,lrt,gt->gl", ws, self.A, ws).ravel()
        M[-1, :-1] = row
        M[:-1, -1] = row
        M[-1, -1] = W[-1, -1] ** 2
        return M


_KEPT = np.array([c for c in range(LOCAL_CONSTRAINTS) if c != DROPPED])


@functools.lru_cache(maxsize=8)
def frame_blocks(n_frames: int) -> FrameBlocks:
    """:class:`FrameBlocks` of ``n_frames`` rotations (built once per count, read-only)."""
    n = int(n_frames)
    if n < 1:
        raise ValueError(f"n_frames: must be >= 1, got {n_frames!r}")
    d = 9 * n + 1
    index = np.concatenate([9 * np.arange(n)[:, None] + np.arange(9)[None, :],
                            np.full((n, 1), d - 1)], axis=1)
    A = np.ascontiguousarray(local_constraint_matrices()[_KEPT])
    for a in (index, A):
        a.flags.writeable = False
    return FrameBlocks(n=n, index=index, A=A)

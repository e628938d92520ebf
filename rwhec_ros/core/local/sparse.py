"""Riemannian Newton on the unreduced sparse cost: the local solver of the large-problem path.

Minimises the same function as :func:`rwhec_ros.core.local.dense.refine_rotations` -- the MLE
cost with the translations (and ``alpha``) at their optimum, ``f(R) = min_f z^T Q z`` over
SO(3)^n -- without forming ``Q'``. With ``z = [f; vec R; s]`` (:mod:`rwhec_ros.core.
sparse_problem`) and right perturbations ``R_l <- R_l exp(omega_l^)``:

* the free variables are re-optimised after every step (*variable projection*: ``f = -Q_ff^{-1}
  Q_fy y``), so the gradient of ``f(R)`` is the rotation part of ``2 Q z``: ``g_l = 4
  vee(R_l^T G_l)`` with ``G_l`` the 3x3 block of ``Q z`` of rotation ``l``;
* the Hessian of ``f(R)`` is the Schur complement of the Hessian in ``(f, omega)``::

      H = 2 [[Q_ff, Q_fr J], [J^T Q_rf, J^T Q_rr J + Diag(S_l - tr(S_l) I)]],

  ``S_l = sym(R_l^T G_l)``, ``J`` block-diagonal (``omega_l -> vec(R_l omega_l^)``), so solving
  ``(H + Diag(0, lambda I)) [df; omega] = [0; -g]`` gives exactly the damped Newton step
  ``(H_red + lambda I) omega = -g`` of the dense solver, with one sparse ``L D L^T``
  factorisation (:class:`~rwhec_ros.core.numerics.sparse_ldl.SparseLDL`) on a pattern fixed once.

The damping, the acceptance test and the stopping rules are those of the dense solver (the damping
scale uses the diagonal of ``J^T Q_rr J + D``, an upper bound on that of ``H_red``), so both reach
the same critical point.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..lie import vee
from ..model.sparse_cost import FullForm
from ..numerics.sparse_ldl import SparseLDL
from .dense import LocalSolution, LocalSolverOptions, _basis_jacobian, damped_newton

__all__ = ["NewtonSystem", "refine_rotations_sparse", "rotation_blocks"]


def rotation_blocks(Qz: np.ndarray, n_free: int, n: int) -> np.ndarray:
    """The 3x3 blocks ``G_l`` (n, 3, 3) of the rotation part of ``Q z`` (``vec`` column-major)."""
    return np.swapaxes(Qz[n_free: n_free + 9 * n].reshape(n, 3, 3), 1, 2)


class _UpperPattern:
    """A fixed upper-triangular CSC pattern of size ``N`` (full diagonal included) built from
    coordinate lists, and the positions of further coordinates in it."""

    def __init__(self, N: int, rows: list[np.ndarray], cols: list[np.ndarray]) -> None:
        r = np.concatenate(rows + [np.arange(N)])
        c = np.concatenate(cols + [np.arange(N)])
        self.N = N
        self.keys = np.unique(c.astype(np.int64) * N + r)
        self.indices = (self.keys % N).astype(np.int32)
        self.indptr = np.concatenate([[0], np.cumsum(np.bincount(self.keys // N, minlength=N))]
                                     ).astype(np.int32)

    def positions(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        return np.searchsorted(self.keys, cols.astype(np.int64) * self.N + rows)

    def matrix(self, data: np.ndarray) -> sp.csc_matrix:
        return sp.csc_matrix((data, self.indices, self.indptr), shape=(self.N, self.N))


class NewtonSystem:
    """The matrix ``H + Diag(0, lambda I)`` of the module docstring on ``[f; omega]`` (size
    ``n_free + 3 n``), assembled into a fixed pattern and factorised by ``L D L^T``.

    Parameters
    ----------
    Qs : scipy.sparse.csr_matrix
        The (scaled) symmetric cost on ``z`` (:class:`~rwhec_ros.core.model.sparse_cost.FullForm`).
    n_free, n : int
        Free variables and rotations.
    """

    def __init__(self, Qs: sp.csr_matrix, n_free: int, n: int) -> None:
        nf = n_free
        self.nf, self.n = nf, n
        N = nf + 3 * n
        Qff = sp.triu(Qs[:nf, :nf], format="coo")
        Qfr = Qs[:nf, nf: nf + 9 * n].tocoo()
        Brr = sp.bsr_matrix(Qs[nf: nf + 9 * n, nf: nf + 9 * n], blocksize=(9, 9))
        bl = np.repeat(np.arange(n), np.diff(Brr.indptr))
        bm = Brr.indices
        keep = bl <= bm
        self._bl, self._bm, self._B = bl[keep], bm[keep], Brr.data[keep]
        # coordinates of every contribution (upper triangle)
        fr_rows = np.repeat(Qfr.row, 3)
        fr_cols = nf + 3 * np.repeat(Qfr.col // 9, 3) + np.tile(np.arange(3), Qfr.nnz)
        self._fr_l, self._fr_a, self._fr_v = Qfr.col // 9, Qfr.col % 9, Qfr.data
        d, e = np.meshgrid(np.arange(3), np.arange(3), indexing="ij")
        rr_rows = (nf + 3 * self._bl[:, None] + d.ravel()[None, :]).ravel()
        rr_cols = (nf + 3 * self._bm[:, None] + e.ravel()[None, :]).ravel()
        self._rr_keep = rr_rows <= rr_cols
        dl_rows = (nf + 3 * np.arange(n)[:, None] + d.ravel()[None, :]).ravel()
        dl_cols = (nf + 3 * np.arange(n)[:, None] + e.ravel()[None, :]).ravel()
        self._dl_keep = dl_rows <= dl_cols
        self.pattern = _UpperPattern(N, [Qff.row, fr_rows, rr_rows[self._rr_keep]],
                                     [Qff.col, fr_cols, rr_cols[self._rr_keep]])
        P = self.pattern
        nnz = P.keys.size
        self._base = np.bincount(P.positions(Qff.row, Qff.col), weights=2.0 * Qff.data,
                                 minlength=nnz)
        self._pos_fr = P.positions(fr_rows, fr_cols)
        self._pos_rr = P.positions(rr_rows[self._rr_keep], rr_cols[self._rr_keep])
        self._pos_dl = P.positions(dl_rows[self._dl_keep], dl_cols[self._dl_keep])
        self._pos_om = P.positions(np.arange(nf, N), np.arange(nf, N))
        self._factor: SparseLDL | None = None
        self._data = self._base
        self.owner: object | None = None  # the model the matrix is assembled for

    def assemble(self, R: np.ndarray, G: np.ndarray) -> float:
        """Set the matrix for rotations ``R`` (n, 3, 3) and gradient blocks ``G`` (n, 3, 3);
        returns the largest absolute diagonal entry of its rotation block (damping scale)."""
        J = _basis_jacobian(R)  # (n, 9, 3)
        fr = 2.0 * self._fr_v[:, None] * J[self._fr_l, self._fr_a, :]  # (nnz, 3)
        rr = 2.0 * np.matmul(np.matmul(np.swapaxes(J[self._bl], 1, 2), self._B), J[self._bm])
        RtG = np.swapaxes(R, 1, 2) @ G
        S = 0.5 * (RtG + np.swapaxes(RtG, 1, 2))
        Dl = 2.0 * (S - np.trace(S, axis1=1, axis2=2)[:, None, None] * np.eye(3))
        nnz = self._base.size
        self._data = (self._base
                      + np.bincount(self._pos_fr, weights=fr.ravel(), minlength=nnz)
                      + np.bincount(self._pos_rr, weights=rr.reshape(-1)[self._rr_keep],
                                    minlength=nnz)
                      + np.bincount(self._pos_dl, weights=Dl.reshape(-1)[self._dl_keep],
                                    minlength=nnz))
        return float(np.abs(self._data[self._pos_om]).max(initial=0.0))

    def factor(self, damping: float) -> SparseLDL:
        """Factorise the assembled matrix plus ``damping`` on the rotation diagonal. Raises
        :class:`~rwhec_ros.core.numerics.sparse_ldl.FactorizationError` on a zero pivot."""
        data = self._data.copy()
        data[self._pos_om] += damping
        if self._factor is None:
            self._factor = SparseLDL(self.pattern.matrix(data))
        else:
            self._factor.refactor(data)
        return self._factor

    def step(self, g: np.ndarray, damping: float) -> np.ndarray:
        """The damped Newton step ``omega`` (3 n,) for gradient ``g``."""
        factor = self.factor(damping)
        rhs = np.concatenate([np.zeros(self.nf), -g])
        return factor.solve(rhs)[self.nf:]


class _SparseModel:
    """Cost, gradient and (lazily) the Newton system of ``min_f z^T Qs z`` at ``R`` for
    :func:`~rwhec_ros.core.local.dense.damped_newton`; the models share one
    :class:`NewtonSystem`, assembled for whichever model asks for a step."""

    def __init__(self, form: FullForm, Qs: sp.csr_matrix, system: NewtonSystem,
                 R: np.ndarray) -> None:
        self.R, self.system = R, system
        self.z = form.state(R)
        Qz = Qs @ self.z
        self.f = float(self.z @ Qz)
        self.G = rotation_blocks(Qz, form.n_free, form.n)
        self.g = (4.0 * vee(np.swapaxes(R, 1, 2) @ self.G)).reshape(-1)
        self._scale: float | None = None

    def _assembled(self) -> None:
        if self.system.owner is not self:
            self._scale = max(1.0, self.system.assemble(self.R, self.G))
            self.system.owner = self

    @property
    def scale_h(self) -> float:
        self._assembled()
        return self._scale

    def step(self, damping: float) -> np.ndarray:
        self._assembled()
        return self.system.step(self.g, damping)

    def curvature(self, step: np.ndarray, damping: float) -> float:
        # (H_red + damping I) step = -g  =>  step^T H_red step = -g.step - damping |step|^2
        return float(-(self.g @ step) - damping * (step @ step))


def refine_rotations_sparse(
    form: FullForm, Qs: sp.csr_matrix, R0: np.ndarray, options: LocalSolverOptions | None = None,
    f_floor: float = 1.0,
) -> LocalSolution:
    """Minimise ``min_f z^T Qs z`` over SO(3)^n from ``R0`` (n, 3, 3) by damped Riemannian Newton
    (:func:`~rwhec_ros.core.local.dense.damped_newton`) on the sparse system of the module
    docstring; ``Qs`` is ``form.Q`` divided by the data scale. The counterpart of
    :func:`~rwhec_ros.core.local.dense.refine_rotations`, except that the gradient tolerance is
    relative to ``max(f, f_floor)`` (the dense solver: ``max(f, 1)``): a start far above the
    optimum makes the scaled optimum ``f << 1``, and the certificate needs the stationarity
    relative to the optimum (``f_floor``: the cost regarded as zero, scaled)."""
    R0 = np.asarray(R0, dtype=float)
    system = NewtonSystem(Qs, form.n_free, R0.shape[0])
    first = _SparseModel(form, Qs, system, R0)
    # round-off level of f = z^T Q z: decreases below it are noise
    az = np.abs(first.z)
    f_noise = 64.0 * np.finfo(float).eps * float(az @ (abs(Qs) @ az))
    return damped_newton(R0, lambda R: _SparseModel(form, Qs, system, R),
                         options or LocalSolverOptions(), f_noise, f_floor, first)

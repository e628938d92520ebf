"""The certificate of the large-problem path: a rigorous dual bound from a sparse ``Z(lambda)``.

The dense certificate (:mod:`rwhec_ros.core.certificate`) bounds the smallest eigenvalue of the
reduced ``Z = Q' - K(lambda)``, whose ``Q'`` is dense for large rigs. Here the multipliers are the
same first-order ones (:func:`~rwhec_ros.core.local_solver.fast_certificate_multipliers`: the
blocks ``Gamma_l`` of the orthogonality constraints (50b) and ``lambda_s`` of ``s^2 = 1``), but the
bound is proven on the *unreduced* matrix (:mod:`rwhec_ros.core.sparse_problem` for ``z = [f;
y]``)::

    Z = Q_s - K,   K = Diag(0_f, Gamma_1 (x) I_3, ..., Gamma_n (x) I_3, lambda_s - sum tr Gamma_l),

with ``Q_s = Q / scale`` (``Q`` the symmetric matrix defined by the stored upper triangle; the
division is exact in the proof and its rounding is accounted for below). For every feasible ``z``
(rotations in SO(3), ``s^2 = 1``, free ``f``) weak duality gives ``z^T Q_s z = lambda_s + z^T Z
z``, because ``y^T K y = lambda_s`` on the constraint set.

**Theorem (the sparse bound).** Let ``Z_fl`` be ``Z`` as computed, ``|Z - Z_fl| <= E``
entrywise (``E`` symmetric, nonnegative), and choose shifts ``delta_i >= 0`` on the free
coordinates and ``mu`` on ``y``. Let ``A = fl(Z_fl + Diag(-delta, mu I))`` and suppose its
``L D L^T`` factorisation (:class:`~rwhec_ros.core.sparse_ldl.SparseLDL`) runs to completion with
every pivot ``D_ii > 0``, so that ``(I + L) D (I + L)^T = P^T (A + dA) P`` is positive
semidefinite with ``|dA| <= W`` (the bound of :mod:`rwhec_ros.core.sparse_ldl`). Put::

    c_i = (W 1)_i + u |A_ii| + (E 1)_i.

If ``delta_i >= c_i`` for every free coordinate ``i``, then for every feasible ``z``::

    z^T Q_s z >= d = lambda_s - (3 n + 1) mu - min(sum_{i in y} c_i, (3 n + 1) max_{i in y} c_i).

*Proof.* ``Z = (A + dA) - dA - (A - Z_fl - Diag(sigma)) - Diag(sigma) + (Z - Z_fl)`` with
``sigma = (-delta, mu)``; the first term is PSD, ``|A_ii - (Z_fl,ii + sigma_i)| <= u |A_ii|``
(one rounding), and for any symmetric nonnegative ``N``, ``|z|^T N |z| <= sum_i z_i^2 (N 1)_i``
(``2 |z_i z_j| <= z_i^2 + z_j^2``). Hence ``z^T Z z >= -sum_i (sigma_i + c_i) z_i^2 =
sum_{free} (delta_i - c_i) f_i^2 - sum_{y} (mu + c_i) y_i^2 >= -mu |y|^2 - sum_y c_i y_i^2``, and
for feasible ``y``, ``|y|^2 = 3 n + 1`` and ``y_i^2 <= 1``. Weak duality concludes. ∎

Why the shifts have these signs: the translations are unconstrained, so a negative curvature
along them, however small, cannot be absorbed by the norm of ``y``; the free block is therefore
shifted *down* by at least its own rounding (proving ``Z`` nonnegative there with room to spare),
and only the ``y`` block pays, through ``mu`` and ``c_y``. The rounding ``c_i`` is bounded per
coordinate, with ``gamma_{r_i + 5}`` from the nonzeros ``r_i`` of row ``i`` of ``L``, so the
dense rows of a hub (a target seen by every camera) do not inflate the margin of the other rows.

``E`` covers the division by the scale (``u |Q_s|``), the subtraction of ``K`` (``u (|Q_s| +
|K|)``) and the sum ``lambda_s - sum tr Gamma_l`` (``gamma_{3n+1}`` times the sum of magnitudes);
the entries of ``K`` on the rotation blocks are the stored ``Gamma_l`` themselves (exact).

**Choice of the shifts.** ``mu`` starts at ``gamma_64`` times the mean ``|Z_ii|`` over ``y`` (a
hub rotation, seen by every camera, has a diagonal entry ``n`` times the others) and grows
(8-fold, later 64-fold) while the factorisation fails; ``delta`` starts at a guess of the rounding
and is raised to ``2 c`` when the check fails (one more factorisation with the same ordering).
The numerical null space and the smallest eigenvalues of the *reduced* certificate matrix
``Z_y - Z_yf Z_ff^{-1} Z_fy`` (the quantities the dense certificate reports) are estimated by
shift-invert Lanczos with the same factorisation: ``((Z + Diag(-delta, mu))^{-1} [0; b])_y =
(Z_red + mu I)^{-1} b`` up to the tiny ``delta``. They decide uniqueness (a one-dimensional null
space), never the bound.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .certificate import CertificateOptions, DualBound, certificate_from_bound
from .result import Certificate, Status
from .sparse_ldl import FactorizationError, SparseLDL, upper_with_diagonal
from .sparse_problem import FullForm
from .sparse_solver import rotation_blocks
from .verified import UNIT_ROUNDOFF, gamma

__all__ = ["CertificatePattern", "first_order_multipliers", "sparse_dual_bound", "certify_sparse"]

#: Factorisations tried with a growing ``mu`` before giving up on a bound.
MAX_ATTEMPTS = 16


class CertificatePattern:
    """The fixed upper-triangular pattern of ``Z = Q_s - K`` (module docstring): ``Q_s``'s own
    pattern, the 3 x 3 ``Gamma_l (x) I_3`` entries of every rotation block and the diagonal; built
    once per problem and scale."""

    def __init__(self, form: FullForm, Qs: sp.csr_matrix) -> None:
        nf, n = form.n_free, form.n
        size = form.size
        a, b, i = np.meshgrid(np.arange(3), np.arange(3), np.arange(3), indexing="ij")
        up = (a <= b).ravel()
        self._a, self._b = a.ravel()[up], b.ravel()[up]
        loc_r = (3 * a + i).ravel()[up]
        loc_c = (3 * b + i).ravel()[up]
        self._k_rows = (nf + 9 * np.arange(n)[:, None] + loc_r[None, :]).ravel()
        self._k_cols = (nf + 9 * np.arange(n)[:, None] + loc_c[None, :]).ravel()
        U = upper_with_diagonal(Qs, self._k_rows, self._k_cols)
        self.U = U
        keys = U.indices.astype(np.int64) + size * np.repeat(np.arange(size), np.diff(U.indptr))
        order_keys = self._k_cols.astype(np.int64) * size + self._k_rows
        self.pos_k = np.searchsorted(keys, order_keys)
        self.diag = U.indptr[1:] - 1
        self.abs_rows_Q = np.asarray(abs(Qs).sum(axis=1)).ravel()
        self.nf, self.n, self.size = nf, n, size

    def matrix_data(self, Gamma: np.ndarray, lambda_s: float) -> tuple[np.ndarray, np.ndarray]:
        """``Z_fl`` (the data of :attr:`U`) for the blocks ``Gamma`` (n, 3, 3) and ``lambda_s``,
        and the row sums of ``E`` (module docstring)."""
        n, nf = self.n, self.nf
        data = self.U.data.copy()
        kv = Gamma[:, self._a, self._b].ravel()  # entry (3a+i, 3b+i) of block l is Gamma_l[a, b]
        data[self.pos_k] -= kv
        tr = float(np.trace(Gamma, axis1=1, axis2=2).sum())
        k_ss = lambda_s - tr
        data[self.diag[-1]] -= k_ss
        k_rows = np.zeros(self.size)
        # row 3a+i of block l holds Gamma_l[a, b] for b = 0..2
        k_rows[nf: nf + 9 * n] = np.repeat(np.abs(Gamma).sum(axis=2), 3, axis=1).ravel()
        k_rows[-1] = abs(k_ss)
        err = gamma(2) * (self.abs_rows_Q + k_rows)
        err[-1] += gamma(3 * n + 1) * (abs(lambda_s) + float(np.abs(
            np.diagonal(Gamma, axis1=1, axis2=2)).sum()))
        return data, err


def first_order_multipliers(form: FullForm, Qs: sp.csr_matrix, R: np.ndarray
                            ) -> tuple[np.ndarray, float, np.ndarray]:
    """``Gamma_l = sym(R_l^T G_l)`` (n, 3, 3), ``lambda_s = z^T Q_s z`` and ``z`` at rotations ``R``
    with optimal free variables (the multipliers of the fast certificate, module docstring)."""
    z = form.state(R)
    Qz = Qs @ z
    G = rotation_blocks(Qz, form.n_free, form.n)
    RtG = np.swapaxes(R, 1, 2) @ G
    return 0.5 * (RtG + np.swapaxes(RtG, 1, 2)), float(z @ Qz), z


@dataclass
class SparseBound:
    """The outcome of :func:`sparse_dual_bound`: the bound (scaled units), the factorisation that
    proved it (or the last positive definite one), and the shifts."""

    bound: DualBound
    factor: SparseLDL | None
    mu: float
    attempts: int


def sparse_dual_bound(pattern: CertificatePattern, data: np.ndarray, err_rows: np.ndarray,
                      lambda_s: float, mu0: float) -> SparseBound:
    """``d`` of the theorem in the module docstring (scaled units) for ``Z_fl`` with the upper
    data ``data`` and the rounding row sums ``err_rows``; ``mu0`` is the first ``mu``."""
    nf, n = pattern.nf, pattern.n
    ny = 9 * n + 1
    diag = pattern.diag
    mu = float(mu0)
    # first guess of the free block's rounding; raised to twice the actual bound if that is
    # larger (a hub row of L is long: one more factorisation with the same ordering)
    delta = 4.0 * gamma(64) * pattern.abs_rows_Q[:nf]
    factor = None
    attempts = adjust = 0
    reason = "no shifted factorisation of Z succeeded"
    while attempts < MAX_ATTEMPTS:
        attempts += 1
        A = data.copy()
        A[diag[:nf]] -= delta
        A[diag[nf:]] += mu
        try:
            if factor is None:
                factor = SparseLDL(sp.csc_matrix((A, pattern.U.indices, pattern.U.indptr),
                                                 shape=pattern.U.shape))
            else:
                factor.refactor(A)
            ok = factor.positive_definite
        except FactorizationError:
            factor, ok = None, False
        if not ok:
            mu *= 8.0 if attempts <= 4 else 64.0
            continue
        c = factor.backward_error_rows() + UNIT_ROUNDOFF * np.abs(A[diag]) + err_rows
        c *= 1.0 + gamma(4)
        short = c[:nf] > delta
        if np.any(short):  # the free block's rounding exceeds its shift: raise it and redo
            if adjust == 3:
                reason = "the rounding of the translation block exceeds its shift"
                break
            adjust += 1
            delta = np.maximum(delta, 2.0 * c[:nf])
            continue
        c_y = c[nf:]
        e_y = float(min(c_y.sum(), ny * c_y.max(initial=0.0)) * (1.0 + gamma(ny)))
        eig_term = float(ny * mu * (1.0 + gamma(2)))
        value = float(lambda_s - eig_term - e_y)
        lower = -(mu + float(c_y.max(initial=0.0)))
        return SparseBound(DualBound(value, float(lambda_s), lower, eig_term, e_y, 0.0),
                           factor, mu, attempts)
    if factor is not None and not factor.positive_definite:
        factor = None
    return SparseBound(DualBound(float("-inf"), float(lambda_s), float("-inf"), float("inf"),
                                 float("nan"), float("nan"), reason), factor, mu, attempts)


def reduced_eigenvalues(factor: SparseLDL, mu: float, nf: int, n: int, k: int,
                        rotations_only: bool) -> np.ndarray:
    """The ``k`` smallest eigenvalues (ascending, an estimate) of the reduced certificate matrix
    on ``y`` (or on the rotations only), by shift-invert Lanczos with ``factor`` of ``Z +
    Diag(-delta, mu I)`` (module docstring)."""
    m = 9 * n if rotations_only else 9 * n + 1
    size = factor.n

    def op(b: np.ndarray) -> np.ndarray:
        rhs = np.zeros(size)
        rhs[nf: nf + m] = b
        return factor.solve(rhs)[nf: nf + m]

    def no_matvec(_b: np.ndarray) -> np.ndarray:  # ARPACK's shift-invert mode never calls it
        raise RuntimeError("matvec of the reduced certificate matrix is not available")

    k = int(min(k, m - 1))
    OP = spla.LinearOperator((m, m), matvec=op, dtype=float)
    A = spla.LinearOperator((m, m), matvec=no_matvec, dtype=float)
    w = spla.eigsh(A, k=k, sigma=-mu, which="LM", OPinv=OP, return_eigenvectors=False,
                   v0=np.ones(m))
    return np.sort(w)


def certify_sparse(
    form: FullForm,
    Qs: sp.csr_matrix,
    pattern: CertificatePattern,
    R: np.ndarray,
    primal_cost: float,
    scale: float,
    *,
    homogeneous: bool = False,
    cost_floor: float = 0.0,
    options: CertificateOptions | None = None,
) -> Certificate:
    """The certificate of rotations ``R`` (n, 3, 3) with the direct cost ``primal_cost``
    (unscaled) on the large-problem path (module docstring). ``Qs = form.Q / scale``; ``pattern``
    from :class:`CertificatePattern` ``(form, Qs)``; ``homogeneous``, ``cost_floor`` and
    ``options`` as for :func:`~rwhec_ros.core.certificate.certify_from_Z`."""
    opts = options or CertificateOptions()
    n, nf = form.n, form.n_free
    Gamma, lambda_s, _ = first_order_multipliers(form, Qs, R)
    p = float(primal_cost)
    if not (np.isfinite(lambda_s) and np.isfinite(p) and np.all(np.isfinite(Gamma))):
        return Certificate(Status.SOLVER_FAILED, p, float("nan"), float("nan"), float("nan"),
                           np.zeros(0), -1, opts.rho_tol, "no finite dual point")
    data, err = pattern.matrix_data(Gamma, lambda_s)
    # first shift: the typical rounding of the y block (as the dense verified bound starts)
    mu0 = gamma(64) * float(np.abs(data[pattern.diag[nf:]]).mean()) + 1e-300
    sb = sparse_dual_bound(pattern, data, err, lambda_s, mu0)
    z_ss = float(data[pattern.diag[-1]])
    if sb.factor is None:
        w = np.array([float("nan")])
        null_dim, trivial_s = -1, False
    elif homogeneous:  # s is decoupled: its eigenvalue is Z_ss, the rest are the rotations'
        w_r = reduced_eigenvalues(sb.factor, sb.mu, nf, n, opts.n_eigenvalues, True)
        w = np.sort(np.append(w_r, z_ss))[: opts.n_eigenvalues]
        trivial_s = abs(z_ss) <= opts.null_tol
        null_dim = int(np.sum((w_r if trivial_s else w) <= opts.null_tol))
    else:
        w = reduced_eigenvalues(sb.factor, sb.mu, nf, n, opts.n_eigenvalues, False)
        null_dim, trivial_s = int(np.sum(w <= opts.null_tol)), False
    return certificate_from_bound(sb.bound, w, null_dim, trivial_s, p, scale,
                                  cost_floor=cost_floor, options=opts)

"""The certificate of the large-problem path: a rigorous dual bound from a sparse ``Z(lambda)``.

The dense certificate (:mod:`rwhec_ros.core.certify.dense`) bounds the smallest eigenvalue of the
reduced ``Z = Q' - K(lambda)``, whose ``Q'`` is dense for large rigs. Here the multipliers are the
same first-order ones (:func:`~rwhec_ros.core.certify.multipliers.fast_certificate_multipliers`: the
blocks ``Gamma_l`` of the orthogonality constraints (50b) and ``lambda_s`` of ``s^2 = 1``), but the
bound is proven on the *unreduced* matrix (:mod:`rwhec_ros.core.model.sparse_cost` for ``z = [f;
y]``)::

    Z = Q_s - K,   K = Diag(0_f, Gamma_1 (x) I_3, ..., Gamma_n (x) I_3, lambda_s - sum tr Gamma_l),

with ``Q_s = Q / scale`` (``Q`` the symmetric matrix defined by the stored upper triangle; the
division is exact in the proof and its rounding is accounted for below). For every feasible ``z``
(rotations in SO(3), ``s^2 = 1``, free ``f``) weak duality gives ``z^T Q_s z = lambda_s + z^T Z
z``, because ``y^T K y = lambda_s`` on the constraint set.

**Theorem (the sparse bound).** Let ``Z_fl`` be ``Z`` as computed, ``|Z - Z_fl| <= E``
entrywise (``E`` symmetric, nonnegative), and choose shifts ``delta_i >= 0`` on the free
coordinates and ``mu`` on ``y``. Let ``A = fl(Z_fl + Diag(-delta, mu I))`` and suppose its
``L D L^T`` factorisation (:class:`~rwhec_ros.core.numerics.sparse_ldl.SparseLDL`) runs to
completion with every pivot ``D_ii > 0``, so that ``(I + L) D (I + L)^T = P^T (A + dA) P`` is
positive semidefinite, and let ``w`` be weights with ``(|dA| 1)_i <= w_i``
(:meth:`~rwhec_ros.core.numerics.sparse_ldl.SparseLDL.backward_error_rows`). Put::

    c_i = w_i + u |A_ii| + (E 1)_i.

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
the entries of ``K`` on the rotation blocks are the stored ``Gamma_l`` themselves (exact). The
final subtractions of ``d`` are rounded down by ``4 u`` of their magnitudes. The theorem holds for
any multipliers; the *strengthened* certificate uses ``lambda + t lambda_h`` with the handedness
direction ``lambda_h`` of :func:`~rwhec_ros.core.certify.multipliers.handedness_multipliers` (whose
matrix ``D`` has ``D z = 0``), its entries' rounding added to ``E``.

Scope, as for the dense certificate: ``Q`` as computed in double precision -- here the unreduced
cost of :mod:`rwhec_ros.core.model.sparse_cost`, with the gauge penalty as its spring tree and the
translations shifted by the prior's particular solution, the same problem in exact arithmetic --
and ``p`` the direct cost of eq. (33) plus the penalty at the returned estimate.

**Choice of the shifts.** ``mu`` starts at ``gamma_64`` times the mean ``|Z_ii|`` over ``y`` (a
hub rotation, seen by every camera, has a diagonal entry ``n`` times the others) and grows
(8-fold, later 64-fold) while the factorisation fails, and is never below ``1.5 sum_free delta_i
z_i^2 / |y|^2`` for the estimate ``z`` (``Z z ~ 0``, so ``z^T (Z + Diag(-delta, mu)) z > 0``
needs it); ``delta`` starts at a guess of the rounding and is refit to ``1.25 c`` after the first
factorisation (one more factorisation with the same ordering; again if ``c`` grew).
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

from ..local.sparse import rotation_blocks
from ..model.sparse_cost import FullForm
from ..numerics.sparse_ldl import FactorizationError, SparseLDL, upper_with_diagonal
from ..numerics.verified import UNIT_ROUNDOFF, gamma, lanczos_start
from ..result import Certificate, Status
from .dense import CertificateOptions, DualBound, certificate_from_bound
from .multipliers import handedness_multipliers
from .relaxation import _PATTERN

__all__ = ["CertificatePattern", "first_order_multipliers", "sparse_dual_bound", "certify_sparse"]

#: Factorisations tried with a growing ``mu`` before giving up on a bound.
MAX_ATTEMPTS = 16


def _handedness_layout() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local upper pairs ``(p, q)``, ``p <= q`` of one rotation's ``[vec R; s]`` (``s`` local 9)
    and the scatter matrix from the constraint entries of
    :func:`~rwhec_ros.core.certify.relaxation.so3_constraint_matrices` to them."""
    P, Qi, _, _ = _PATTERN
    pp, qq = np.triu_indices(10)
    slot = {(int(a), int(b)): k for k, (a, b) in enumerate(zip(pp, qq, strict=True))}
    target = np.array([slot.get((int(a), int(b)), -1) for a, b in zip(P, Qi, strict=True)])
    return pp, qq, target


_HAND_P, _HAND_Q, _HAND_TARGET = _handedness_layout()


def handedness_entries(R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The upper entries (n, 55) of the 10 x 10 blocks on ``[vec R_l; s]`` of the matrix ``D`` of
    :func:`~rwhec_ros.core.certify.multipliers.handedness_multipliers` (``D z = 0``), and of an
    entrywise bound on their absolute values (the terms summed)."""
    _, _, V, Ci = _PATTERN
    n = R.shape[0]
    lam = handedness_multipliers(R)[: 21 * n].reshape(n, 21)
    terms = V[None, :] * lam[:, Ci]  # (n, entries)
    keep = _HAND_TARGET >= 0  # the lower halves of split entries mirror the upper ones
    vals = np.zeros((n, 55))
    absv = np.zeros((n, 55))
    for k in np.flatnonzero(keep):
        vals[:, _HAND_TARGET[k]] += terms[:, k]
        absv[:, _HAND_TARGET[k]] += np.abs(terms[:, k])
    return vals, absv


class CertificatePattern:
    """The fixed upper-triangular pattern of ``Z = Q_s - K`` (module docstring): ``Q_s``'s own
    pattern, every rotation's 9 x 9 block and its column of ``s`` (the ``Gamma_l (x) I_3``
    entries and those of the handedness direction used to strengthen the certificate) and the
    diagonal; built once per problem and scale."""

    def __init__(self, form: FullForm, Qs: sp.csr_matrix) -> None:
        nf, n = form.n_free, form.n
        size = form.size
        a, b, i = np.meshgrid(np.arange(3), np.arange(3), np.arange(3), indexing="ij")
        up = (a <= b).ravel()
        self._a, self._b = a.ravel()[up], b.ravel()[up]
        loc_r = (3 * a + i).ravel()[up]
        loc_c = (3 * b + i).ravel()[up]
        k_rows = (nf + 9 * np.arange(n)[:, None] + loc_r[None, :]).ravel()
        k_cols = (nf + 9 * np.arange(n)[:, None] + loc_c[None, :]).ravel()
        base = nf + 9 * np.arange(n)[:, None]
        h_rows = np.where(_HAND_P[None, :] == 9, size - 1, base + _HAND_P[None, :]).ravel()
        h_cols = np.where(_HAND_Q[None, :] == 9, size - 1, base + _HAND_Q[None, :]).ravel()
        U = upper_with_diagonal(Qs, np.concatenate([k_rows, h_rows]),
                                np.concatenate([k_cols, h_cols]))
        self.U = U
        keys = U.indices.astype(np.int64) + size * np.repeat(np.arange(size), np.diff(U.indptr))
        self.pos_k = np.searchsorted(keys, k_cols.astype(np.int64) * size + k_rows)
        self.pos_h = np.searchsorted(keys, h_cols.astype(np.int64) * size + h_rows)
        self._h_rows, self._h_cols = h_rows, h_cols
        self.diag = U.indptr[1:] - 1
        self.abs_rows_Q = np.asarray(abs(Qs).sum(axis=1)).ravel()
        self.nf, self.n, self.size = nf, n, size

    def factorise(self, data: np.ndarray, factor: SparseLDL | None = None) -> SparseLDL | None:
        """``L D L^T`` of the matrix with the upper data ``data`` (refactoring ``factor`` when
        given: same pattern, same ordering); ``None`` on a breakdown."""
        try:
            if factor is None:
                return SparseLDL(sp.csc_matrix((data, self.U.indices, self.U.indptr),
                                               shape=self.U.shape))
            factor.refactor(data)
            return factor
        except FactorizationError:
            return None

    def matrix_data(self, Gamma: np.ndarray, lambda_s: float, t: float = 0.0,
                    hand: tuple[np.ndarray, np.ndarray] | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
        """``Z_fl`` (the data of :attr:`U`) for the blocks ``Gamma`` (n, 3, 3), ``lambda_s`` and
        ``t`` times the handedness direction ``hand`` (:func:`handedness_entries`), and the row
        sums of ``E`` (module docstring)."""
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
        if t != 0.0 and hand is not None:
            vals, absv = hand
            data -= np.bincount(self.pos_h, weights=t * vals.ravel(), minlength=data.size)
            # D's entries are sums of at most 6 terms; times t, subtracted, and the s entry sums
            # n of them: gamma_{n + 8} on the terms' magnitudes, row by row (both triangles)
            a = abs(t) * absv.ravel()
            off = self._h_rows != self._h_cols
            h_rows = (np.bincount(self._h_rows, weights=a, minlength=self.size)
                      + np.bincount(self._h_cols[off], weights=a[off], minlength=self.size))
            # ... and one more rounding where the subtraction meets those of Q_s and K
            err += gamma(n + 8) * h_rows + gamma(2) * (self.abs_rows_Q + k_rows + h_rows)
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
                      lambda_s: float, mu0: float, z: np.ndarray | None = None) -> SparseBound:
    """``d`` of the theorem in the module docstring (scaled units) for ``Z_fl`` with the upper
    data ``data`` and the rounding row sums ``err_rows``; ``mu0`` is the first ``mu``. ``z``, the
    primal point (``Z z ~ 0``), if given, sets the least ``mu`` that can succeed for the free
    shift: ``z^T Diag(-delta, mu) z > 0``, i.e. ``mu > sum_free delta_i z_i^2 / |y|^2``."""
    nf, n = pattern.nf, pattern.n
    ny = 9 * n + 1
    diag = pattern.diag
    # first guess of the free block's rounding; after the first factorisation the shift is refit
    # to 1.25 times the actual bound (down for short rows, up for the long rows of a hub), and
    # raised again if a refactorisation shows more
    delta = 4.0 * gamma(64) * pattern.abs_rows_Q[:nf]
    factor = None
    attempts = adjust = 0
    fitted = False
    reason = "no shifted factorisation of Z succeeded"

    def mu_for(delta: np.ndarray) -> float:
        if z is None:
            return 0.0
        return 1.5 * float(delta @ z[:nf] ** 2) / float(z[nf:] @ z[nf:])

    floor_mu = float(mu0)
    mu = max(floor_mu, mu_for(delta))
    while attempts < MAX_ATTEMPTS:
        attempts += 1
        A = data.copy()
        A[diag[:nf]] -= delta
        A[diag[nf:]] += mu
        factor = pattern.factorise(A, factor)
        ok = factor is not None and factor.positive_definite
        if not ok:
            floor_mu = mu * (8.0 if attempts <= 6 else 64.0)
            mu = max(floor_mu, mu_for(delta))
            continue
        c = factor.backward_error_rows() + UNIT_ROUNDOFF * np.abs(A[diag]) + err_rows
        c *= 1.0 + gamma(4)
        short = c[:nf] > delta
        if not fitted or np.any(short):  # refit the free shift to its rounding and redo
            if adjust == 4:
                reason = "the rounding of the translation block exceeds its shift"
                break
            adjust += 1
            delta = 1.25 * c[:nf] if not fitted else np.maximum(delta, 1.25 * c[:nf])
            fitted = True
            mu = max(floor_mu, mu_for(delta))
            continue
        c_y = c[nf:]
        e_y = float(min(c_y.sum(), ny * c_y.max(initial=0.0)) * (1.0 + gamma(ny)))
        eig_term = float(ny * mu * (1.0 + gamma(2)))
        # the two subtractions themselves round: 4 u of the magnitudes, subtracted too
        value = float(lambda_s - eig_term - e_y)
        value -= 4.0 * UNIT_ROUNDOFF * (abs(lambda_s) + eig_term + e_y)
        lower = -(mu + float(c_y.max(initial=0.0)))
        return SparseBound(DualBound(value, float(lambda_s), lower, eig_term, e_y, 0.0),
                           factor, mu, attempts)
    if factor is not None and not factor.positive_definite:
        factor = None
    return SparseBound(DualBound(float("-inf"), float(lambda_s), float("-inf"), float("inf"),
                                 float("nan"), float("nan"), reason), factor, mu, attempts)


def reduced_eigenvalues(factor: SparseLDL, mu: float, nf: int, n: int, k: int,
                        rotations_only: bool, vectors: bool = False):
    """The ``k`` smallest eigenvalues (ascending, an estimate) of the reduced certificate matrix
    on ``y`` (or on the rotations only), by shift-invert Lanczos with ``factor`` of ``Z +
    Diag(-delta, mu I)`` (module docstring); with ``vectors``, also the eigenvectors (m, k)."""
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
    # estimates to 1e-8 relative in (Z_red + mu I)^{-1}: ample for the null_tol decision
    out = spla.eigsh(A, k=k, sigma=-mu, which="LM", OPinv=OP, return_eigenvectors=vectors,
                     v0=lanczos_start(m), tol=1e-8)
    if not vectors:
        return np.sort(out)
    w, V = out
    order = np.argsort(w)
    return w[order], V[:, order]


@dataclass
class _Dual:
    """The first-order dual point at the estimate: ``Gamma`` (n, 3, 3), ``lambda_s``, the primal
    ``z`` and what the status decision needs."""

    Gamma: np.ndarray
    lambda_s: float
    z: np.ndarray
    p: float
    scale: float
    homogeneous: bool
    cost_floor: float
    opts: CertificateOptions


def _certificate_at(pattern: CertificatePattern, dual: _Dual, t: float = 0.0,
                    hand: tuple[np.ndarray, np.ndarray] | None = None
                    ) -> tuple[Certificate, np.ndarray | None]:
    """The certificate of the multipliers ``lambda + t lambda_h`` and the direction of the second
    smallest eigenvalue of the reduced matrix (on ``y``; ``None`` without a bound): in the span
    of the two smallest eigenvectors, the one orthogonal to the estimate's own ``y``."""
    opts, nf, n = dual.opts, pattern.nf, pattern.n
    data, err = pattern.matrix_data(dual.Gamma, dual.lambda_s, t, hand)
    # first shift: the typical rounding of the y block (as the dense verified bound starts)
    mu0 = gamma(64) * float(np.abs(data[pattern.diag[nf:]]).mean()) + 1e-300
    sb = sparse_dual_bound(pattern, data, err, dual.lambda_s, mu0, dual.z)
    z_ss = float(data[pattern.diag[-1]])
    v2 = None
    k = opts.n_eigenvalues
    if sb.factor is None:
        w = np.array([float("nan")])
        null_dim, trivial_s = -1, False
    elif dual.homogeneous and t == 0.0:
        # s is decoupled: its eigenvalue is Z_ss, the others are the rotations'
        w_r, V = reduced_eigenvalues(sb.factor, sb.mu, nf, n, k, True, vectors=True)
        w = np.sort(np.append(w_r, z_ss))[:k]
        trivial_s = abs(z_ss) <= opts.null_tol
        null_dim = int(np.sum((w_r if trivial_s else w) <= opts.null_tol))
        v2 = _second_direction(V, dual.z[nf: nf + 9 * n])
        v2 = np.append(v2, 0.0)
    else:
        w, V = reduced_eigenvalues(sb.factor, sb.mu, nf, n, k, False, vectors=True)
        null_dim, trivial_s = int(np.sum(w <= opts.null_tol)), False
        v2 = _second_direction(V, dual.z[nf:])
    cert = certificate_from_bound(sb.bound, w, null_dim, trivial_s, dual.p, dual.scale,
                                  cost_floor=dual.cost_floor, options=opts)
    return cert, v2


def _second_direction(V: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The unit vector in the span of ``V[:, :2]`` orthogonal to ``y``."""
    c = V[:, :2].T @ (y / np.linalg.norm(y))
    v = V[:, :2] @ np.array([c[1], -c[0]])
    nv = float(np.linalg.norm(v))
    return v / nv if nv > 0 else V[:, 1]


def _handedness_matrix_y(vals: np.ndarray, n: int) -> sp.csr_matrix:
    """The handedness direction ``D`` on ``y = [vec R; s]`` (9 n + 1, symmetric, sparse)."""
    base = 9 * np.arange(n)[:, None]
    r = np.where(_HAND_P[None, :] == 9, 9 * n, base + _HAND_P[None, :]).ravel()
    c = np.where(_HAND_Q[None, :] == 9, 9 * n, base + _HAND_Q[None, :]).ravel()
    U = sp.csr_matrix((vals.ravel(), (r, c)), shape=(9 * n + 1, 9 * n + 1))
    return (U + sp.triu(U, 1).T).tocsr()


def _strengthen(pattern: CertificatePattern, dual: _Dual, R: np.ndarray, v2: np.ndarray
                ) -> Certificate | None:
    """A certified certificate with the multipliers ``lambda + t lambda_h`` of the handedness
    direction (:func:`~rwhec_ros.core.certify.multipliers.strengthen_certificate`, sparse): ``t``
    moves the second null direction ``v2`` up (sign from ``v2^T D v2``) in 4-fold steps from where
    the first-order change reaches ``2 null_tol``, each ``t`` screened by the inertia of ``Z(t) -
    null_tol`` on ``y`` (one eigenvalue below ``null_tol``: the estimate's own direction); the
    rigorous bound is then computed at the middle of the passing steps (then the others, nearest
    first). ``None`` when no ``t`` certifies."""
    opts, nf, n = dual.opts, pattern.nf, pattern.n
    hand = handedness_entries(R)
    slope = float(v2 @ (_handedness_matrix_y(hand[0], n) @ v2))
    if not np.isfinite(slope) or abs(slope) < 1e-300:
        return None
    data0, _ = pattern.matrix_data(dual.Gamma, dual.lambda_s)
    t_max = float(np.abs(data0).max()) / max(float(np.abs(hand[0]).max()), 1e-300)
    t = -np.sign(slope) * 2.0 * opts.null_tol / abs(slope)
    delta = 4.0 * gamma(64) * pattern.abs_rows_Q[:nf]
    probe = None
    passed: list[float] = []
    while abs(t) <= t_max:
        data, _ = pattern.matrix_data(dual.Gamma, dual.lambda_s, t, hand)
        data[pattern.diag[:nf]] -= delta
        data[pattern.diag[nf:]] -= opts.null_tol
        probe = pattern.factorise(data, probe)
        below = -1 if probe is None else probe.n_negative
        if below == 1:
            passed.append(t)
        elif passed:
            break  # left the interval where only the estimate's direction is below null_tol
        t *= 4.0
    # the second eigenvalue is concave in t: the middle of the passing steps is near its maximum
    for t in sorted(passed, key=lambda x: abs(np.log(abs(x)) - np.mean(np.log(np.abs(passed))))):
        cert, _ = _certificate_at(pattern, dual, t, hand)
        if cert.certified:
            return cert
    return None


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
    strengthen: bool = True,
) -> tuple[Certificate, bool]:
    """The certificate of rotations ``R`` (n, 3, 3) with the direct cost ``primal_cost``
    (unscaled) on the large-problem path (module docstring) and whether it needed the handedness
    multipliers. ``Qs = form.Q / scale``; ``pattern`` from :class:`CertificatePattern` ``(form,
    Qs)``; ``homogeneous``, ``cost_floor`` and ``options`` as for
    :func:`~rwhec_ros.core.certify.dense.certify_from_Z`. With ``strengthen``, a certificate that
    proves the bound but shows a second null direction is retried with the handedness
    multipliers, as on the dense path."""
    opts = options or CertificateOptions()
    Gamma, lambda_s, z = first_order_multipliers(form, Qs, R)
    p = float(primal_cost)
    if not (np.isfinite(lambda_s) and np.isfinite(p) and np.all(np.isfinite(Gamma))):
        return Certificate(Status.SOLVER_FAILED, p, float("nan"), float("nan"), float("nan"),
                           np.zeros(0), -1, opts.rho_tol, "no finite dual point"), False
    dual = _Dual(Gamma, lambda_s, z, p, scale, homogeneous, cost_floor, opts)
    cert, v2 = _certificate_at(pattern, dual)
    if (strengthen and v2 is not None and cert.status is Status.NOT_TIGHT
            and cert.lambda_min >= -opts.null_tol):
        better = _strengthen(pattern, dual, R, v2)
        if better is not None:
            return better, True
    return cert, False

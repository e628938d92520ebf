"""Every path of the sparse certificate (:mod:`rwhec_ros.core.certify.sparse`) against a
reference: the bound against the documented algorithm and formula (module docstring, "The sparse
bound" and "Choice of the shifts"), the eigenvalue estimates against ``numpy.linalg.eigvalsh`` of
the dense reduced matrix, the status decisions (homogeneous ``s``, tolerances exactly at an
eigenvalue, no bound, no finite dual point) and the handedness strengthening against a dense
replay of its documented search. Problems: a one-target star of 5 cameras (6 rotations, known or
unknown scale) and the planar rig with a height prior that needs the strengthening.
"""

import functools
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from rwhec_ros.core.certify.dense import CertificateOptions
from rwhec_ros.core.certify.multipliers import handedness_direction
from rwhec_ros.core.certify.sparse import (
    CertificatePattern,
    _certificate_at,
    _Dual,
    _handedness_matrix_y,
    _second_direction,
    certify_sparse,
    first_order_multipliers,
    handedness_entries,
    reduced_eigenvalues,
    sparse_dual_bound,
)
from rwhec_ros.core.local.sparse import refine_rotations_sparse, rotation_blocks
from rwhec_ros.core.model.gauge import GaugeOptions, TranslationPrior
from rwhec_ros.core.numerics.sparse_ldl import FactorizationError, SparseLDL
from rwhec_ros.core.numerics.verified import UNIT_ROUNDOFF, gamma
from rwhec_ros.core.pipeline.sparse import estimate_sparse, prepare_sparse
from rwhec_ros.core.result import Status
from rwhec_ros.core.solve import SolveOptions
from rwhec_ros.simulation.synthetic import random_instance

sys.path.insert(0, str(Path(__file__).parent))
from test_gauge import _planar_rig  # noqa: E402


@functools.cache
def _case(kind: str):
    """The prepared problem, its local optimum ``R``, pattern, direct cost ``p`` and the
    first-order dual point (``Gamma``, ``lambda_s``, ``z``) with ``Z_fl`` and ``E`` rows."""
    options = SolveOptions()
    if kind == "planar":  # planar motion with a height prior: needs the handedness step
        problem, _, Y = _planar_rig(np.random.default_rng(7), M=2, P=8, n=10, jitter=1e-6)
        prior = TranslationPrior("cam0", "z", float(Y[0, 2, 3]))
        options = SolveOptions(gauge=GaugeOptions(priors=(prior,)))
    else:
        kw = dict(unknown_scale=True, alpha=0.8) if kind == "unknown_scale" else {}
        problem, _ = random_instance(np.random.default_rng(4), 1, 5, n_per_edge=8, sigma=0.02,
                                     kappa=100, **kw)
    prep = prepare_sparse(problem, options)
    R = refine_rotations_sparse(prep.form, prep.Qs, prep.init_R).R
    pattern = CertificatePattern(prep.form, prep.Qs)
    _, p = estimate_sparse(prep, R)
    Gamma, lam_s, z = first_order_multipliers(prep.form, prep.Qs, R)
    data, err = pattern.matrix_data(Gamma, lam_s)
    return dict(prep=prep, R=R, pattern=pattern, p=p, Gamma=Gamma, lam_s=lam_s, z=z, data=data,
                err=err, homogeneous=problem.unknown_scale)


def _dual(c, opts=None, Gamma=None, lam_s=None):
    return _Dual(c["Gamma"] if Gamma is None else Gamma,
                 c["lam_s"] if lam_s is None else lam_s, c["z"], c["p"], c["prep"].scale,
                 c["homogeneous"], c["prep"].cost_floor, opts or CertificateOptions())


def _dense_Z(pattern, data):
    U = sp.csc_matrix((data, pattern.U.indices, pattern.U.indptr), shape=pattern.U.shape)
    U = U.toarray()
    return np.triu(U) + np.triu(U, 1).T


def _reduced(pattern, data):
    """The reduced certificate matrix ``Z_y - Z_yf Z_ff^{-1} Z_fy`` (dense)."""
    Z, nf = _dense_Z(pattern, data), pattern.nf
    return Z[nf:, nf:] - Z[nf:, :nf] @ np.linalg.solve(Z[:nf, :nf], Z[:nf, nf:])


def _mu0(pattern, data):
    """The first shift of the docstring: gamma_64 times the mean |Z_ii| over y (+ 1e-300)."""
    return gamma(64) * float(np.abs(data[pattern.diag[pattern.nf:]]).mean()) + 1e-300


def _factor(pattern, A):
    try:
        f = SparseLDL(sp.csc_matrix((A, pattern.U.indices, pattern.U.indptr),
                                    shape=pattern.U.shape))
    except FactorizationError:
        return None
    return f if f.positive_definite else None


def _reference_bound(pattern, data, err, lam_s, mu0, z):
    """The bound as the module docstring states it, with a fresh factorisation each time:
    ``delta`` starts at ``4 gamma_64 (|Q_s| 1)_free`` and is refit to ``1.25 c`` (then raised to
    it) after each positive definite factorisation until ``delta >= c`` on the free block;
    ``mu = max(floor, 1.5 delta . f^2 / |y|^2)`` with the floor grown 8-fold for the first 6
    failures, then 64-fold, for at most 16 factorisations; then
    ``d = lambda_s - ny mu (1 + gamma_2) - e_y - 4 u (|lambda_s| + ...)`` with
    ``c = (w + u |A_ii| + E 1)(1 + gamma_4)`` and ``e_y = min(sum c_y, ny max c_y)(1 + gamma_ny)``.
    Returns ``(value, lambda_min_lower, eigenvalue_term, rounding_term, mu, attempts, delta, c)``
    or ``None`` when no factorisation succeeds."""
    nf, diag = pattern.nf, pattern.diag
    ny = 9 * pattern.n + 1
    delta = 4.0 * gamma(64) * pattern.abs_rows_Q[:nf]
    mu_for = (lambda d: 0.0) if z is None else (
        lambda d: 1.5 * float(d @ z[:nf] ** 2) / float(z[nf:] @ z[nf:]))
    floor = mu0
    mu = max(floor, mu_for(delta))
    fitted = False
    for attempt in range(1, 17):
        A = data.copy()
        A[diag[:nf]] -= delta
        A[diag[nf:]] += mu
        f = _factor(pattern, A)
        if f is None:
            floor = mu * (8.0 if attempt <= 6 else 64.0)
            mu = max(floor, mu_for(delta))
            continue
        c = (f.backward_error_rows() + UNIT_ROUNDOFF * np.abs(A[diag]) + err) * (1.0 + gamma(4))
        if not fitted or np.any(c[:nf] > delta):
            delta = 1.25 * c[:nf] if not fitted else np.maximum(delta, 1.25 * c[:nf])
            fitted = True
            mu = max(floor, mu_for(delta))
            continue
        cy = c[nf:]
        e_y = min(cy.sum(), ny * cy.max()) * (1.0 + gamma(ny))
        eig = ny * mu * (1.0 + gamma(2))
        value = lam_s - eig - e_y
        value -= 4.0 * UNIT_ROUNDOFF * (abs(lam_s) + eig + e_y)
        return value, -(mu + cy.max()), eig, e_y, mu, attempt, delta, c
    return None


def _indefinite_rotation(c, eta=1e-2):
    """``Z_fl`` with ``eta`` subtracted from one rotation entry's diagonal: the reduced matrix
    gets an eigenvalue of about ``-eta`` (a dual point that is not optimal)."""
    bad = c["data"].copy()
    bad[c["pattern"].diag[c["pattern"].nf + 4]] -= eta
    return bad


# exact equality below: the test repeats the same floating-point operations in the same order
@pytest.mark.parametrize("variant", ["optimum", "negative_lambda_s", "small_lambda_s",
                                     "no_primal_point", "indefinite_rotation", "large_mu0"])
def test_bound_is_the_documented_formula(variant):
    c = _case("star")
    pattern, data, err, lam_s, z = c["pattern"], c["data"], c["err"], c["lam_s"], c["z"]
    mu0 = _mu0(pattern, data)
    if variant == "negative_lambda_s":  # only d depends on lambda_s: |lambda_s| in the rounding
        lam_s = -lam_s - 1.0
    elif variant == "small_lambda_s":  # d ~ 1e-11: the 4 u rounding of every term shows
        lam_s = 1e-10
    elif variant == "no_primal_point":  # no z: mu is the floor alone
        z = None
    elif variant == "indefinite_rotation":  # mu grows 8-fold 6 times, then 64-fold
        data, mu0 = _indefinite_rotation(c), 1e-14
    elif variant == "large_mu0":  # a start above what z asks for
        mu0 = 1e-6
    ref = _reference_bound(pattern, data, err, lam_s, mu0, z)
    assert ref is not None
    value, lower, eig, e_y, mu, attempts, delta, cc = ref
    sb = sparse_dual_bound(pattern, data, err, lam_s, mu0, z)
    b = sb.bound
    assert (b.value, b.lambda_min_lower, b.eigenvalue_term, b.rounding_term) == (
        value, lower, eig, e_y)
    assert b.schur_term == 0.0 and b.lambda_s == lam_s and b.reason == ""
    assert (sb.mu, sb.attempts) == (mu, attempts)
    assert sb.factor is not None and sb.factor.positive_definite
    # the theorem's premise holds at the returned factorisation: delta_i >= c_i on the free block
    assert np.all(delta >= cc[:pattern.nf])
    if variant == "indefinite_rotation":
        assert attempts > 8  # the 64-fold steps ran
        lam_min = np.linalg.eigvalsh(_reduced(pattern, data))[0]
        assert lam_min < -1e-4 and b.lambda_min_lower <= lam_min  # proven below the truth
    elif variant == "no_primal_point":  # mu0 alone is too small twice, then a refit
        assert attempts == 4 and mu == 64.0 * mu0
    else:
        assert attempts == 2  # one factorisation, one refit of delta, done
    if variant == "large_mu0":
        assert mu == mu0 and value < lam_s - (9 * pattern.n + 1) * 1e-6


def test_roundings_of_one_plus_gamma():
    """Why some constants of the bound are interchangeable (see benchmarks/mutation.py
    EQUIVALENT): 1 + gamma_1 = 1 + gamma_2 and 1 + gamma_3 = 1 + gamma_4 as doubles."""
    assert 1.0 + gamma(1) == 1.0 + gamma(2) == 1.0 + 2.0**-52
    assert 1.0 + gamma(3) == 1.0 + gamma(4) == 1.0 + 2.0**-51
    assert 1.0 + gamma(5) > 1.0 + gamma(4)


def test_no_bound_after_sixteen_factorisations():
    """A translation direction of negative curvature: every factorisation fails; after 16 the
    last ``mu`` tried is ``mu0 8^6 64^10`` (6 eight-fold, then 64-fold steps), no factor is kept
    and the bound is ``-inf`` with the reason."""
    c = _case("star")
    pattern, data = c["pattern"], c["data"].copy()
    data[pattern.diag[5]] -= 2.0 * np.linalg.eigvalsh(_dense_Z(pattern, data)[:pattern.nf,
                                                                               :pattern.nf])[-1]
    mu0 = 1e-14
    sb = sparse_dual_bound(pattern, data, c["err"], c["lam_s"], mu0, None)
    assert sb.attempts == 16 and sb.factor is None
    assert sb.mu == mu0 * 8.0**6 * 64.0**10  # powers of two: exact
    assert sb.bound.value == -np.inf and "no shifted factorisation" in sb.bound.reason
    # a non-finite Z: every factorisation raises; still no factor and no bound
    nan = np.full_like(data, np.nan)
    sb = sparse_dual_bound(pattern, nan, c["err"], c["lam_s"], mu0, None)
    assert sb.attempts == 16 and sb.factor is None and sb.bound.value == -np.inf


class _StubFactor:
    def __init__(self, owner):
        self.owner = owner

    positive_definite = True

    def backward_error_rows(self):
        self.owner.calls += 1
        return self.owner.bwd * 2.0**self.owner.calls  # the rounding doubles every time


class _StubPattern:
    """A 2 + 10 diagonal 'matrix' (nf = 2, one rotation): records the shifted data it is asked
    to factorise; positive definite when every y entry is at least ``need``."""

    nf, n, size = 2, 1, 12

    def __init__(self, need=0.0):
        self.diag = np.arange(12)
        self.abs_rows_Q = np.ones(12)
        self.bwd = np.full(12, 1e-10)
        self.calls, self.seen, self.need = 0, [], need

    def factorise(self, A, factor=None):
        self.seen.append(A.copy())
        return _StubFactor(self) if np.all(A[2:] >= self.need) else None


def test_refit_of_the_translation_shift_gives_up_after_four():
    """The free shift is refit to 1.25 c, then raised to max(delta, 1.25 c) while the rounding
    keeps exceeding it; the fifth shortfall gives up with the reason, keeping the last positive
    definite factor; mu follows 1.5 delta . f^2 / |y|^2 (z given)."""
    pat = _StubPattern()
    data = np.zeros(12)
    err = np.zeros(12)
    z = np.concatenate([[1.0, 2.0], np.full(10, 0.5)])
    sb = sparse_dual_bound(pat, data, err, 0.3, 1e-30, z)
    assert sb.attempts == 5 and sb.factor is not None
    assert "rounding of the translation block exceeds its shift" in sb.bound.reason
    assert sb.bound.value == -np.inf
    deltas = [-A[:2] for A in pat.seen]  # data is 0: A_free = -delta exactly
    assert np.array_equal(deltas[0], 4.0 * gamma(64) * np.ones(2))
    expected = None
    for k in range(1, 5):
        ck = (1e-10 * 2.0**k + UNIT_ROUNDOFF * np.abs(pat.seen[k - 1][:2])) * (1.0 + gamma(4))
        expected = 1.25 * ck if expected is None else np.maximum(expected, 1.25 * ck)
        assert np.array_equal(deltas[k], expected)
    for A, d in zip(pat.seen, deltas, strict=True):  # mu on the y block, from delta and z
        assert np.all(A[2:] == 1.5 * float(d @ z[:2] ** 2) / float(z[2:] @ z[2:]))


def test_mu_growth_without_a_primal_point():
    """z = None: mu is the floor alone, multiplied by 8 after each of the first 6 failures and
    by 64 after later ones, until the factorisation succeeds."""
    pat = _StubPattern(need=1e-3)
    pat.bwd = np.zeros(12)
    mu0 = 1e-14
    sb = sparse_dual_bound(pat, np.zeros(12), np.zeros(12), 0.3, mu0, None)
    mus = [float(A[2]) for A in pat.seen]
    expected = [mu0]
    while expected[-1] < 1e-3:
        expected.append(expected[-1] * (8.0 if len(expected) <= 6 else 64.0))
    expected.append(expected[-1])  # the refit of delta keeps mu (no z)
    assert mus == expected and sb.mu == expected[-1]
    assert sb.attempts == len(expected) and np.isfinite(sb.bound.value)
    # d = lambda_s - 10 mu (1 + gamma_2) - e_y - 4 u (...), c_y = u |A_ii| (1 + gamma_4) here
    cy = UNIT_ROUNDOFF * sb.mu * (1.0 + gamma(4))
    e_y = min(10 * cy, 10 * cy) * (1.0 + gamma(10))
    eig = 10 * sb.mu * (1.0 + gamma(2))
    d = 0.3 - eig - e_y
    d -= 4.0 * UNIT_ROUNDOFF * (0.3 + eig + e_y)
    assert sb.bound.value == pytest.approx(d, rel=1e-15, abs=0)  # the sum order of c_y
    assert sb.bound.lambda_min_lower == pytest.approx(-(sb.mu + cy), rel=1e-15, abs=0)


LANCZOS_TOL = 1e-8  # the ``tol`` reduced_eigenvalues asks ARPACK for


def _lanczos_error_bound(M, mu):
    """Per-eigenvalue bound on |estimate - eigvalsh| for shift-invert Lanczos on ``M``.

    Lanczos runs on ``OP = (M + mu I)^{-1}``; an eigenvalue ``lam`` of ``M`` is ``nu = 1 / (lam +
    mu)`` there, and an error ``dnu`` maps back to ``dlam = dnu (lam + mu)^2``. Three terms:

    * the requested ARPACK tolerance, relative on ``nu``: ``tol |lam + mu|``;
    * the rounding of the Krylov basis, absolute on ``nu`` at the scale of OP's largest
      eigenvalue ``nu_max = 1 / min |lam + mu|`` (~1e12: the null space): ``m eps nu_max`` with
      the usual factor ``m`` of a length-``m`` recurrence, i.e. ``m eps nu_max (lam + mu)^2``.
      This is what limits the non-null eigenvalues; scipy 1.11's ARPACK reaches ~0.2 of it
      (4e-3 relative on lam ~ 60), newer ones ~1e-10 of it;
    * the backward error of the factorisation OP is applied with, ``m eps ||M||``, which limits
      the (near-)null eigenvalues the status is decided on (~1e-12 here, measured 1e-12).
    """
    lam = np.linalg.eigvalsh(M)
    m = M.shape[0]
    eps = np.finfo(float).eps
    nu_max = 1.0 / np.abs(lam + mu).min()
    norm = np.abs(lam).max()
    bound = (LANCZOS_TOL * np.abs(lam + mu) + m * eps * nu_max * (lam + mu) ** 2
             + m * eps * norm)
    return lam, bound


def _assert_lanczos_eigenvalues(actual, M, mu):
    """Shift-invert Lanczos estimates (ascending) against ``eigvalsh`` of the dense matrix ``M``,
    each within the error bound of :func:`_lanczos_error_bound` of its own eigenvalue; the
    (near-)null ones additionally to 1e-9 absolute (the status is decided on them against
    ``null_tol``: the bound gives ~1e-11 there)."""
    actual = np.asarray(actual)
    lam, bound = _lanczos_error_bound(M, mu)
    lam, bound = lam[: actual.size], bound[: actual.size]
    err = np.abs(actual - lam)
    assert np.all(err <= bound), (
        f"Lanczos error beyond its bound at {np.flatnonzero(err > bound)}: "
        f"err {err[err > bound]}, bound {bound[err > bound]}")
    near = np.abs(lam) < 1e-3
    np.testing.assert_allclose(actual[near], lam[near], rtol=0, atol=1e-9)
    return lam


@pytest.mark.parametrize("kind", ["star", "unknown_scale"])
def test_reduced_eigenvalues_against_eigvalsh(kind):
    """Shift-invert Lanczos with the bound's factorisation against the dense reduced matrix
    (on y, and on the rotations only); asking for more eigenvalues than the size allows gives
    m - 1 of them; the vectors are eigenvectors. Tolerances: see _lanczos_error_bound."""
    c = _case(kind)
    pattern, data, nf, n = c["pattern"], c["data"], c["pattern"].nf, c["pattern"].n
    sb = sparse_dual_bound(pattern, data, c["err"], c["lam_s"], _mu0(pattern, data), c["z"])
    Zr = _reduced(pattern, data)
    w = reduced_eigenvalues(sb.factor, sb.mu, nf, n, 4, False)
    assert isinstance(w, np.ndarray) and w.shape == (4,)
    _assert_lanczos_eigenvalues(w, Zr, sb.mu)
    w_r, V = reduced_eigenvalues(sb.factor, sb.mu, nf, n, 4, True, vectors=True)
    # on the rotations only: s eliminated as well (its Schur complement)
    Zrr = Zr[:-1, :-1] - np.outer(Zr[:-1, -1], Zr[-1, :-1]) / Zr[-1, -1]
    lam_r = _assert_lanczos_eigenvalues(w_r, Zrr, sb.mu)
    # the vectors: orthonormal, and Ritz pairs of Zrr: for a unit v and r = Zrr v - w v, an
    # eigenvalue of the symmetric Zrr lies within |r| of w (Bauer-Fike); ordered as eigvalsh
    np.testing.assert_allclose(V.T @ V, np.eye(V.shape[1]), atol=1e-8)
    res = np.linalg.norm(Zrr @ V - V * w_r, axis=0)
    assert np.all(np.abs(w_r - lam_r) <= res + 1e-12)
    assert res[0] < 1e-7  # the null direction: as accurate as its eigenvalue (1e-9)
    # the others: the residual of OP's Ritz pair, |M + mu| (tol + m eps nu_max (lam + mu))
    # (the error model of _lanczos_error_bound, carried to the residual in M)
    _, b = _lanczos_error_bound(Zrr, sb.mu)
    nu_max = 1.0 / np.abs(np.linalg.eigvalsh(Zrr) + sb.mu).min()
    norm = np.abs(np.linalg.eigvalsh(Zrr)).max() + sb.mu
    res_bound = norm * (LANCZOS_TOL + Zrr.shape[0] * np.finfo(float).eps * nu_max
                        * np.abs(lam_r + sb.mu))
    assert np.all(res[1:] <= res_bound[1:]), (res, res_bound)
    all_w = reduced_eigenvalues(sb.factor, sb.mu, nf, n, 1000, False)
    assert all_w.shape == (9 * n,)  # m - 1 = 9 n of the m = 9 n + 1
    _assert_lanczos_eigenvalues(all_w, Zr, sb.mu)


def test_certificate_with_default_arguments_matches_the_dense_reference():
    """certify_sparse with its defaults (known scale, cost floor 0, default options) on the star:
    certified without strengthening; d = scale times the documented bound; rho_hat = (p - d) / d;
    the eigenvalues those of the dense reduced matrix."""
    c = _case("star")
    pattern = c["pattern"]
    cert, strengthened = certify_sparse(c["prep"].form, c["prep"].Qs, pattern, c["R"], c["p"],
                                        c["prep"].scale)
    assert cert.status is Status.CERTIFIED_OPTIMAL and not strengthened, cert.message
    ref = _reference_bound(pattern, c["data"], c["err"], c["lam_s"], _mu0(pattern, c["data"]),
                           c["z"])
    d = ref[0] * c["prep"].scale
    assert cert.dual_bound == d and cert.lambda_min_lower == ref[1]
    assert cert.suboptimality_bound == (c["p"] - d) / d
    assert cert.null_space_dim == 1 and cert.tolerance == 1e-6
    assert "sign of s" not in cert.message
    # the same problem with the cost in other units (times 1e-4, so d < 1): no floor by default,
    # rho_hat = (p - d) / d again
    k = 1e-4
    cert_k, _ = certify_sparse(c["prep"].form, c["prep"].Qs, pattern, c["R"], k * c["p"],
                               k * c["prep"].scale)
    d_k = ref[0] * (k * c["prep"].scale)
    assert cert_k.dual_bound == d_k < 1.0
    assert cert_k.suboptimality_bound == (k * c["p"] - d_k) / d_k
    # the Lanczos accuracy (_assert_lanczos_eigenvalues), at the shift of the bound's factor
    mu = sparse_dual_bound(pattern, c["data"], c["err"], c["lam_s"], _mu0(pattern, c["data"]),
                           c["z"]).mu
    _assert_lanczos_eigenvalues(cert.eigenvalues, _reduced(pattern, c["data"]), mu)


def test_unknown_scale_sets_the_trivial_s_aside():
    """Homogeneous problem: s is decoupled, its eigenvalue Z_ss (~0) is set aside as the free
    sign of s; the null space is one-dimensional on the rotations; certified with no
    strengthening; the eigenvalues are those of the dense reduced matrix (Z_ss among them)."""
    c = _case("unknown_scale")
    pattern = c["pattern"]
    cert, strengthened = certify_sparse(c["prep"].form, c["prep"].Qs, pattern, c["R"], c["p"],
                                        c["prep"].scale, homogeneous=True,
                                        cost_floor=c["prep"].cost_floor)
    assert cert.status is Status.CERTIFIED_OPTIMAL and not strengthened, cert.message
    assert cert.null_space_dim == 1 and "sign of s" in cert.message
    Zr = _reduced(pattern, c["data"])
    assert np.abs(Zr[-1, :-1]).max() < 1e-12 * np.abs(Zr).max()  # s decoupled (rounding)
    mu = sparse_dual_bound(pattern, c["data"], c["err"], c["lam_s"], _mu0(pattern, c["data"]),
                           c["z"]).mu
    _assert_lanczos_eigenvalues(cert.eigenvalues, Zr, mu)
    z_ss = c["data"][pattern.diag[-1]]
    assert abs(z_ss) < 1e-12 and np.min(np.abs(cert.eigenvalues - z_ss)) == 0.0
    # the estimate direction v2: unit, orthogonal to y, zero on s
    _, v2 = _certificate_at(pattern, _dual(c))
    y = c["z"][pattern.nf:]
    assert v2[-1] == 0.0 and abs(np.linalg.norm(v2) - 1.0) < 1e-12 and abs(v2 @ y) < 1e-9


def test_a_negative_s_eigenvalue_is_not_set_aside():
    """Homogeneous, but lambda_s raised by 1e-3 so that Z_ss = -1e-3 (< -null_tol): the s
    direction counts in the null space (2) and the bound drops by at least ny 1e-3."""
    c = _case("unknown_scale")
    pattern = c["pattern"]
    cert, _ = _certificate_at(pattern, _dual(c, lam_s=c["lam_s"] + 1e-3))
    assert cert.status is Status.NOT_TIGHT
    assert cert.null_space_dim == 2
    # Z_ss = -1e-3 + (its ~1e-15 value at the optimum): rel 1e-9 is ample
    assert cert.eigenvalues[0] == pytest.approx(-1e-3, rel=1e-9, abs=0)
    ny = 9 * pattern.n + 1
    assert cert.dual_bound < (c["lam_s"] + 1e-3 - ny * 1e-3) * c["prep"].scale


@pytest.mark.parametrize("kind", ["star", "unknown_scale"])
def test_null_tol_exactly_at_an_eigenvalue_counts_it(kind):
    """An eigenvalue equal to null_tol is in the numerical null space (``<=``, as the dense
    certificate): null_tol set to the second eigenvalue gives a two-dimensional null space (not
    certified); for the homogeneous problem, null_tol = |Z_ss| still sets s aside."""
    c = _case(kind)
    pattern = c["pattern"]
    base, _ = _certificate_at(pattern, _dual(c))
    w_rot = base.eigenvalues[base.eigenvalues != c["data"][pattern.diag[-1]]]
    opts = CertificateOptions(null_tol=float(w_rot[1]))
    cert, _ = _certificate_at(pattern, _dual(c, opts))
    assert cert.null_space_dim == 2 and cert.status is Status.NOT_TIGHT
    if kind == "unknown_scale":
        z_ss = abs(float(c["data"][pattern.diag[-1]]))
        cert, _ = _certificate_at(pattern, _dual(c, CertificateOptions(null_tol=z_ss)))
        assert "sign of s" in cert.message and cert.null_space_dim == 1
        assert cert.status is Status.CERTIFIED_OPTIMAL


def test_options_are_honoured():
    """A user's tolerances and eigenvalue count are used (not the defaults)."""
    c = _case("star")
    opts = CertificateOptions(rho_tol=1e-12, n_eigenvalues=3)
    cert, strengthened = certify_sparse(c["prep"].form, c["prep"].Qs, c["pattern"], c["R"],
                                        c["p"], c["prep"].scale, options=opts)
    assert cert.status is Status.NOT_TIGHT and cert.tolerance == 1e-12 and not strengthened
    assert "rho_hat" in cert.message and cert.eigenvalues.shape == (3,)


def test_no_finite_dual_point():
    """A non-finite direct cost: solver_failed, nothing estimated, no strengthening."""
    c = _case("star")
    cert, strengthened = certify_sparse(c["prep"].form, c["prep"].Qs, c["pattern"], c["R"],
                                        float("nan"), c["prep"].scale)
    assert cert.status is Status.SOLVER_FAILED and not strengthened
    assert cert.message == "no finite dual point" and cert.null_space_dim == -1
    assert cert.eigenvalues.shape == (0,) and cert.tolerance == 1e-6
    assert np.isnan(cert.dual_bound) and np.isnan(cert.suboptimality_bound)


def test_no_bound_is_ill_conditioned():
    """Non-finite multipliers reaching the bound: no factorisation, so no bound and no
    eigenvalue estimate: ill_conditioned with null space dimension -1 (unknown)."""
    c = _case("star")
    Gamma = c["Gamma"].copy()
    Gamma[0, 0, 0] = np.nan
    cert, v2 = _certificate_at(c["pattern"], _dual(c, Gamma=Gamma))
    assert v2 is None and cert.status is Status.ILL_CONDITIONED
    assert cert.null_space_dim == -1 and np.isnan(cert.lambda_min)
    assert "no rigorous dual bound" in cert.message


def test_second_direction():
    """The unit vector in span(V[:, :2]) orthogonal to y (up to sign); when y is orthogonal to
    that span, V[:, 1] (any unit vector of the span would do)."""
    V, _ = np.linalg.qr(np.random.default_rng(0).standard_normal((7, 3)))
    y = 3.0 * (0.8 * V[:, 0] + 0.5 * V[:, 1] + 0.3 * V[:, 2])
    v = _second_direction(V, y)
    assert abs(np.linalg.norm(v) - 1.0) < 1e-14 and abs(v @ y) < 1e-14  # rounding only
    coef = V.T @ v
    assert abs(coef[2]) < 1e-14 and abs(abs(coef[0]) - 0.5 / np.hypot(0.8, 0.5)) < 1e-14
    E = np.eye(7)[:, [4, 1, 6]]  # exact zeros: y has no component in span(E[:, :2])
    assert np.array_equal(_second_direction(E, 2.0 * E[:, 2]), E[:, 1])


def test_handedness_matrix_on_y_is_the_dense_direction():
    """The sparse handedness direction D on y = [vec R; s] equals the dense matrix of
    handedness_multipliers over the SO(3) constraint matrices, and D y = 0 at the rotations."""
    c = _case("star")
    R, n = c["R"], c["R"].shape[0]
    vals, absv = handedness_entries(R)
    D = _handedness_matrix_y(vals, n).toarray()
    Dd = handedness_direction(R)
    # the same sums in another order: each entry is a sum of at most 9 terms, so the two differ
    # by at most 2 gamma_9 times the sum of the terms' absolute values (absv), entrywise
    A = _handedness_matrix_y(absv, n).toarray()
    assert np.all(np.abs(D - Dd) <= 2.0 * gamma(9) * np.abs(A))
    y = c["z"][c["pattern"].nf:]
    assert np.abs(D @ y).max() < 1e-12  # D z = 0 (rounding of the rotations)
    assert np.all(absv >= np.abs(vals)) and np.any(absv > 0)


def test_first_order_multipliers_against_dense():
    """Gamma_l = sym(R_l^T G_l) with G the rotation blocks of Q_s z, exactly symmetric, and
    lambda_s = z^T Q_s z."""
    c = _case("star")
    form, Qs, R = c["prep"].form, c["prep"].Qs, c["R"]
    Gamma, lam_s, z = first_order_multipliers(form, Qs, R)
    G = rotation_blocks(Qs.toarray() @ z, form.n_free, form.n)
    RtG = np.einsum("lba,lbc->lac", R, G)
    np.testing.assert_allclose(Gamma, 0.5 * (RtG + np.swapaxes(RtG, 1, 2)), rtol=0,
                               atol=1e-12 * np.abs(RtG).max())  # another summation order
    assert np.array_equal(Gamma, np.swapaxes(Gamma, 1, 2))
    # a quadratic form in two summation orders: each within gamma_m |z|^T |Q_s| |z| of the exact
    # value (m = the terms of a row plus the outer sum; the form is ~2e4 times smaller than that
    # at the optimum, so a relative tolerance would be one machine's rounding)
    Q = Qs.toarray()
    bound = 2.0 * gamma(2 * Q.shape[0]) * (np.abs(z) @ (np.abs(Q) @ np.abs(z)))
    assert abs(lam_s - z @ (Q @ z)) <= bound


def test_matrix_data_ignores_the_direction_at_t_zero_and_counts_lambda_s_magnitude():
    """t = 0 with a direction given is the plain matrix (data and rounding rows); a negative
    lambda_s adds gamma_{3n+1} |lambda_s| to the s row of E."""
    c = _case("star")
    pattern, Gamma, lam_s = c["pattern"], c["Gamma"], c["lam_s"]
    hand = handedness_entries(c["R"])
    d0, e0 = pattern.matrix_data(Gamma, lam_s)
    d1, e1 = pattern.matrix_data(Gamma, lam_s, 0.0, hand)
    assert np.array_equal(d0, d1) and np.array_equal(e0, e1)
    n = pattern.n
    # s row: gamma_2 (|Q_s| 1 + |lambda_s - tr|) + gamma_{3n+1} (|lambda_s| + sum |diag Gamma|)
    # (the optimum's Gamma has a positive diagonal: also its negative, and both signs of
    # lambda_s)
    for G in (Gamma, -Gamma):
        assert np.any(np.diagonal(G, axis1=1, axis2=2) < 0) or G is Gamma
        tr = float(np.trace(G, axis1=1, axis2=2).sum())
        dg = float(np.abs(np.diagonal(G, axis1=1, axis2=2)).sum())
        for ls in (2.0, -2.0):
            _, e = pattern.matrix_data(G, ls)
            want = gamma(2) * (pattern.abs_rows_Q[-1] + abs(ls - tr)) + gamma(3 * n + 1) * (
                abs(ls) + dg)
            assert e[-1] == pytest.approx(want, rel=1e-14, abs=0)  # summation order only


def _replay_strengthening(c, v2):
    """The documented search of _strengthen replayed with dense linear algebra: t from
    -sign(s) 2 null_tol / |s| (s = v2^T D v2, D dense), times 4 while |t| <= max|Z| / max|D|;
    a t passes when Z(t) - Diag(delta, null_tol) has exactly one negative eigenvalue; the
    passing t are tried from the middle (in log |t|) out. Returns the passing t in that order."""
    pattern, R, null_tol = c["pattern"], c["R"], 1e-6
    nf = pattern.nf
    hand = handedness_entries(R)
    slope = float(v2 @ handedness_direction(R) @ v2)
    t_max = float(np.abs(c["data"]).max()) / float(np.abs(hand[0]).max())
    t = -np.sign(slope) * 2.0 * null_tol / abs(slope)
    delta = 4.0 * gamma(64) * pattern.abs_rows_Q[:nf]
    passed = []
    while abs(t) <= t_max:
        data, _ = pattern.matrix_data(c["Gamma"], c["lam_s"], t, hand)
        data[pattern.diag[:nf]] -= delta
        data[pattern.diag[nf:]] -= null_tol
        below = int(np.sum(np.linalg.eigvalsh(_dense_Z(pattern, data)) < 0.0))
        if below == 1:
            passed.append(t)
        elif passed:
            break
        t *= 4.0
    mid = np.mean(np.log(np.abs(passed)))
    return sorted(passed, key=lambda x: abs(np.log(abs(x)) - mid)), hand


def test_strengthening_matches_its_dense_replay():
    """Planar motion: the first-order certificate has a second null direction (not tight); the
    strengthened one is certified, equals the certificate at the first certified t of the
    replayed search, and at that t the dense reduced matrix has one eigenvalue <= null_tol."""
    c = _case("planar")
    pattern = c["pattern"]
    dual = _dual(c)
    plain, v2 = _certificate_at(pattern, dual)
    assert plain.status is Status.NOT_TIGHT and plain.null_space_dim == 2
    cert, strengthened = certify_sparse(c["prep"].form, c["prep"].Qs, pattern, c["R"], c["p"],
                                        c["prep"].scale, cost_floor=c["prep"].cost_floor)
    assert strengthened and cert.status is Status.CERTIFIED_OPTIMAL, cert.message
    order, hand = _replay_strengthening(c, v2)
    assert len(order) >= 3  # the ordering matters
    chosen = None
    for t in order:
        ref, _ = _certificate_at(pattern, dual, t, hand)
        if ref.certified:
            chosen = t
            break
    assert chosen is not None
    assert cert.dual_bound == ref.dual_bound and cert.lambda_min_lower == ref.lambda_min_lower
    data, _ = pattern.matrix_data(c["Gamma"], c["lam_s"], chosen, hand)
    w = np.linalg.eigvalsh(_reduced(pattern, data))
    assert np.sum(w <= 1e-6) == 1 and cert.dual_bound <= cert.primal_cost
    # without strengthening: the plain certificate, not strengthened
    cert0, s0 = certify_sparse(c["prep"].form, c["prep"].Qs, pattern, c["R"], c["p"],
                               c["prep"].scale, cost_floor=c["prep"].cost_floor,
                               strengthen=False)
    assert not s0 and cert0.status is Status.NOT_TIGHT and cert0.dual_bound == plain.dual_bound


def test_first_shift_is_gamma64_times_the_mean_y_diagonal():
    """At a dual point whose primal translations are zero (so z asks for no shift), the bound
    starts from mu0 = gamma_64 mean |Z_ii| over y (+ 1e-300), as documented: the certificate's
    bound equals the reference bound from that start."""
    c = _case("star")
    pattern, nf = c["pattern"], c["pattern"].nf
    z0 = c["z"].copy()
    z0[:nf] = 0.0
    dual = _Dual(c["Gamma"], c["lam_s"], z0, c["p"], c["prep"].scale, False,
                 c["prep"].cost_floor, CertificateOptions())
    cert, _ = _certificate_at(pattern, dual)
    mu0 = _mu0(pattern, c["data"])
    ref = _reference_bound(pattern, c["data"], c["err"], c["lam_s"], mu0, z0)
    assert ref[4] / mu0 in (1.0, 8.0, 64.0)  # mu is mu0 or a few 8-fold steps of it
    assert cert.dual_bound == ref[0] * c["prep"].scale
    assert cert.lambda_min_lower == ref[1]


def test_strengthening_in_a_lowering_direction_certifies_nothing():
    """A direction u (orthogonal to y) with u^T D u > 0 makes the search step t < 0, which
    lowers the planar rig's second null direction (its v2^T D v2 < 0): no t leaves a single
    eigenvalue below null_tol; the search stops at |t| > t_max and returns None."""
    from rwhec_ros.core.certify.sparse import _strengthen

    c = _case("planar")
    pattern = c["pattern"]
    y = c["z"][pattern.nf:] / np.linalg.norm(c["z"][pattern.nf:])
    D = handedness_direction(c["R"])
    P = np.eye(len(y)) - np.outer(y, y)
    w, V = np.linalg.eigh(P @ D @ P)
    u = V[:, -1]
    assert w[-1] > 0 and abs(u @ y) < 1e-12
    _, v2 = _certificate_at(pattern, _dual(c))
    assert v2 @ D @ v2 < 0
    assert _strengthen(pattern, _dual(c), c["R"], u) is None


def test_a_failed_probe_factorisation_is_not_a_pass(monkeypatch):
    """The screen counts negative pivots; a probe whose factorisation breaks down proves nothing
    and must not count as 'one eigenvalue below null_tol': no certificate is attempted."""
    import rwhec_ros.core.certify.sparse as sc

    c = _case("planar")
    pattern = c["pattern"]
    _, v2 = _certificate_at(pattern, _dual(c))
    attempted = []
    monkeypatch.setattr(sc, "_certificate_at", lambda *a, **k: attempted.append(a[2]))
    monkeypatch.setattr(pattern, "factorise", lambda data, factor=None: None)
    assert sc._strengthen(pattern, _dual(c), c["R"], v2) is None and attempted == []

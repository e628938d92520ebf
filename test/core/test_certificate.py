"""The certification function on crafted certificate matrices with known answers.

``Z = V diag(w) V^T`` with a random orthogonal ``V`` and chosen eigenvalues ``w``; scale 1, an
exact reduction (no translations), ``lambda_s = 1``. Each test pins one decision of
:func:`rwhec_ros.core.certify.dense.certify_from_Z` (the tolerances, the dual bound of eq. (71), the
solver-status and non-finite paths) so that changing it makes a test fail.
"""

import numpy as np
import pytest

from rwhec_ros.core.certify.dense import (
    CertificateOptions,
    DualBound,
    ExactReduction,
    certificate_from_bound,
    certificate_matrix,
    certify,
    certify_from_Z,
    rigorous_dual_bound,
)
from rwhec_ros.core.certify.multipliers import (
    fast_certificate_matrix,
    fast_certificate_multipliers,
    handedness_direction,
    handedness_multipliers,
)
from rwhec_ros.core.certify.relaxation import so3_constraint_matrices
from rwhec_ros.core.local.dense import refine_rotations
from rwhec_ros.core.model.cost import StateLayout, build_cost_matrices
from rwhec_ros.core.model.reduction import reduce_cost
from rwhec_ros.core.numerics.verified import gamma
from rwhec_ros.core.result import Status
from rwhec_ros.simulation.synthetic import random_instance, random_rotations

N_ROT = 2  # two rotations: Z is 19 x 19 and |y|^2 = 3 n + 1 = 7
D = 9 * N_ROT + 1


def _crafted(w, seed=0):
    rng = np.random.default_rng(seed)
    V, _ = np.linalg.qr(rng.standard_normal((len(w), len(w))))
    Z = V @ np.diag(w) @ V.T
    return 0.5 * (Z + Z.T)


def _spectrum(*smallest):
    w = np.linspace(0.05, 1.0, D)
    w[: len(smallest)] = smallest
    return w


def _cert(w, p=1.0, lambda_s=1.0, **kw):
    return certify_from_Z(_crafted(w), lambda_s, p, 1.0, N_ROT, **kw)


def test_clear_gap_is_certified():
    c = _cert(_spectrum(0.0))
    assert c.status is Status.CERTIFIED_OPTIMAL, c.message
    assert "sign of s" not in c.message  # a known-scale problem has no free sign of s
    assert c.null_space_dim == 1
    assert abs(c.suboptimality_bound) < 1e-12


def test_negative_eigenvalue_with_small_gap_is_not_certified():
    """lambda_min = -1e-3 < 0 and no second null direction: the bound lambda_s + 7 lambda_min
    leaves rho_hat ~7e-3 (the suboptimality test alone decides)."""
    c = _cert(_spectrum(-1e-3))
    assert c.null_space_dim == 1
    assert c.status is Status.NOT_TIGHT
    assert c.suboptimality_bound == pytest.approx(7e-3 / (1 - 7e-3), rel=1e-6)


def test_second_eigenvalue_above_null_tol_is_certified():
    """A second eigenvalue of 1e-5 is above null_tol = 1e-6 (a 100x looser null_tol would count
    it and refuse the certificate)."""
    c = _cert(_spectrum(0.0, 1e-5))
    assert c.status is Status.CERTIFIED_OPTIMAL, c.message


def test_second_eigenvalue_below_null_tol_is_not_certified():
    """A second eigenvalue of 5e-8 <= null_tol: two null directions, not certified (a 100x tighter
    null_tol would miss it)."""
    c = _cert(_spectrum(0.0, 5e-8))
    assert c.null_space_dim == 2
    assert c.status is Status.NOT_TIGHT


def test_tiny_positive_smallest_eigenvalue_still_certified():
    c = _cert(_spectrum(1e-7))
    assert c.status is Status.CERTIFIED_OPTIMAL, c.message
    assert c.null_space_dim == 1


@pytest.mark.parametrize("rho,certified", [(0.5e-6, True), (2e-6, False)])
def test_rho_hat_just_below_and_above_tolerance(rho, certified):
    """p = d (1 + rho): certified iff rho <= rho_tol = 1e-6 (100x looser/tighter flips one)."""
    c = _cert(_spectrum(0.0), p=1.0 + rho)
    assert c.suboptimality_bound == pytest.approx(rho, rel=1e-3)
    assert c.certified is certified


def test_dual_bound_is_eq_71_to_machine_precision():
    """With lambda_min < 0 the bound is lambda_s + (3 n + 1) lambda_min (eq. (71) with the norm of
    a feasible point), lowered only by the verified-eigenvalue margin (~1e-15 here)."""
    lam_min = -3e-4
    lambda_s = 2.5
    c = _cert(_spectrum(lam_min), p=2.6, lambda_s=lambda_s)
    eq71 = lambda_s + (3 * N_ROT + 1) * lam_min
    assert c.dual_bound <= eq71
    assert c.dual_bound == pytest.approx(eq71, abs=1e-12)
    assert c.lambda_min == pytest.approx(lam_min, abs=1e-14)
    assert c.lambda_min_lower <= lam_min


def test_positive_lambda_min_does_not_raise_the_bound():
    """min(0, lambda_min): a positive smallest eigenvalue must not increase d above lambda_s."""
    c = _cert(_spectrum(0.2), p=1.0, lambda_s=1.0)
    assert c.dual_bound <= 1.0
    assert c.dual_bound == pytest.approx(1.0, abs=1e-12)


def test_scale_multiplies_the_bound():
    c = certify_from_Z(_crafted(_spectrum(0.0)), 1.0, 50.0, 50.0, N_ROT)
    assert c.dual_bound == pytest.approx(50.0, rel=1e-12)
    assert c.certified


def test_cost_floor_is_the_denominator_for_zero_cost():
    """Noise-free data: d = p = 0; rho_hat = (p - d) / max(d, floor) stays finite."""
    c = certify_from_Z(_crafted(_spectrum(0.0)), 0.0, 1e-12, 1.0, N_ROT, cost_floor=1e-3)
    assert np.isfinite(c.suboptimality_bound) and c.certified


@pytest.mark.parametrize("status", ["optimal_inaccurate", "max_iterations", "infeasible"])
def test_solver_status_other_than_optimal_is_inaccurate(status):
    c = _cert(_spectrum(0.0), solver_ok=False, solver_status=status)
    assert c.status is Status.SOLVER_INACCURATE
    assert status in c.message
    assert np.isfinite(c.dual_bound)  # the numbers are still reported


def test_nan_multipliers_are_solver_failed():
    c = certify_from_Z(_crafted(_spectrum(0.0)), float("nan"), 1.0, 1.0, N_ROT)
    assert c.status is Status.SOLVER_FAILED
    # no eigenvalues were computed: none reported, and the null-space dimension is the -1 flag
    assert c.eigenvalues.size == 0 and c.null_space_dim == -1
    assert c.tolerance == CertificateOptions().rho_tol
    Z = _crafted(_spectrum(0.0))
    Z[0, 1] = Z[1, 0] = np.inf
    assert certify_from_Z(Z, 1.0, 1.0, 1.0, N_ROT).status is Status.SOLVER_FAILED


def test_non_default_tolerances_are_honoured():
    loose = CertificateOptions(rho_tol=1e-2)
    assert _cert(_spectrum(0.0), p=1.001, options=loose).certified
    assert not _cert(_spectrum(0.0), p=1.001).certified
    wide = CertificateOptions(null_tol=1e-3)
    c = _cert(_spectrum(0.0, 1e-4), options=wide)
    assert c.null_space_dim == 2 and not c.certified
    few = CertificateOptions(n_eigenvalues=3)
    assert len(_cert(_spectrum(0.0), options=few).eigenvalues) == 3


@pytest.mark.parametrize("field,value", [("rho_tol", 0.0), ("null_tol", -1.0),
                                         ("rho_tol", float("nan")), ("n_eigenvalues", 1)])
def test_bad_options_are_refused(field, value):
    with pytest.raises(ValueError, match=field):
        CertificateOptions(**{field: value})


def test_unverifiable_reduction_is_ill_conditioned():
    c = _cert(_spectrum(0.0), reduced=ExactReduction(D, verified=False))
    assert c.status is Status.ILL_CONDITIONED
    assert "translation block" in c.message


def test_no_shifted_factorisation_gives_no_bound():
    """The branch of rigorous_dual_bound where every shifted Cholesky factorisation of Z fails:
    an estimate of lambda_min above the whole spectrum (1.0 for the spectrum 0.05..1, of an
    eigensolver that went wrong) puts every shift mu = estimate - gap (the gap grows from
    gamma_{n+1} max|Z_ii| ~ 1e-15 to ~1e-8 in 8 attempts) above lambda_max, so fl(Z - mu I) is
    negative definite and no factorisation succeeds, deterministically on any machine. No bound:
    -inf, with the reason."""
    Z = _crafted(_spectrum(0.05))
    b = rigorous_dual_bound(Z, np.zeros(D), 1.0, ExactReduction(D), 1.0, N_ROT, 1.0 + 1e-3)
    assert b.value == float("-inf") and b.lambda_min_lower == float("-inf")
    assert b.reason == "no shifted factorisation of Z succeeded"
    # the same Z with a right estimate is bounded (the failure is the factorisation's alone)
    ok = rigorous_dual_bound(Z, np.zeros(D), 1.0, ExactReduction(D), 1.0, N_ROT, 0.05)
    assert np.isfinite(ok.value) and ok.reason == ""


def test_no_shifted_factorisation_is_not_certified(monkeypatch):
    """Through certify_from_Z: when the eigenvalue estimate it factorises Z against is wrong
    (above the spectrum), no shifted factorisation succeeds and the status is ill-conditioned
    with that reason, never certified (the data are otherwise a clear certificate)."""
    import rwhec_ros.core.certify.dense as certificate

    def estimate_above_spectrum(Z, k):
        return np.full(k, float(np.linalg.eigvalsh(Z)[-1]) + 1e-3)

    assert _cert(_spectrum(0.0)).status is Status.CERTIFIED_OPTIMAL
    monkeypatch.setattr(certificate, "smallest_eigenvalues", estimate_above_spectrum)
    c = _cert(_spectrum(0.0))
    assert c.status is Status.ILL_CONDITIONED
    assert "no shifted factorisation of Z succeeded" in c.message
    assert c.dual_bound == float("-inf")


def test_schur_residual_lowers_the_bound():
    """||F||^2 / l_e times |y|^2 = 7 is subtracted: residual 1e-3, block bound 1 -> 7e-6."""
    red = ExactReduction(D, residual_norm=1e-3, block_lower=1.0)
    c = _cert(_spectrum(0.0), reduced=red)
    assert c.dual_bound == pytest.approx(1.0 - 7e-6, abs=1e-12)
    assert not c.certified  # rho_hat 7e-6 > 1e-6


def test_rounding_rows_lower_the_bound():
    """The rounding bound enters as min(sum of rows, |y|^2 * largest row sum)."""
    rows = np.zeros(D)
    rows[3] = 1e-7
    c = _cert(_spectrum(0.0), z_err_rows=rows)
    assert 1.0 - 1e-6 < c.dual_bound < 1.0 - 1e-7 + 1e-12


def test_homogeneous_trivial_s_judged_on_rotations():
    """Unknown scale: Z has a zero last row/column (e_s a trivial null vector); uniqueness is
    judged on the rotation block, which has one null direction -> certified."""
    w = _spectrum(0.0)[:-1]
    Zr = _crafted(w)
    Z = np.zeros((D, D))
    Z[:-1, :-1] = Zr
    c = certify_from_Z(Z, 1.0, 1.0, 1.0, N_ROT, homogeneous=True)
    assert c.certified, c.message
    assert "sign of s" in c.message
    c2 = certify_from_Z(Z, 1.0, 1.0, 1.0, N_ROT, homogeneous=False)
    assert c2.null_space_dim == 2 and not c2.certified


def test_mid_size_z_takes_the_index_range_path():
    """A 301 x 301 Z (33 rotations + s) runs the index-range eigensolve in the certificate."""
    n = 33
    d = 9 * n + 1
    w = np.linspace(0.05, 1.0, d)
    w[0] = 0.0
    c = certify_from_Z(_crafted(w, seed=1), 1.0, 1.0, 1.0, n)
    assert c.certified, c.message
    w[1] = -1e-4
    c = certify_from_Z(_crafted(w, seed=1), 1.0, 1.0, 1.0, n)
    assert not c.certified


def test_fast_multipliers_reproduce_the_fast_certificate_matrix():
    """K(lambda) of the fast multipliers is Diag(Gamma_l (x) I, lambda_s - sum tr Gamma_l): the
    constraint-set form and the closed form agree, and Z z = 0 at a critical point."""
    rng = np.random.default_rng(4)
    problem, gt = random_instance(rng, 2, 1, n_per_edge=12, sigma=0.01, kappa=200)
    layout = StateLayout(problem.M, problem.P)
    Q, _ = build_cost_matrices(problem)
    red = reduce_cost(Q, layout, False)
    Qs = red.Qr / 100.0
    R = random_rotations(rng, 3)
    n = 3
    cons = so3_constraint_matrices(np.arange(n) * 9, 9 * n + 1, 9 * n)
    lam = fast_certificate_multipliers(Qs, R)
    Z1, _ = certificate_matrix(Qs, cons, lam)
    Z2, lam_s = fast_certificate_matrix(Qs, R)
    np.testing.assert_allclose(Z1, Z2, atol=1e-12 * np.abs(Qs).max())
    assert lam[-1] == pytest.approx(lam_s)
    hm = handedness_multipliers(R)
    D_ = cons.apply(hm)
    # the same matrix assembled in another order: each entry a sum of at most max_terms terms,
    # so the two are within 2 gamma_{max_terms} of the sum of the terms' absolute values
    absD = np.asarray(cons.abs_C @ np.abs(hm)).reshape(cons.d, cons.d, order="F")
    assert np.all(np.abs(D_ - handedness_direction(R)) <= 2.0 * gamma(cons.max_terms) * absD)
    z = np.concatenate([np.swapaxes(R, 1, 2).reshape(-1), [1.0]])
    np.testing.assert_allclose(D_ @ z, 0.0, atol=1e-12)  # the handedness direction keeps Z z


def test_symmetrisation_and_subtraction_of_certificate_matrix():
    """Z = Q' - K: a symmetric Q' and K give exactly Q' - K (the 1/2 (Z + Z^T) is exact)."""
    rng = np.random.default_rng(5)
    n = 2
    cons = so3_constraint_matrices(np.arange(n) * 9, D, D - 1)
    A = rng.standard_normal((D, D))
    Qs = A @ A.T
    lam = rng.standard_normal(cons.m)
    Z, err = certificate_matrix(Qs, cons, lam)
    np.testing.assert_allclose(Z, Qs - cons.apply(lam), rtol=0, atol=1e-13 * np.abs(Qs).max())
    assert np.all(err >= 0) and err.max() < 1e-12 * np.abs(Qs).max() * D


def _constraint_case(seed: int):
    """Q' and multipliers of mixed sign spanning ten orders of magnitude, for two rotations."""
    rng = np.random.default_rng(seed)
    n = 2
    cons = so3_constraint_matrices(np.arange(n) * 9, D, D - 1)
    A = rng.standard_normal((D, D)) * 10.0 ** rng.uniform(-3, 3, (D, 1))
    Qs = A @ A.T
    lam = rng.standard_normal(cons.m) * 10.0 ** rng.uniform(-5, 5, cons.m)
    return Qs, cons, lam


def test_certificate_matrix_rounding_bound_holds_in_exact_arithmetic():
    """The entrywise rounding of Z (row sums) is below the bound of certificate_matrix, with Z
    computed exactly in rational arithmetic from the same float inputs."""
    from fractions import Fraction

    for seed in range(3):
        Qs, cons, lam = _constraint_case(seed)
        Z, err = certificate_matrix(Qs, cons, lam)
        C = cons.C.tocoo()
        K = [[Fraction(0)] * D for _ in range(D)]
        for r, c, v in zip(C.row, C.col, C.data, strict=True):
            i, j = r % D, r // D  # vec() is column-major
            K[i][j] += Fraction(float(v)) * Fraction(float(lam[c]))
        for i in range(D):
            row_err = sum(abs(Fraction(float(Z[i, j])) - (Fraction(float(Qs[i, j])) - K[i][j]))
                          for j in range(D))
            assert row_err <= Fraction(float(err[i])), (seed, i)


def test_certificate_matrix_rounding_bound_is_the_documented_formula():
    """err_rows = gamma_{t+1} rows(|C||lambda|) + gamma_3 rows(|Q'| + |K|), t the most
    constraints on one entry of Z (counted here from the dense constraint matrices)."""
    from rwhec_ros.core.numerics.verified import gamma

    Qs, cons, lam = _constraint_case(7)
    Z, err = certificate_matrix(Qs, cons, lam)
    Cd = cons.C.toarray()
    t = int((Cd != 0).sum(axis=1).max())
    assert t >= 2  # the s-s entry carries every rotation's constant term
    K = (Cd @ lam).reshape(D, D, order="F")
    K_abs = (np.abs(Cd) @ np.abs(lam)).reshape(D, D, order="F")
    expected = gamma(t + 1) * K_abs.sum(axis=1) + gamma(3) * (np.abs(Qs).sum(axis=1)
                                                             + np.abs(K).sum(axis=1))
    np.testing.assert_allclose(err, expected, rtol=1e-12)


def test_certificate_options_defaults_and_bounds():
    """Documented defaults (6 eigenvalues reported) and the smallest accepted count (2: the
    certificate needs the gap after the null direction); a reduction and a bound are immutable
    values."""
    import dataclasses

    c = _cert(_spectrum(0.0))
    assert len(c.eigenvalues) == 6
    assert len(_cert(_spectrum(0.0), options=CertificateOptions(n_eigenvalues=2)).eigenvalues) == 2
    assert len(_cert(_spectrum(0.0), options=CertificateOptions(n_eigenvalues=3)).eigenvalues) == 3
    with pytest.raises(ValueError, match="n_eigenvalues"):
        CertificateOptions(n_eigenvalues=1)
    with pytest.raises(dataclasses.FrozenInstanceError):
        ExactReduction(D).block_lower = 0.0  # type: ignore[misc]
    bound = rigorous_dual_bound(_crafted(_spectrum(0.0)), np.zeros(D), 1.0, ExactReduction(D),
                                1.0, N_ROT, 0.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        bound.value = 0.0  # type: ignore[misc]


def test_certify_with_real_reduction_matches_certify_from_z():
    rng = np.random.default_rng(6)
    problem, gt = random_instance(rng, 1, 2, n_per_edge=15, sigma=0.01, kappa=200)
    layout = StateLayout(problem.M, problem.P)
    Q, _ = build_cost_matrices(problem)
    red = reduce_cost(Q, layout, False)
    assert red.verified and red.block_lower > 0 and red.residual_norm >= 0
    scale = 10.0
    Qs = red.Qr / scale
    R = refine_rotations(Qs, np.concatenate([gt.X, gt.Y])[:, :3, :3]).R  # the optimum
    lam = fast_certificate_multipliers(Qs, R)
    cons = so3_constraint_matrices(np.arange(3) * 9, 28, 27)
    c = certify(red, scale, Qs, cons, lam, lam[-1] * scale)
    Z, err = certificate_matrix(Qs, cons, lam)
    c2 = certify_from_Z(Z, lam[-1], lam[-1] * scale, scale, 3, reduced=red, z_err_rows=err)
    assert c.dual_bound == c2.dual_bound and c.status is c2.status
    assert c.certified, c.message
    # the margins are tiny on well-conditioned data
    assert sum(c.margins.values()) < 1e-8 * lam[-1] * scale


class _Reduction:
    """A reduction with non-zero rounding rows (as a ReducedCost after eliminating translations)."""

    def __init__(self, err_rows, block_lower=2.0, residual_norm=0.0):
        self.err_rows = np.asarray(err_rows, float)
        self.verified = True
        self.block_lower = block_lower
        self.residual_norm = residual_norm


def _documented_rounding(Z, z_err_rows, red_rows, scale, ny, k_red=2):
    """The rounding term of the module docstring's bound, written out independently:
    rows = ((e_red / scale)(1 + gamma_2) + u sum_j |Z_ij| + e_Z)(1 + gamma_3), then
    min(sum(rows), ny max(rows)) (1 + gamma_size), with gamma_k = k u / (1 - k u)."""
    u = np.finfo(float).eps / 2
    g = lambda k: k * u / (1 - k * u)
    rows = (red_rows / scale) * (1.0 + g(k_red)) + u * np.abs(Z).sum(axis=1)
    rows = (rows + z_err_rows) * (1.0 + g(3))
    return float(min(rows.sum(), ny * rows.max()) * (1.0 + g(rows.size))), rows


@pytest.mark.parametrize("spread", ["uniform", "one_row", "reduction"])
def test_rounding_term_is_the_documented_formula_bit_for_bit(spread):
    """Every factor of the rounding term (the (1 + gamma_k) inflations, the division by the
    scale, the min of the two sums) is pinned exactly: each is a few ulps, so only an exact
    comparison sees a wrong one. ``uniform`` rows make ``ny max`` the smaller of the two sums
    (the size 19 exceeds ny = 7), ``one_row`` makes the sum the smaller one; in ``reduction`` the
    reduction's rows dominate so that their own (1 + gamma_2) is not lost below an ulp."""
    Z = _crafted(_spectrum(0.0))
    rng = np.random.default_rng(3)
    if spread == "uniform":
        z_rows = np.full(D, 3e-9)
        red_rows = np.full(D, 5e-9)
    elif spread == "reduction":
        z_rows = np.zeros(D)
        red_rows = np.full(D, 1e3)
    else:
        z_rows = np.zeros(D)
        z_rows[4] = 2e-8
        red_rows = np.zeros(D)
        red_rows[4] = rng.uniform(1e-9, 2e-9)
    scale, ny = 4.0, 3 * N_ROT + 1
    b = rigorous_dual_bound(Z, z_rows, 1.0, _Reduction(red_rows), scale, N_ROT, 0.0)
    expected, rows = _documented_rounding(Z, z_rows, red_rows, scale, ny)
    # the case exercises the branch of the min it is named for
    assert (rows.sum() < ny * rows.max()) == (spread == "one_row")
    if spread == "reduction":  # the case sees the reduction's own inflation (1 + gamma_2)
        assert _documented_rounding(Z, z_rows, red_rows, scale, ny, k_red=3)[0] != expected
    assert b.rounding_term == expected
    # the bound subtracts exactly the rounding, the eigenvalue and the Schur terms from lambda_s
    assert b.value == float(1.0 - b.eigenvalue_term - b.rounding_term - b.schur_term)


def test_schur_term_uses_block_lower_and_scale():
    """schur = ny ||F||^2 / (l_e scale): a residual 1e-3, l_e = 2, scale 4 -> 7e-6 / 8."""
    Z = _crafted(_spectrum(0.0))
    red = _Reduction(np.zeros(D), block_lower=2.0, residual_norm=1e-3)
    b = rigorous_dual_bound(Z, np.zeros(D), 1.0, red, 4.0, N_ROT, 0.0)
    assert b.schur_term == pytest.approx(7 * 1e-6 / 8, rel=1e-12)


@pytest.mark.parametrize("where", ["Z", "lambda_s"])
def test_non_finite_z_or_lambda_s_is_named(where):
    """A NaN in Z alone (finite lambda_s), or in lambda_s alone, is "non-finite multipliers"
    (not an eigensolver failure), and the certificate says solver failure."""
    Z = _crafted(_spectrum(0.0))
    lam_s = 1.0
    if where == "Z":
        Z[2, 5] = Z[5, 2] = np.nan
    else:
        lam_s = np.nan
    b = rigorous_dual_bound(Z, np.zeros(D), lam_s, ExactReduction(D), 1.0, N_ROT, 0.0)
    assert b.value == float("-inf")
    assert b.reason == "non-finite multipliers"


def test_eigenvalue_equal_to_null_tol_counts_as_null():
    """The null-space test is inclusive (``w <= null_tol``): a diagonal Z (exact eigenvalues)
    whose second eigenvalue is exactly ``null_tol`` has a two-dimensional null space."""
    w = _spectrum(0.0, CertificateOptions().null_tol)
    c = certify_from_Z(np.diag(w), 1.0, 1.0, 1.0, N_ROT)
    assert c.eigenvalues[1] == CertificateOptions().null_tol  # exact for a diagonal matrix
    assert c.null_space_dim == 2 and not c.certified


def _homogeneous_z(corner=0.0, column=None):
    """Unknown scale: a rotation block with one null direction, the s row/column zero except
    ``Z[-1, -1] = corner`` and the off-diagonal entries ``column`` (dict row -> value)."""
    Z = np.zeros((D, D))
    Z[:-1, :-1] = _crafted(_spectrum(0.0)[:-1])
    Z[-1, -1] = corner
    for i, v in (column or {}).items():
        Z[i, -1] = Z[-1, i] = v
    return Z


def test_homogeneous_is_off_by_default():
    """Without ``homogeneous=True`` a zero s row/column is a second null direction."""
    c = certify_from_Z(_homogeneous_z(), 1.0, 1.0, 1.0, N_ROT)
    assert c.null_space_dim == 2 and not c.certified


def test_homogeneous_with_a_positive_s_entry_is_judged_on_the_whole_z():
    """e_s is set aside only when its whole row/column is (numerically) zero: with Z[s, s] = 1
    the full Z has one null direction, certified without the sign-of-s remark."""
    c = certify_from_Z(_homogeneous_z(corner=1.0), 1.0, 1.0, 1.0, N_ROT, homogeneous=True)
    assert c.certified, c.message
    assert "sign of s" not in c.message


def test_homogeneous_with_a_negative_s_entry_is_not_trivial():
    """Z[s, s] = -1e-3 is a negative eigenvalue, not a zero: two eigenvalues <= null_tol."""
    c = certify_from_Z(_homogeneous_z(corner=-1e-3), 1.0, 1.0, 1.0, N_ROT, homogeneous=True)
    assert not c.certified
    assert "2 eigenvalues" in c.message


@pytest.mark.parametrize("row", [0, D - 2])
def test_homogeneous_with_s_coupled_to_a_rotation_is_judged_on_the_whole_z(row):
    """A coupling of s to the first or the last rotation entry (1e-3 > null_tol), with Z[s, s]
    large enough to keep Z PSD: judged on the whole Z (one null direction), no sign-of-s remark."""
    Z = _homogeneous_z(corner=1.0, column={row: 1e-3})
    assert np.linalg.eigvalsh(Z)[1] > 1e-3  # still one null direction
    c = certify_from_Z(Z, 1.0, 1.0, 1.0, N_ROT, homogeneous=True)
    assert "sign of s" not in c.message


@pytest.mark.parametrize("where", ["column", "corner"])
def test_homogeneous_s_entries_equal_to_null_tol_are_zero(where):
    """The trivial-e_s test is inclusive: a coupling of norm exactly null_tol, or Z[s, s]
    exactly null_tol, still sets e_s aside (the certificate is judged on the rotations)."""
    tol = CertificateOptions().null_tol
    Z = _homogeneous_z(column={0: tol}) if where == "column" else _homogeneous_z(corner=tol)
    c = certify_from_Z(Z, 1.0, 1.0, 1.0, N_ROT, homogeneous=True)
    assert c.certified, c.message
    assert "sign of s" in c.message


@pytest.mark.parametrize("row", [3, D - 2])
def test_homogeneous_zero_corner_but_a_coupled_column_is_not_trivial(row):
    """Z[s, s] = 0 is not enough: every entry of the s column counts (the slice ``Z[:-1, -1]``
    must reach a middle and the last rotation entry). Z = diag(0, 1, ..., 1, 0) plus a coupling
    c = 2e-3 of s to rotation entry ``row``: the block [[1, c], [c, 0]] has the eigenvalue
    -c^2 / (1 + ...) ~ -4e-6 <= null_tol, so the whole Z has two eigenvalues <= null_tol (with
    the rotation block's 0); set aside as trivial, e_s would leave one (on the rotations)."""
    Z = np.diag(np.r_[0.0, np.ones(D - 2), 0.0])
    Z[row, -1] = Z[-1, row] = 2e-3
    w = np.linalg.eigvalsh(Z)
    assert w[0] < -1e-6 and w[1] == 0.0 and w[2] > 0.5  # two null directions, exactly
    c = certify_from_Z(Z, 1.0, 1.0, 1.0, N_ROT, homogeneous=True)
    assert c.null_space_dim == 2 and not c.certified
    assert "2 eigenvalues" in c.message and "sign of s" not in c.message


def test_inflation_factors_that_are_the_same_double():
    """Why two mutants of the rounding term are equivalent (benchmarks/mutation.py): as doubles,
    1 + gamma_1 == 1 + gamma_2 (= 1 + 2^-52) and 1 + gamma_3 == 1 + gamma_4 (= 1 + 2^-51), while
    1 + gamma_2 < 1 + gamma_3."""
    from rwhec_ros.core.numerics.verified import gamma

    assert 1.0 + gamma(1) == 1.0 + gamma(2) == 1.0 + 2.0**-52
    assert 1.0 + gamma(3) == 1.0 + gamma(4) == 1.0 + 2.0**-51


def _bound(value=1.0, eig=0.0, rounding=0.0, schur=0.0):
    return DualBound(value, value + eig + rounding + schur, 0.0, eig, rounding, schur)


W = np.array([0.0, 0.25, 0.5, 0.75, 1.0, 1.25])


def test_status_from_bound_exact_rho_and_margins():
    """d = value * scale, rho_hat = (p - d) / d, the margins in unscaled units: exact numbers
    (powers of two) so that a changed operator or factor shows."""
    b = _bound(value=1.0, eig=0.125, rounding=0.25, schur=0.5)
    c = certificate_from_bound(b, W, 1, False, 3.0, 2.0)
    assert c.dual_bound == 2.0
    assert c.suboptimality_bound == 0.5
    assert c.margins == {"eigenvalue": 0.25, "rounding": 0.5, "schur": 1.0}
    assert c.status is Status.NOT_TIGHT
    assert c.null_space_dim == 1 and c.tolerance == CertificateOptions().rho_tol
    np.testing.assert_array_equal(c.eigenvalues, W)


def test_rho_hat_equal_to_the_tolerance_is_certified():
    """The tolerance is inclusive: rho_hat = 2^-20 exactly, with rho_tol = 2^-20."""
    tol = 2.0**-20
    c = certificate_from_bound(_bound(1.0), W, 1, False, 1.0 + tol, 1.0,
                               options=CertificateOptions(rho_tol=tol))
    assert c.suboptimality_bound == tol
    assert c.certified, c.message


def test_rho_hat_equal_to_the_tolerance_is_not_a_reason():
    """At rho_hat == rho_tol exactly (2^-20) but a two-dimensional null space, the message gives
    the null space as the only reason: rho_hat is within the (inclusive) tolerance."""
    tol = 2.0**-20
    c = certificate_from_bound(_bound(1.0), W, 2, False, 1.0 + tol, 1.0,
                               options=CertificateOptions(rho_tol=tol))
    assert not c.certified
    assert c.message.startswith("not certified: Z has 2 eigenvalues <= ")
    assert "rho_hat" not in c.message


def test_null_space_message_prints_eigenvalues_to_three_digits():
    """The smallest eigenvalues in the 'not certified' message are printed with 3 decimals
    (numpy's array2string precision=3): enough to tell 1e-3 from 1e-4 at a glance."""
    w = np.array([0.00123456, 0.0456789, 0.987654])
    c = certificate_from_bound(_bound(1.0), w, 2, False, 1.0, 1.0)
    assert "(smallest [0.001 0.046 0.988])" in c.message


def test_zero_dual_bound_without_floor_has_no_rho():
    """d = 0 and no cost floor: rho_hat is undefined (nan), never a division by zero."""
    c = certificate_from_bound(_bound(0.0), W, 1, False, 1.0, 1.0)
    assert np.isnan(c.suboptimality_bound) and not c.certified
    assert "rho_hat=nan" in c.message
    c2 = certificate_from_bound(_bound(0.0), W, 1, False, 1.0, 1.0, cost_floor=0.5)
    assert c2.suboptimality_bound == 2.0  # (1 - 0) / 0.5


def test_messages_name_the_numbers():
    """Each status message carries the numbers it is decided on, formatted as documented."""
    ok = certificate_from_bound(_bound(1.0), W, 1, False, 1.0, 1.0)
    assert ok.certified
    assert "rho_hat=0 <= 1e-06" in ok.message
    assert "eigenvalues 0, 0.25, ..." in ok.message
    inacc = certificate_from_bound(_bound(1.0), W + 0.5, 1, False, 1.5, 1.0, solver_ok=False,
                                   solver_status="max_iterations")
    assert inacc.status is Status.SOLVER_INACCURATE
    assert "'max_iterations'" in inacc.message
    assert "rho_hat=0.5" in inacc.message and "lambda_min=0.5" in inacc.message
    only_rho = certificate_from_bound(_bound(1.0), W, 1, False, 1.5, 1.0)
    assert only_rho.message == "not certified: rho_hat=0.5 > 1e-06"
    only_null = certificate_from_bound(_bound(1.0), W, 2, False, 1.0, 1.0)
    assert only_null.message.startswith("not certified: Z has 2 eigenvalues <= 1e-06 (smallest ")
    assert "rho_hat" not in only_null.message
    assert np.array2string(W, precision=3) in only_null.message
    both = certificate_from_bound(_bound(1.0), W, 3, False, 1.5, 1.0)
    assert both.message.startswith("not certified: rho_hat=0.5 > 1e-06; Z has 3 eigenvalues")
    trivial = certificate_from_bound(_bound(1.0), W, 1, True, 1.0, 1.0)
    assert trivial.message.endswith("on the rotation block (the sign of s is free for unknown "
                                    "scale)")


def test_homogeneous_rotation_block_eigenvalue_equal_to_null_tol_counts_as_null():
    """With e_s set aside, the rotation block's null space is counted inclusively too."""
    tol = CertificateOptions().null_tol
    Z = np.zeros((D, D))
    Z[:-1, :-1] = np.diag(_spectrum(0.0, tol)[:-1])
    c = certify_from_Z(Z, 1.0, 1.0, 1.0, N_ROT, homogeneous=True)
    assert c.null_space_dim == 2 and not c.certified


def test_known_scale_is_the_default_of_certify():
    import inspect

    for f in (certify, certify_from_Z, certificate_from_bound):
        params = inspect.signature(f).parameters
        if "homogeneous" in params:
            assert params["homogeneous"].default is False, f.__name__


def test_certify_with_non_finite_multipliers_fails_without_eigenvalues():
    rng = np.random.default_rng(6)
    problem, gt = random_instance(rng, 1, 1, n_per_edge=6, sigma=0.01, kappa=200)
    red = reduce_cost(build_cost_matrices(problem)[0], StateLayout(problem.M, problem.P), False)
    cons = so3_constraint_matrices(np.arange(2) * 9, 19, 18)
    lam = np.zeros(cons.m)
    lam[3] = np.nan
    c = certify(red, 1.0, red.Qr, cons, lam, 2.5, solver_status="optimal")
    assert c.status is Status.SOLVER_FAILED
    assert c.primal_cost == 2.5 and np.isnan(c.dual_bound) and np.isnan(c.lambda_min)
    assert c.eigenvalues.size == 0 and c.null_space_dim == -1
    assert c.tolerance == CertificateOptions().rho_tol
    assert c.message == "solver status 'optimal': no finite dual point"

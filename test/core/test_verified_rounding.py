"""The rounding analysis of :mod:`rwhec_ros.core.numerics.verified`, pinned to its documented
formulas.

The factors ``(1 + gamma_k)``, the power iterations and the gap schedule of the shifted
factorisation each move the proven bound by a few ulps or pick another shift: tests of the kind
"the bound is below the true eigenvalue and close to it" (``test_verified.py``) cannot see them.
Here each is recomputed independently from the module docstring and compared exactly, and the
paths and edge cases (empty and zero matrices, overflow, the size thresholds of
``smallest_eigenvalues``) are asserted on the path taken. Mutation testing
(``benchmarks/mutation.py``) found these gaps.
"""

import dataclasses
import inspect

import numpy as np
import pytest
import scipy.linalg

from rwhec_ros.core.numerics import verified
from rwhec_ros.core.numerics.verified import (
    UNIT_ROUNDOFF,
    VerifiedBound,
    gamma,
    lanczos_start,
    nonnegative_spectral_radius_bound,
    smallest_eigenvalues,
    verified_min_eigenvalue,
)

U = np.finfo(float).eps / 2


def _g(k):
    return k * U / (1 - k * U)


def _radius_bound(R, iterations=4):
    """Collatz-Wielandt with power iterations from the all-ones vector, written out."""
    A = np.abs(R)
    x = np.ones(A.shape[1])
    for _ in range(iterations):
        y = A.T @ (A @ x)
        x = np.maximum(y / y.max(), 1e-30)
    y = A.T @ (A @ x)
    return float(np.max(y / x)) * (1.0 + _g(2 * max(A.shape))) * (1.0 + 2.0 * U)


def test_gamma_and_its_overflow_guard():
    assert UNIT_ROUNDOFF == 2.0**-53
    assert gamma(3) == 3 * U / (1 - 3 * U)
    assert gamma(2**52) == 1.0  # ku = 1/2: 0.5 / 0.5
    assert gamma(2**53) == float("inf")  # ku = 1: no bound (and no division by zero)
    assert gamma(2**54) == float("inf")


@pytest.mark.parametrize("shape", [(6, 6), (4, 7)])
@pytest.mark.parametrize("size", [1.0, 0.01])
def test_spectral_radius_bound_is_the_documented_formula(shape, size):
    """Bit for bit, with the default 4 power iterations; a slowly converging R (random,
    nonnegative and mixed-sign entries) so that one iteration more or less changes the value;
    small entries (products below 1) run every iteration too."""
    R = size * np.random.default_rng(11).standard_normal(shape)
    got = nonnegative_spectral_radius_bound(R)
    assert got == _radius_bound(R, 4)
    assert got != _radius_bound(R, 5) and got != _radius_bound(R, 3)
    assert got >= np.linalg.norm(np.abs(R), 2) ** 2


def test_spectral_radius_bound_of_empty_zero_and_huge_matrices():
    assert nonnegative_spectral_radius_bound(np.zeros((3, 0))) == 0.0
    assert nonnegative_spectral_radius_bound(np.zeros((3, 3))) == 0.0
    # products overflow: the iteration stops and the bound is +inf (never nan, never small)
    with np.errstate(over="ignore", invalid="ignore"):
        assert nonnegative_spectral_radius_bound(np.full((3, 3), 1e200)) == float("inf")


def test_spectral_radius_bound_with_a_zero_column():
    """A zero column of R gives a zero entry of B x: the floor keeps x positive, the bound is the
    radius of the rest (a 2 x 2 all-ones block: radius 4, up to the inflation)."""
    R = np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 0.0]])
    got = nonnegative_spectral_radius_bound(R)
    assert got == _radius_bound(R)
    assert 4.0 <= got < 4.0 * (1 + 1e-14)


def test_shifted_cholesky_bound_is_the_documented_formula():
    """lambda_min >= mu - gamma_{n+1} rho(|R|^T |R|) - u max |fl(a_ii - mu)|, bit for bit."""
    rng = np.random.default_rng(5)
    V, _ = np.linalg.qr(rng.standard_normal((8, 8)))
    A = V @ np.diag(np.linspace(1.0, 9.0, 8)) @ V.T
    A = 0.5 * (A + A.T)
    mu = 0.5
    B = A.copy()
    B[np.diag_indices(8)] -= mu
    R = scipy.linalg.cholesky(B, lower=False)
    expected = mu - _g(9) * _radius_bound(R) - U * np.max(np.abs(np.diag(B)))
    assert verified._shifted_cholesky_bound(A, mu) == expected
    assert verified._shifted_cholesky_bound(A, 1.5) is None  # A - 1.5 I is indefinite


def test_gap_schedule_of_the_verified_bound():
    """First gap gamma_{n+1} max|a_ii|, growing 8-fold: with the estimate 100 gaps above the true
    minimum 1 of diag(1..6), shifts 1+99g, 1+92g, 1+36g fail and the 4th, 1 - 412 g, succeeds."""
    A = np.diag(np.arange(1.0, 7.0))
    g0 = _g(7) * 6.0
    estimate = 1.0 + 100 * g0
    b = verified_min_eigenvalue(A, estimate)
    assert b.attempts == 4
    assert b.shift == estimate - g0 * 512.0
    assert b.lower == verified._shifted_cholesky_bound(A, b.shift)
    assert b.margin == estimate - b.lower
    assert b.lower <= 1.0
    # fewer attempts allowed: no shift verified
    fail = verified_min_eigenvalue(A, estimate, max_attempts=3)
    assert fail.lower == float("-inf") and fail.attempts == 3 and np.isnan(fail.shift)
    assert fail.margin == float("inf") and not fail.verified


def test_default_attempts_are_eight():
    """An estimate 10 gaps x 8^8 above the minimum needs a 9th attempt: refused by default."""
    assert inspect.signature(verified_min_eigenvalue).parameters["max_attempts"].default == 8
    A = np.diag(np.arange(1.0, 7.0))
    g0 = _g(7) * 6.0
    b = verified_min_eigenvalue(A, 1.0 + 10 * g0 * 8.0**7)
    assert b.attempts == 8 and not b.verified
    last = verified_min_eigenvalue(A, 1.0 + 0.5 * g0 * 8.0**7)
    assert last.verified and last.attempts == 8  # the 8th attempt succeeds
    assert last.shift == 1.0 + 0.5 * g0 * 8.0**7 - g0 * 8.0**7


def test_estimate_defaults_to_the_smallest_eigenvalue():
    """Without an estimate the smallest eigenvalue is used: the first shift succeeds."""
    A = np.diag(np.arange(1.0, 7.0))
    b = verified_min_eigenvalue(A)
    assert b.attempts == 1
    assert b.shift == 1.0 - _g(7) * 6.0


def test_zero_matrix_uses_the_tiny_floor_gap():
    b = verified_min_eigenvalue(np.zeros((3, 3)), 0.0)
    assert b.shift == -1e-300 and b.attempts == 1
    assert b.lower <= 0.0


def test_empty_and_non_finite_matrices():
    assert verified_min_eigenvalue(np.zeros((0, 0))) == VerifiedBound(float("inf"), 0.0, 0.0, 0)
    b = verified_min_eigenvalue(np.array([[1.0, np.nan], [np.nan, 1.0]]))
    assert b.lower == float("-inf") and np.isnan(b.shift) and b.margin == float("inf")
    assert b.attempts == 0
    with pytest.raises(ValueError, match="square"):
        verified_min_eigenvalue(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="square"):
        verified_min_eigenvalue(np.zeros(3))


def test_verified_bound_is_frozen():
    b = VerifiedBound(1.0, 0.5, 0.1, 1)
    with pytest.raises(dataclasses.FrozenInstanceError):
        b.lower = 2.0


def test_lanczos_start_is_fixed_positive_and_mixed():
    v = lanczos_start(50)
    np.testing.assert_array_equal(v, lanczos_start(50))  # reproducible
    assert v.shape == (50,) and np.all(v >= 0.5) and np.all(v <= 1.5)
    assert v.max() - v.min() > 0.9  # mixed components, not a near-constant vector


class _Taken(Exception):
    pass


def _spy_paths(monkeypatch):
    """Replace the three eigensolvers by stubs that name the path taken."""
    def raiser(name):
        def f(*args, **kwargs):
            raise _Taken(name)
        return f

    monkeypatch.setattr(verified.np.linalg, "eigvalsh", raiser("full"))
    monkeypatch.setattr(verified.scipy.linalg, "eigh", raiser("index_range"))
    monkeypatch.setattr(verified.scipy.sparse.linalg, "eigsh", raiser("lanczos"))


def _path(monkeypatch, d, k, diag=1.0):
    _spy_paths(monkeypatch)
    with pytest.raises(_Taken) as taken:
        smallest_eigenvalues(np.eye(d) * diag, k)
    return str(taken.value)


def test_smallest_eigenvalues_size_thresholds(monkeypatch):
    """Full eigensolve up to 120, an index range from 121, all eigenvalues when k >= d,
    Lanczos from 3,000 (positive definite), the index range when the factorisation fails."""
    assert verified.FULL_EIGH_MAX_SIZE == 120 and verified.LANCZOS_MIN_SIZE == 3000
    assert _path(monkeypatch, 120, 2) == "full"
    assert _path(monkeypatch, 121, 2) == "index_range"
    assert _path(monkeypatch, 121, 121) == "full"
    assert _path(monkeypatch, 2999, 2) == "index_range"
    assert _path(monkeypatch, 3000, 2) == "lanczos"
    # Z + shift I not positive definite: lambda_min = -2e-8 < -shift (default shift 1e-8)
    assert _path(monkeypatch, 3000, 2, diag=-2e-8) == "index_range"
    # lambda_min = -5e-9 > -shift: still factorised
    assert _path(monkeypatch, 3000, 2, diag=-5e-9) == "lanczos"


def test_smallest_eigenvalues_k_zero_and_k_above_d():
    assert smallest_eigenvalues(np.eye(4), 0).shape == (0,)
    np.testing.assert_array_equal(smallest_eigenvalues(np.diag([3.0, 1.0, 2.0]), 5),
                                  [1.0, 2.0, 3.0])


def test_spectral_radius_bound_of_one_column():
    """n = 1: |R|^T |R| is the 1 x 1 matrix sum r_i^2 (here 25), up to the inflation."""
    got = nonnegative_spectral_radius_bound(np.array([[3.0], [4.0]]))
    assert got == _radius_bound(np.array([[3.0], [4.0]]))
    assert 25.0 <= got < 25.0 * (1 + 1e-14)

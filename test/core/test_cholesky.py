"""The direct LAPACK Cholesky calls give scipy.linalg's factors and solutions bit for bit."""

import numpy as np
import pytest
import scipy.linalg

from rwhec_ros.core.numerics.cholesky import upper_cholesky, upper_cholesky_solve


def _spd(rng: np.random.Generator, n: int) -> np.ndarray:
    M = rng.standard_normal((n, n))
    return M @ M.T + 1e-3 * np.eye(n)


@pytest.mark.parametrize("n", [1, 7, 72, 217])
def test_factors_and_solves_are_scipys_bit_for_bit(n):
    rng = np.random.default_rng(n)
    A = _spd(rng, n)
    R = upper_cholesky(A)
    ref = scipy.linalg.cholesky(A, lower=False, check_finite=False)
    assert np.array_equal(R, ref) and R.flags.f_contiguous == ref.flags.f_contiguous
    c = upper_cholesky(A, clean=False)
    c_ref, _ = scipy.linalg.cho_factor(A, lower=False, check_finite=False)
    assert np.array_equal(c, c_ref)
    # in place on a Fortran-ordered copy: the same factor, and the copy holds it
    F = np.array(A, order="F")
    R_in = upper_cholesky(F, overwrite=True)
    assert np.array_equal(R_in, ref) and np.shares_memory(R_in, F)
    for b in (rng.standard_normal(n), rng.standard_normal((n, 5))):
        b_before = b.copy()
        x = upper_cholesky_solve(c, b)
        assert np.array_equal(x, scipy.linalg.cho_solve((c_ref, False), b, check_finite=False))
        assert np.array_equal(b, b_before)  # the right-hand side is left alone


def test_an_indefinite_matrix_has_no_factor():
    A = np.array([[1.0, 2.0], [2.0, 1.0]])  # eigenvalues 3 and -1
    assert upper_cholesky(A) is None
    assert upper_cholesky(A, clean=False) is None

"""Floating-point eigenvalue bounds: the verified lower bound and the smallest-eigenvalue estimate
on every path (full eigensolve, index range, shift-invert Lanczos), against known spectra."""

import numpy as np
import pytest

from rwhec_ros.core.numerics import verified
from rwhec_ros.core.numerics.verified import (
    UNIT_ROUNDOFF,
    gamma,
    nonnegative_spectral_radius_bound,
    smallest_eigenvalues,
    verified_min_eigenvalue,
)


def _with_spectrum(rng, w: np.ndarray, reflectors: int = 3) -> np.ndarray:
    """Dense symmetric matrix with eigenvalues ``w``: ``H diag(w) H^T`` for a product ``H`` of
    Householder reflectors (orthogonal), built in O(n^2) so that the spectrum is known without an
    eigensolve (reference: the exact ``w``, up to the rounding of the construction)."""
    A = np.diag(np.asarray(w, float))
    for _ in range(reflectors):
        v = rng.standard_normal(len(w))
        v /= np.linalg.norm(v)
        Av = A @ v
        # (I - 2vv^T) A (I - 2vv^T) = A - 2 v (Av)^T - 2 (Av) v^T + 4 (v^T A v) v v^T
        A = A - 2 * np.outer(v, Av) - 2 * np.outer(Av, v) + 4 * (v @ Av) * np.outer(v, v)
    return 0.5 * (A + A.T)


def _spectrum(rng, n: int, kind: str) -> np.ndarray:
    w = rng.uniform(0.5, 10.0, n)
    if kind == "definite":
        w[:4] = [1e-3, 2e-3, 3e-3, 4e-3]
    else:  # indefinite: two negative eigenvalues
        w[:4] = [-2.0, -1e-2, 1e-3, 5e-3]
    return w


@pytest.mark.parametrize("n", [10, 301])
@pytest.mark.parametrize("kind", ["definite", "indefinite"])
def test_smallest_eigenvalues_match_eigvalsh(n, kind):
    """Sizes 10 (full eigensolve) and 301 (index-range eigensolve) against numpy.linalg.eigvalsh."""
    rng = np.random.default_rng(n)
    A = _with_spectrum(rng, _spectrum(rng, n, kind))
    ref = np.linalg.eigvalsh(A)[:4]
    got = smallest_eigenvalues(A, 4)
    # both backward stable: eigenvalues agree to a few u ||A|| (||A|| ~ 10)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-11)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["definite", "indefinite"])
def test_smallest_eigenvalues_large_paths(kind):
    """3,001 x 3,001: shift-invert Lanczos on a Cholesky factor (definite) and its fallback to the
    index-range eigensolve when the factorisation fails (indefinite). Reference: the constructed
    spectrum (a full eigvalsh of this size would double the test's time for no extra check)."""
    rng = np.random.default_rng(7)
    n = 3001
    assert n >= verified.LANCZOS_MIN_SIZE
    w = _spectrum(rng, n, kind)
    A = _with_spectrum(rng, w)
    got = smallest_eigenvalues(A, 4)
    # construction rounding: a few reflections, each ~u ||A|| (||A|| ~ 10); Lanczos converges to
    # ARPACK's default relative tolerance (machine precision) around the shift
    np.testing.assert_allclose(got, np.sort(w)[:4], rtol=0, atol=1e-9)


@pytest.mark.parametrize("n", [10, 301, 700])
@pytest.mark.parametrize("kind", ["definite", "indefinite", "singular"])
def test_verified_lower_bound_is_below_and_close(n, kind):
    rng = np.random.default_rng(100 + n)
    w = _spectrum(rng, n, "indefinite" if kind == "indefinite" else "definite")
    if kind == "singular":
        w[0] = 0.0
    A = _with_spectrum(rng, w)
    lam = float(np.linalg.eigvalsh(A)[0])
    vb = verified_min_eigenvalue(A)
    assert vb.verified
    assert vb.lower <= lam  # the bound holds
    # and is close: the margin is gamma_{n+1} times a norm of |R|^T |R| (<= n ||A|| here)
    assert lam - vb.lower <= 4 * gamma(n + 1) * n * 10.0
    assert vb.margin >= 0


def test_verified_bound_with_a_bad_estimate_still_holds():
    """An estimate far above the true smallest eigenvalue: the factorisations fail until the
    shift is below it, then the bound holds."""
    rng = np.random.default_rng(3)
    A = _with_spectrum(rng, np.r_[-1.0, rng.uniform(1, 2, 49)])
    vb = verified_min_eigenvalue(A, estimate=-1.0 + 1e-13 * 8**3)
    assert vb.verified and vb.lower <= -1.0 + 1e-12
    assert vb.attempts >= 1


def test_verified_bound_refuses_non_finite():
    A = np.eye(5)
    A[2, 2] = np.nan
    vb = verified_min_eigenvalue(A)
    assert not vb.verified and vb.lower == -np.inf


def test_verified_bound_rejects_non_square():
    with pytest.raises(ValueError, match="square"):
        verified_min_eigenvalue(np.zeros((3, 4)))


def test_spectral_radius_bound_is_an_upper_bound():
    rng = np.random.default_rng(0)
    for shape in [(5, 5), (40, 40), (30, 50)]:
        R = rng.standard_normal(shape)
        exact = np.linalg.norm(np.abs(R), 2) ** 2
        ub = nonnegative_spectral_radius_bound(R)
        assert exact <= ub <= 1.5 * exact  # Collatz-Wielandt after a few power steps is tight


def test_gamma():
    assert gamma(1) == pytest.approx(UNIT_ROUNDOFF, rel=1e-12)
    assert gamma(10) > 10 * UNIT_ROUNDOFF
    assert gamma(2**60) == np.inf

"""The shortcuts that take fixed costs out of every (live) re-solve give the old results exactly:
the dense blocks of the Schur reduction by slices, the constraint set cached per frame count and
the BLAS thread limit skipped when it is already in place."""

import contextlib

import numpy as np
import pytest

from rwhec_ros.core.certify.relaxation import frame_constraints, so3_constraint_matrices
from rwhec_ros.core.model.cost import StateLayout, build_cost_matrices
from rwhec_ros.core.model.reduction import _dense_blocks, reduce_cost
from rwhec_ros.core.numerics.blas import _blas_controller
from rwhec_ros.core.solve import SolveOptions, blas_threads, solve
from rwhec_ros.simulation.synthetic import random_instance


def _ix_blocks(Qd, layout, unknown_scale):
    """The fancy-index blocks reduce_cost took before (the reference)."""
    r = np.arange(layout.r0, layout.size)
    if unknown_scale:
        elim, keep = np.arange(0, layout.n_t + 1), r
    else:
        elim, keep = np.arange(0, layout.n_t), np.concatenate([r, [layout.alpha]])
    return Qd[np.ix_(elim, elim)], Qd[np.ix_(elim, keep)], Qd[np.ix_(keep, keep)]


@pytest.mark.parametrize("unknown_scale", [False, True])
def test_dense_blocks_equal_the_fancy_index(unknown_scale):
    rng = np.random.default_rng(11)
    problem, _ = random_instance(rng, 2, 3, n_per_edge=8, sigma=0.03, kappa=40,
                                 unknown_scale=unknown_scale,
                                 alpha=0.6 if unknown_scale else 1.0)
    layout = StateLayout(problem.M, problem.P)
    Q = build_cost_matrices(problem)[0]
    Qd = Q.toarray() if hasattr(Q, "toarray") else np.asarray(Q)
    # a non-symmetric matrix too: a transposed block would go unnoticed on Q itself
    for A in (Qd, rng.standard_normal(Qd.shape)):
        for got, ref in zip(_dense_blocks(A, layout, unknown_scale),
                            _ix_blocks(A, layout, unknown_scale), strict=True):
            assert got.shape == ref.shape
            assert np.array_equal(got, ref)  # the same entries: bit for bit
            assert got.flags.c_contiguous  # the same memory layout as the fancy index's copy
    red = reduce_cost(Qd, layout, unknown_scale)
    assert red.verified  # the reduction itself still runs its checks on these blocks


@pytest.mark.parametrize("n", [1, 3, 24])
def test_frame_constraints_equal_a_fresh_build(n):
    d = 9 * n + 1
    fresh = so3_constraint_matrices(np.arange(n) * 9, d, d - 1)
    cached = frame_constraints(n)
    assert frame_constraints(n) is cached  # built once per frame count
    assert (cached.d, cached.s_index, cached.n_rotations) == (fresh.d, fresh.s_index,
                                                               fresh.n_rotations)
    for name in ("data", "indices", "indptr"):
        assert np.array_equal(getattr(cached.C, name), getattr(fresh.C, name))
        assert not getattr(cached.C, name).flags.writeable  # shared: nobody may change it
    lam = np.random.default_rng(n).standard_normal(cached.m)
    assert np.array_equal(cached.apply(lam), fresh.apply(lam))


def _blas_counts():
    return [lib.num_threads for lib in _blas_controller().select(user_api="blas").lib_controllers]


def test_nested_blas_limit_is_skipped_and_restored():
    if not _blas_counts():
        pytest.skip("no BLAS library visible to threadpoolctl")
    before = _blas_counts()
    with blas_threads(1):
        assert _blas_counts() == [1] * len(before)
        inner = blas_threads(1)
        assert isinstance(inner, contextlib.nullcontext)  # nothing to set: a no-op
        with inner:
            assert _blas_counts() == [1] * len(before)
        assert _blas_counts() == [1] * len(before)  # the inner exit restored nothing
    assert _blas_counts() == before  # the outer limit restores what was there


def test_solve_inside_a_blas_limit_equals_a_plain_solve():
    rng = np.random.default_rng(12)
    problem, _ = random_instance(rng, 2, 3, n_per_edge=10, sigma=0.02, kappa=60)
    plain = solve(problem, SolveOptions(mode="fast"))
    with blas_threads(1):
        nested = solve(problem, SolveOptions(mode="fast"))
    assert plain.certificate.status == nested.certificate.status
    # the same BLAS thread count either way: bit for bit
    assert np.array_equal(plain.X, nested.X) and np.array_equal(plain.Y, nested.Y)
    assert plain.certificate.dual_bound == nested.certificate.dual_bound

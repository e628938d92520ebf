"""Validation of the problem model: every failure is a ValueError naming edge, index, value."""

import numpy as np
import pytest

from rwhec_ros.core.lie import make_transform
from rwhec_ros.core.problem import Edge, Problem
from rwhec_ros.simulation.synthetic import random_transforms


@pytest.fixture
def pair():
    rng = np.random.default_rng(0)
    return random_transforms(rng, 4), random_transforms(rng, 4)


def test_valid_problem_sizes(pair):
    A, B = pair
    e = Edge.build("x0", "y0", A, B, sigma=0.01, kappa=100.0)
    p = Problem(["x0"], ["y0"], [e])
    assert (p.M, p.P, p.n_measurements) == (1, 1, 4)
    assert e.sigma.shape == (4,) and np.all(e.kappa == 100.0)


def test_non_finite_named(pair):
    A, B = pair
    B = B.copy()
    B[2, 0, 3] = np.nan
    with pytest.raises(ValueError, match=r"edge \(x0, y0\) B\[2\].*non-finite"):
        Edge.build("x0", "y0", A, B)


def test_not_orthonormal_named(pair):
    A, B = pair
    A = A.copy()
    A[1, :3, :3] *= 1.01
    with pytest.raises(ValueError, match=r"A\[1\].*not orthonormal"):
        Edge.build("x0", "y0", A, B)


def test_reflection_named(pair):
    A, B = pair
    B = B.copy()
    B[3, :3, :3] = B[3, :3, :3] @ np.diag([1.0, 1.0, -1.0])
    with pytest.raises(ValueError, match=r"B\[3\].*det -1"):
        Edge.build("x0", "y0", A, B)


def test_last_row_named(pair):
    A, B = pair
    A = A.copy()
    A[0, 3, 0] = 0.5
    with pytest.raises(ValueError, match=r"A\[0\].*last row"):
        Edge.build("x0", "y0", A, B)


@pytest.mark.parametrize("field", ["sigma", "kappa"])
@pytest.mark.parametrize("bad", [0.0, -1.0, np.inf])
def test_precisions_positive(pair, field, bad):
    A, B = pair
    values = np.ones(4)
    values[2] = bad
    with pytest.raises(ValueError, match=rf"{field}\[2\].*> 0"):
        Edge.build("x0", "y0", A, B, **{field: values})


def test_count_mismatch(pair):
    A, B = pair
    with pytest.raises(ValueError, match="4 A transforms but 3 B"):
        Edge.build("x0", "y0", A, B[:3])


def test_unknown_frames_and_untouched(pair):
    A, B = pair
    e = Edge.build("x0", "y9", A, B)
    with pytest.raises(ValueError, match="unknown Y frame 'y9'"):
        Problem(["x0"], ["y0"], [e])
    e2 = Edge.build("x0", "y0", A, B)
    with pytest.raises(ValueError, match=r"not touched by any edge: \['x1'\]"):
        Problem(["x0", "x1"], ["y0"], [e2])
    with pytest.raises(ValueError, match="duplicate edge"):
        Problem(["x0"], ["y0"], [e2, e2])
    with pytest.raises(ValueError, match="unique"):
        Problem(["a"], ["a"], [Edge.build("a", "a", A, B)])


def test_components():
    rng = np.random.default_rng(1)
    T = lambda: random_transforms(rng, 2)  # noqa: E731
    edges = [Edge.build("x0", "y0", T(), T()), Edge.build("x1", "y1", T(), T())]
    p = Problem(["x0", "x1"], ["y0", "y1"], edges)
    comps = sorted(sorted(c) for c in p.components())
    assert comps == [["x0", "y0"], ["x1", "y1"]]


def test_single_transform_accepted():
    T = make_transform(np.eye(3), [1.0, 2.0, 3.0])
    e = Edge.build("x", "y", T, T)
    assert e.n == 1
